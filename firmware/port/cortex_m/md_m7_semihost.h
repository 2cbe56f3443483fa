/// @file md_m7_semihost.h
/// ARM semihosting (the debugger / QEMU services reached with `bkpt 0xAB` on
/// M-profile): console output and exit with a status code. Under QEMU use
/// `-semihosting-config enable=on,target=native`; on a real board a debug
/// probe must service the calls, or the firmware stops at the first one.
///
/// All functions are synchronous, use no heap and may be called from any
/// context, including fault handlers.
#ifndef MD_M7_SEMIHOST_H
#define MD_M7_SEMIHOST_H

#include <stdint.h>

/// Semihosting operation numbers (ARM "Semihosting for AArch32 and AArch64", v2).
#define MD_SH_SYS_WRITEC 0x03u
#define MD_SH_SYS_WRITE0 0x04u
#define MD_SH_SYS_EXIT 0x18u
#define MD_SH_SYS_GET_CMDLINE 0x15u
#define MD_SH_SYS_EXIT_EXTENDED 0x20u
#define MD_SH_SYS_OPEN 0x01u
#define MD_SH_SYS_CLOSE 0x02u
#define MD_SH_SYS_READ 0x06u
#define MD_SH_SYS_SEEK 0x0Au
/// SYS_OPEN mode "rb" (read, binary).
#define MD_SH_OPEN_RB 1u
/// Reason code of SYS_EXIT*: the application finished normally.
#define MD_SH_ADP_STOPPED_APPLICATION_EXIT 0x20026u
/// Reason code of SYS_EXIT: unknown run-time error (QEMU exits with 1).
#define MD_SH_ADP_STOPPED_RUNTIME_ERROR 0x20023u

/// Copy the command line the host gives the program (QEMU:
/// `-semihosting-config arg=...`, words joined by spaces, the first is the
/// program) into `buf`, NUL-terminated. Returns its length, or -1 if the host
/// has none or it does not fit in `cap` bytes.
int32_t md_sh_get_cmdline(char *buf, uint32_t cap);

/// Write a NUL-terminated string to the host console. `s` may be NULL (no-op).
void md_sh_write0(const char *s);

/// Write one character to the host console.
void md_sh_writec(char c);

/// Write `v` as 0x-prefixed, 8-digit hexadecimal.
void md_sh_write_hex(uint32_t v);

/// Write `v` in decimal.
void md_sh_write_uint(uint32_t v);

/// Open a host file for reading (SYS_OPEN, mode "rb"); for tools such as
/// md-bench-m7 that read their input from the host, not for the firmware.
/// Returns the handle (>= 0), or -1 if the host cannot open it.
int32_t md_sh_open_read(const char *path);

/// Read up to `len` bytes from `handle` into `buf` (SYS_READ). Returns the
/// bytes read (len unless the file ended), or -1 on an error.
int32_t md_sh_read(int32_t handle, void *buf, uint32_t len);

/// Move to byte `pos` of the file (SYS_SEEK; 32-bit positions, files up to
/// 4 GiB). 0 on success, -1 on an error.
int32_t md_sh_seek(int32_t handle, uint32_t pos);

/// Close a handle of md_sh_open_read (SYS_CLOSE). 0 on success, -1 on an error.
int32_t md_sh_close(int32_t handle);

/// Map a C exit status onto a process exit status 0..255 without letting a
/// failure wrap to 0 (e.g. 256 failed tests): 0 stays 0, 1..255 stay, any
/// other value becomes 255.
uint32_t md_sh_exit_status(int code);

/// End the program: SYS_EXIT_EXTENDED(ADP_Stopped_ApplicationExit, status),
/// so QEMU's own exit status is `md_sh_exit_status(code)`. Falls back to the
/// AArch32 SYS_EXIT (status 0 or 1 only) if the host lacks the extension.
/// Never returns.
__attribute__((noreturn)) void md_sh_exit(int code);

#endif
