/* Cortex-M character sink of the Unity stand-in: line-buffered semihosting.
 * One SYS_WRITE0 per line instead of one trap per character keeps test output
 * cheap under QEMU; md_m7_exit flushes the rest (also after a fault). */
#include <stddef.h>

#include "md_m7_semihost.h"
#include "md_m7_startup.h"
#include "unity.h"

#define LINE_MAX_CHARS 160u

static char line_buf[LINE_MAX_CHARS + 1u];
static size_t line_len;

static void flush_line(void)
{
    line_buf[line_len] = '\0';
    md_sh_write0(line_buf);
    line_len = 0u;
}

void unity_standin_putchar(int c)
{
    md_m7_exit_hook = flush_line;
    line_buf[line_len++] = (char)c;
    if (c == '\n' || line_len >= LINE_MAX_CHARS) {
        flush_line();
    }
}
