/* Host twin of the semihosting platform: the same program, output on stdout. */
#include <stdio.h>
#include <stdlib.h>

#include "m4_plat.h"

void m4_write(const char *s)
{
    fputs(s, stdout);
}

void m4_exit(int status)
{
    fflush(stdout);
    exit(status);
}
