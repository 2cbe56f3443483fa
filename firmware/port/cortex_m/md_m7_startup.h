/// @file md_m7_startup.h
/// Cortex-M7 start-up for the MPS2 AN500 image (QEMU `mps2-an500`): the
/// vector table, the reset sequence and the fault handlers.
///
/// Reset sequence (Reset_Handler): enable the FPU (CPACR CP10/CP11) before any
/// floating-point instruction can run, point VTOR at our table, trap integer
/// division by zero, enable the separate MemManage/BusFault/UsageFault
/// handlers, copy .data, zero .bss and .psram, paint the unused stack (for a
/// high-water mark), call `int main(void)` and end the program with
/// md_m7_exit(main's return value), i.e. a semihosting exit whose status is
/// QEMU's exit status.
///
/// A fault prints its name, the fault status registers and the faulting PC on
/// the semihosting console and exits with MD_M7_FAULT_EXIT_STATUS.
#ifndef MD_M7_STARTUP_H
#define MD_M7_STARTUP_H

#include <stdint.h>

/// Exit status of a program that took a fault or an unexpected interrupt.
#define MD_M7_FAULT_EXIT_STATUS 254

/// Hook run by md_m7_exit before the program ends (e.g. to flush a console
/// buffer). NULL = none. Set it once from main or a test glue.
extern void (*md_m7_exit_hook)(void);

/// Entry point named in the vector table and the linker script's ENTRY().
void Reset_Handler(void);

/// Exception handlers a port unit may define (strong symbol); the defaults
/// report an unexpected exception and exit like a fault.
void SysTick_Handler(void);
void PendSV_Handler(void);
void SVC_Handler(void);
void UART0RX_IRQHandler(void);
void UART1RX_IRQHandler(void);
void UART2RX_IRQHandler(void);
void UART3RX_IRQHandler(void);
void UART4RX_IRQHandler(void);

/// Flush (md_m7_exit_hook), print the stack high-water mark and end the
/// program with exit status `code` (see md_sh_exit_status). Never returns.
__attribute__((noreturn)) void md_m7_exit(int code);

/// Bytes of the stack region ever written since reset (high-water mark),
/// found by scanning the paint pattern from the stack limit upwards. O(stack).
uint32_t md_m7_stack_used_bytes(void);

/// Size of the stack region in bytes (linker symbol __stack_size).
uint32_t md_m7_stack_size_bytes(void);

#endif
