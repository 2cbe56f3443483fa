# Toolchain file: bare-metal Cortex-M7 with the double-precision FPU
# (FPv5-D16, hard-float ABI), GNU Arm Embedded toolchain + newlib-nano.
#
#   cmake --preset cortex-m7          (or -DCMAKE_TOOLCHAIN_FILE=cmake/arm-none-eabi.cmake)
#
# The board support (startup, linker script, semihosting) lives in
# firmware/port/cortex_m; this file only knows the CPU and the C library.

set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(MD_ARM_PREFIX arm-none-eabi- CACHE STRING "Prefix of the cross tools")
set(CMAKE_C_COMPILER ${MD_ARM_PREFIX}gcc)
set(CMAKE_ASM_COMPILER ${MD_ARM_PREFIX}gcc)
find_program(CMAKE_OBJCOPY ${MD_ARM_PREFIX}objcopy REQUIRED)
find_program(CMAKE_SIZE ${MD_ARM_PREFIX}size REQUIRED)
find_program(CMAKE_NM ${MD_ARM_PREFIX}nm REQUIRED)

# A bare-metal compiler cannot link a test program without a linker script.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

# Cortex-M7 with FPv5-D16: double-precision FPU, 16 double registers.
# The same flags at link time select the thumb/v7e-m+dp/hard multilib of
# newlib and libgcc (check: arm-none-eabi-gcc <flags> -print-multi-directory).
set(MD_M7_CPU_FLAGS "-mcpu=cortex-m7 -mthumb -mfpu=fpv5-d16 -mfloat-abi=hard")

set(CMAKE_C_FLAGS_INIT "${MD_M7_CPU_FLAGS} -ffunction-sections -fdata-sections")
set(CMAKE_ASM_FLAGS_INIT "${MD_M7_CPU_FLAGS}")
# -nostartfiles: the port's reset handler replaces crt0.
# nano.specs: newlib-nano (small libc); nosys.specs: stub syscalls, so nothing
# asks for an OS. The no-heap guarantee is checked on every linked ELF by
# scripts/check-no-heap.sh (the linker script also gives the heap 0 bytes).
set(CMAKE_EXE_LINKER_FLAGS_INIT
    "${MD_M7_CPU_FLAGS} -nostartfiles --specs=nano.specs --specs=nosys.specs -Wl,--gc-sections")

set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
