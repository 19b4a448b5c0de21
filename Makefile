# The README's two commands. Both install what is missing, configure and build first.
PRESET ?= release
BUILD_DIR := build

.PHONY: all setup configure build demo team-demo test clean format

all: build

setup:
	@bash scripts/setup

configure: setup
	@cmake --preset $(PRESET) >/dev/null

build: configure
	@cmake --build --preset $(PRESET)

# The demo needs the kestrel program only: the tests and benchmarks (nearly half the build) wait
# for `make test`.
demo: configure
	@cmake --build --preset $(PRESET) --target kestrel
	@$(BUILD_DIR)/kestrel demo

# Broker, two agents (uav + ugv) in market, mapd and the browser station for TEAM_SECONDS.
TEAM_SECONDS ?= 40
team-demo: build
	@BUILD_DIR=$(BUILD_DIR) bash scripts/team_demo.sh $(TEAM_SECONDS)

test: build
	@ctest --preset $(PRESET)

format:
	@git ls-files '*.cpp' '*.hpp' | xargs clang-format -i

clean:
	@rm -rf build build-debug build-asan build-tsan build-fuzz
