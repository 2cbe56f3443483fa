# Compiler flags every project target gets (libcanard's set, plus a few more).
# Warnings are errors everywhere: host, cross, tests.
add_library(md_warnings INTERFACE)
target_compile_options(md_warnings INTERFACE
    -Wall -Wextra -Werror -pedantic
    -Wconversion -Wsign-conversion -Wdouble-promotion -Wfloat-equal
    -Wundef -Wswitch-enum -Wshadow -Wcast-qual -Wstrict-prototypes
    -Wmissing-prototypes -Wvla -Wformat=2 -Wnull-dereference)

# Firmware sources additionally: no heap, checked by the preprocessor.
add_library(md_firmware_rules INTERFACE)
target_compile_options(md_firmware_rules INTERFACE
    "SHELL:-include ${PROJECT_SOURCE_DIR}/firmware/config/md_no_heap.h")
target_link_libraries(md_firmware_rules INTERFACE md_warnings)
