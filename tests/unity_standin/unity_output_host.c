/* Host character sink of the Unity stand-in. */
#include <stdio.h>

#include "unity.h"

void unity_standin_putchar(int c)
{
    (void)putchar(c);
}
