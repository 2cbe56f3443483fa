# Unity v2.6.1 (ThrowTheSwitch), the test framework of every C test.
#
# FetchContent clones the upstream tag. Machines without access to GitHub use
# the released, unmodified copy in ../shared/vendor/Unity-2.6.1 beside the
# source tree: when that folder exists and FETCHCONTENT_SOURCE_DIR_UNITY is not
# set, it is used instead of the clone, so both build the same sources. Any
# other copy: -DFETCHCONTENT_SOURCE_DIR_UNITY=<dir>.
#
# Only the sources are fetched (SOURCE_SUBDIR names a folder Unity does not
# have, so its CMakeLists.txt is not added): the target `unity` below compiles
# src/unity.c with this project's configuration, the same way for the host and
# the Cortex-M7 build, without Unity's install rules and warning set.
include(FetchContent)

set(MD_UNITY_VENDOR_DIR "${CMAKE_SOURCE_DIR}/../shared/vendor/Unity-2.6.1")
if(NOT DEFINED FETCHCONTENT_SOURCE_DIR_UNITY AND EXISTS "${MD_UNITY_VENDOR_DIR}/src/unity.c")
    get_filename_component(MD_UNITY_VENDOR_DIR "${MD_UNITY_VENDOR_DIR}" ABSOLUTE)
    set(FETCHCONTENT_SOURCE_DIR_UNITY "${MD_UNITY_VENDOR_DIR}" CACHE PATH
        "Unity v2.6.1 sources used instead of cloning them (vendored copy found beside the source tree)")
endif()

FetchContent_Declare(unity
    GIT_REPOSITORY https://github.com/ThrowTheSwitch/Unity.git
    GIT_TAG v2.6.1
    GIT_SHALLOW TRUE
    SOURCE_SUBDIR md-sources-only)
FetchContent_MakeAvailable(unity)
if(NOT EXISTS "${unity_SOURCE_DIR}/src/unity.c")
    message(FATAL_ERROR "Unity: no src/unity.c in ${unity_SOURCE_DIR}")
endif()
message(STATUS "Unity: ${unity_SOURCE_DIR}")

add_library(unity STATIC "${unity_SOURCE_DIR}/src/unity.c")
target_include_directories(unity PUBLIC "${unity_SOURCE_DIR}/src")
# Double asserts (TEST_ASSERT_DOUBLE_WITHIN, ..._DOUBLE comparisons); 64-bit
# integers, which Unity enables by itself only where long or pointers are
# 64-bit; and a NaN is never within any delta of anything, not even of another
# NaN (UNITY_NAN_NOT_EQUAL_NAN, read by unity.c): two computations that both
# went wrong must not pass as equal.
target_compile_definitions(unity PUBLIC UNITY_INCLUDE_DOUBLE UNITY_SUPPORT_64 UNITY_NAN_NOT_EQUAL_NAN)
if(MD_TARGET_MCU)
    # Output through the semihosting sink of the target-test glue:
    # tests/target/unity_config.h and md_target_putchar.c.
    target_compile_definitions(unity PUBLIC UNITY_INCLUDE_CONFIG_H)
    target_include_directories(unity PUBLIC "${PROJECT_SOURCE_DIR}/tests/target")
else()
    # putchar + fflush(stdout) after each test: the report so far survives a
    # crash (a sanitizer abort, a signal) of the test program.
    target_compile_definitions(unity PUBLIC UNITY_USE_FLUSH_STDOUT)
endif()
