# Warnings and sanitizers for Kestrel's own targets (not for third-party code).
add_library(kestrel_options INTERFACE)
target_compile_options(kestrel_options INTERFACE -Wall -Wextra -Wpedantic)
# GCC 12 reports -Wrestrict falsely inside libstdc++'s std::string operator+ (GCC bug 105329).
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
  target_compile_options(kestrel_options INTERFACE -Wno-restrict)
endif()
# ORB descriptors are compared by Hamming distance, four popcounts each. Without -mpopcnt,
# std::popcount is a libgcc call per word: 8M distances take 70 ms instead of 8.5 (one core,
# this project's machines), and descriptor matching, relocalization and place recognition pay
# for it. Enabled when the build machine runs the instruction; integer only, so no result changes.
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
  include(CheckCXXSourceRuns)
  set(CMAKE_REQUIRED_FLAGS -mpopcnt)
  check_cxx_source_runs("int main(int argc, char**) {
    return __builtin_popcountll(static_cast<unsigned long long>(argc) * 3u) == 2 ? 0 : 1;
  }" KESTREL_HAVE_POPCNT)
  unset(CMAKE_REQUIRED_FLAGS)
  if(KESTREL_HAVE_POPCNT)
    target_compile_options(kestrel_options INTERFACE -mpopcnt)
  endif()
endif()
target_include_directories(kestrel_options INTERFACE ${PROJECT_SOURCE_DIR})
target_compile_definitions(kestrel_options INTERFACE
  KESTREL_VERSION="${PROJECT_VERSION}"
  KESTREL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")

if(KESTREL_SANITIZE_ADDRESS)
  target_compile_options(kestrel_options INTERFACE -fsanitize=address,undefined -fno-omit-frame-pointer
                                                   -fno-sanitize-recover=undefined)
  target_link_options(kestrel_options INTERFACE -fsanitize=address,undefined)
endif()
if(KESTREL_SANITIZE_THREAD)
  target_compile_options(kestrel_options INTERFACE -fsanitize=thread -fno-omit-frame-pointer)
  target_link_options(kestrel_options INTERFACE -fsanitize=thread)
endif()

# Sanitizers run everything 3-10x slower. The tests that wait on whole processes (agents, the
# broker, the browser) multiply their time limits, CTest's TIMEOUT and the waits inside (as
# $KESTREL_TEST_TIME_SCALE), by this whole number; the sanitizer presets set it.
set(KESTREL_TEST_TIME_SCALE 1 CACHE STRING "factor on the end-to-end tests' time limits")
if(NOT KESTREL_TEST_TIME_SCALE MATCHES "^[1-9][0-9]*$")
  message(FATAL_ERROR "KESTREL_TEST_TIME_SCALE must be a whole number >= 1, not '${KESTREL_TEST_TIME_SCALE}'")
endif()

# kestrel_add_library(NAME SOURCES... [DEPS ...]) — a static library with the project's options.
function(kestrel_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  # Developer switch (off in CI): let a tree with work in progress configure.
  if(KESTREL_TOLERATE_MISSING_TESTS)
    set(present "")
    foreach(src IN LISTS ARG_SOURCES)
      if(EXISTS ${src} OR EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/${src})
        list(APPEND present ${src})
      endif()
    endforeach()
    if(NOT present)
      file(WRITE ${CMAKE_CURRENT_BINARY_DIR}/${name}_empty.cpp "// no sources yet\n")
      set(present ${CMAKE_CURRENT_BINARY_DIR}/${name}_empty.cpp)
    endif()
    set(ARG_SOURCES ${present})
  endif()
  add_library(${name} STATIC ${ARG_SOURCES})
  target_link_libraries(${name} PUBLIC kestrel_options ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
endfunction()

# The CLI links every module library that asks for it.
function(kestrel_app_library name)
  set_property(GLOBAL APPEND PROPERTY KESTREL_APP_LIBRARIES ${name})
endfunction()
