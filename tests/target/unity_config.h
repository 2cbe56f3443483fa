/* Unity's configuration header in the Cortex-M7 build (cmake/md_unity.cmake
 * defines UNITY_INCLUDE_CONFIG_H there; the host build has none). Test output
 * goes to the line-buffered semihosting sink of md_target_putchar.c, which
 * Unity flushes after each test and before it abandons a failed one. These
 * are function-like macros, which CMake cannot pass as compile definitions. */
#ifndef UNITY_CONFIG_H
#define UNITY_CONFIG_H

void md_target_putchar(int c);
void md_target_flush(void);

#define UNITY_OUTPUT_CHAR(c) md_target_putchar(c)
#define UNITY_OUTPUT_FLUSH() md_target_flush()

#endif
