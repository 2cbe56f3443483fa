/* ARM semihosting calls for the Cortex-M port. */
#include "md_m7_semihost.h"

#include <stddef.h>
#include <stdint.h>

/* One semihosting request: r0 = operation, r1 = argument (a pointer to a
 * parameter block or a value); the host answers in r0. */
static uint32_t sh_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

int32_t md_sh_get_cmdline(char *buf, uint32_t cap)
{
    if (buf == NULL || cap < 2u) {
        return -1;
    }
    /* parameter block: buffer address, its size; the host writes the length back */
    uint32_t block[2] = {(uint32_t)(uintptr_t)buf, cap}; /* the call clobbers "memory" */
    if (sh_call(MD_SH_SYS_GET_CMDLINE, block) != 0u || block[1] >= cap) {
        buf[0] = '\0';
        return -1;
    }
    buf[block[1]] = '\0';
    return (int32_t)block[1];
}

/* Parameter blocks of the file calls: words of the AArch32 semihosting ABI,
 * addresses as pointers (32 bits on the M7), so no pointer becomes an integer. */
typedef struct {
    const char *name;
    uint32_t mode;
    uint32_t len; /* of the name, without its NUL */
} sh_open_block_t;

typedef struct {
    uint32_t handle;
    void *buf;
    uint32_t len;
} sh_read_block_t;

_Static_assert(sizeof(sh_open_block_t) == 3u * sizeof(uint32_t), "SYS_OPEN block: three words");
_Static_assert(sizeof(sh_read_block_t) == 3u * sizeof(uint32_t), "SYS_READ block: three words");

int32_t md_sh_open_read(const char *path)
{
    if (path == NULL) {
        return -1;
    }
    uint32_t len = 0u;
    while (len < 4096u && path[len] != '\0') {
        ++len;
    }
    if (len == 0u || len >= 4096u) {
        return -1;
    }
    const sh_open_block_t block = {path, MD_SH_OPEN_RB, len};
    return (int32_t)sh_call(MD_SH_SYS_OPEN, &block);
}

int32_t md_sh_read(int32_t handle, void *buf, uint32_t len)
{
    if (handle < 0 || (buf == NULL && len > 0u) || len > (uint32_t)INT32_MAX) {
        return -1;
    }
    const sh_read_block_t block = {(uint32_t)handle, buf, len};
    /* the host answers with the bytes NOT read (0: all of them) */
    const uint32_t left = sh_call(MD_SH_SYS_READ, &block);
    if (left > len) {
        return -1;
    }
    const uint32_t got = len - left;
    return (int32_t)got;
}

int32_t md_sh_seek(int32_t handle, uint32_t pos)
{
    if (handle < 0) {
        return -1;
    }
    const uint32_t block[2] = {(uint32_t)handle, pos};
    return (sh_call(MD_SH_SYS_SEEK, block) == 0u) ? 0 : -1;
}

int32_t md_sh_close(int32_t handle)
{
    if (handle < 0) {
        return -1;
    }
    const uint32_t block[1] = {(uint32_t)handle};
    return (sh_call(MD_SH_SYS_CLOSE, block) == 0u) ? 0 : -1;
}

void md_sh_write0(const char *s)
{
    if (s != NULL) {
        (void)sh_call(MD_SH_SYS_WRITE0, s);
    }
}

void md_sh_writec(char c)
{
    (void)sh_call(MD_SH_SYS_WRITEC, &c);
}

void md_sh_write_hex(uint32_t v)
{
    static const char digits[] = "0123456789abcdef";
    char buf[11];
    buf[0] = '0';
    buf[1] = 'x';
    for (unsigned i = 0u; i < 8u; ++i) {
        buf[2u + i] = digits[(v >> (28u - 4u * i)) & 0xFu];
    }
    buf[10] = '\0';
    md_sh_write0(buf);
}

void md_sh_write_uint(uint32_t v)
{
    char buf[11];
    unsigned n = sizeof buf - 1u;
    buf[n] = '\0';
    do {
        buf[--n] = (char)('0' + (char)(v % 10u));
        v /= 10u;
    } while (v != 0u && n > 0u);
    md_sh_write0(&buf[n]);
}

uint32_t md_sh_exit_status(int code)
{
    if (code >= 0 && code <= 255) {
        return (uint32_t)code;
    }
    return 255u;
}

void md_sh_exit(int code)
{
    const uint32_t status = md_sh_exit_status(code);
    const uint32_t block[2] = {MD_SH_ADP_STOPPED_APPLICATION_EXIT, status};
    (void)sh_call(MD_SH_SYS_EXIT_EXTENDED, block);

    /* Only reached if the host does not implement SYS_EXIT_EXTENDED: the
     * AArch32 SYS_EXIT takes the reason in r1 and cannot carry a status. */
    const uint32_t reason = (status == 0u) ? MD_SH_ADP_STOPPED_APPLICATION_EXIT : MD_SH_ADP_STOPPED_RUNTIME_ERROR;
    (void)sh_call(MD_SH_SYS_EXIT, (const void *)reason);

    /* No host answered: park the core. This is the one unbounded loop of the
     * port, reached only after the program has ended; a real board's watchdog
     * resets it. */
    for (;;) {
        __asm__ volatile("wfi");
    }
}
