/* Output and exit of the M4 self-test programs: semihosting on the target (m4_plat_semi.c),
 * stdio on the host twin (m4_plat_host.c). No printf on the target: m4_fmt.c formats. */
#ifndef DV_M4_PLAT_H
#define DV_M4_PLAT_H

#include <stddef.h>
#include <stdint.h>

/** Write a NUL-terminated string to the console (semihosting SYS_WRITE0 on the target). */
void m4_write(const char *s);

/** Stop with an exit status (semihosting SYS_EXIT_EXTENDED on the target). */
void m4_exit(int status);

/* Line builder: append pieces, then m4_line_end() writes the line and a newline. */
void m4_put(const char *s);
void m4_put_u(uint32_t v);
void m4_put_hex32(uint32_t v);
void m4_put_e(double v); /* 3 significant digits, e.g. 1.23e-04 */
void m4_line_end(void);

#endif
