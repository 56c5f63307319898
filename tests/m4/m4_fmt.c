/* Minimal line formatting for the self-test programs (no printf: newlib-nano's has no %a/%e
 * unless linked with float support, and the host twin must print the same bytes). */
#include "m4_plat.h"

static char line[256];
static size_t pos;

void m4_put(const char *s)
{
    while (*s != '\0') {
        if (pos + 3u >= sizeof line) { /* room for '\n' and NUL */
            m4_line_end();
        }
        line[pos++] = *s++;
    }
}

void m4_put_u(uint32_t v)
{
    char b[12];
    int i = 11;
    b[i] = '\0';
    do {
        b[--i] = (char)('0' + (int)(v % 10u));
        v /= 10u;
    } while (v != 0u);
    m4_put(&b[i]);
}

void m4_put_hex32(uint32_t v)
{
    static const char digits[] = "0123456789abcdef";
    char b[9];
    for (int i = 7; i >= 0; i--) {
        b[i] = digits[v & 0xfu];
        v >>= 4;
    }
    b[8] = '\0';
    m4_put(b);
}

void m4_put_e(double v)
{
    if (v != v) {
        m4_put("nan");
        return;
    }
    if (v < 0.0) {
        m4_put("-");
        v = -v;
    }
    if (v > 1e300) {
        m4_put("inf");
        return;
    }
    int e = 0;
    if (v != 0.0) {
        while (v >= 10.0) {
            v /= 10.0;
            e++;
        }
        while (v < 1.0) {
            v *= 10.0;
            e--;
        }
    }
    uint32_t m = (uint32_t)(v * 100.0 + 0.5); /* 3 significant digits */
    if (m >= 1000u) {
        m /= 10u;
        e++;
    }
    char b[16];
    b[0] = (char)('0' + (int)(m / 100u));
    b[1] = '.';
    b[2] = (char)('0' + (int)(m / 10u % 10u));
    b[3] = (char)('0' + (int)(m % 10u));
    b[4] = 'e';
    b[5] = e < 0 ? '-' : '+';
    int ae = e < 0 ? -e : e;
    b[6] = (char)('0' + ae / 10 % 10);
    b[7] = (char)('0' + ae % 10);
    b[8] = '\0';
    m4_put(b);
}

void m4_line_end(void)
{
    if (pos + 2u > sizeof line) {
        pos = sizeof line - 2u;
    }
    line[pos++] = '\n';
    line[pos] = '\0';
    m4_write(line);
    pos = 0u;
}
