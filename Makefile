# The README's two commands. Both install what is missing, configure and build first.
PRESET ?= release
BUILD_DIR := build

.PHONY: all setup configure build demo test clean format

all: build

setup:
	@bash scripts/setup

configure: setup
	@cmake --preset $(PRESET) >/dev/null

build: configure
	@cmake --build --preset $(PRESET)

demo: build
	@$(BUILD_DIR)/kestrel demo

test: build
	@ctest --preset $(PRESET)

format:
	@git ls-files '*.cpp' '*.hpp' | xargs clang-format -i

clean:
	@rm -rf build build-debug build-asan build-tsan build-fuzz
