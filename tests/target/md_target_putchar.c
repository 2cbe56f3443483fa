/* Cortex-M character sink of Unity (UNITY_OUTPUT_CHAR / UNITY_OUTPUT_FLUSH in
 * unity_config.h beside this file): line-buffered semihosting. One SYS_WRITE0 per
 * line instead of one trap per character keeps test output cheap under QEMU;
 * md_m7_exit flushes the rest (also after a fault). */
#include <stddef.h>

#include "md_m7_semihost.h"
#include "md_m7_startup.h"
#include "unity.h"

#define LINE_MAX_CHARS 160u

static char line_buf[LINE_MAX_CHARS + 1u];
static size_t line_len;

void md_target_flush(void)
{
    if (line_len > 0u) {
        line_buf[line_len] = '\0';
        md_sh_write0(line_buf);
        line_len = 0u;
    }
}

void md_target_putchar(int c)
{
    md_m7_exit_hook = md_target_flush;
    line_buf[line_len++] = (char)c;
    if (c == '\n' || line_len >= LINE_MAX_CHARS) {
        md_target_flush();
    }
}
