# md-bench-m7: the electrode-cycle stages on the Cortex-M7 (tests/target/bench_m7.c,
# tools/bench/bench_core.c), linked like the target tests. Not a ctest test
# (timed benchmarks are not tests): scripts/bench.sh runs it under QEMU with
# -icount shift=0. Included from tests/target/CMakeLists.txt.
add_executable(md-bench-m7 ${PROJECT_SOURCE_DIR}/tests/target/bench_m7.c
    ${PROJECT_SOURCE_DIR}/tools/bench/bench_core.c)
target_include_directories(md-bench-m7 PRIVATE ${PROJECT_SOURCE_DIR}/tools/bench)
target_link_libraries(md-bench-m7 PRIVATE md_core m md_firmware_rules)
md_m7_link_executable(md-bench-m7 ${MD_M7_TEST_STACK_BYTES})
