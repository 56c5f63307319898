/* A firmware-style use of dynval: static storage, one update per sample, a check at the end. */
#include <math.h>
#include <stdio.h>

#include "dynval/dv.h"

enum { WIN = 64, SEG = 32, NSEG = 8 };
static dv_real_t buf[DV_CHAN_BUF_LEN(WIN, NSEG)];
static dv_chan_t chan;

int main(void)
{
    const dv_chan_config_t cfg = {WIN, SEG, NSEG, DV_R(1.0) / DV_R(640.0), false};
    if (dv_chan_init(&chan, &cfg, buf, sizeof buf / sizeof buf[0]) != DV_OK) return 1;
    int records = 0;
    for (int i = 0; i < SEG * NSEG; i++) {
        records += dv_chan_update(&chan, (dv_real_t)sin(2.0 * 3.141592653589793 * i / 32.0)) == DV_RECORD;
    }
    dv_stats_t st;
    if (records != 1 || dv_chan_get_record(&chan, &st, NULL) != DV_OK) return 1;
#if !DV_VERSION_AT_LEAST(0, 1, 0)
#error "dynval >= 0.1.0 expected"
#endif
    printf("consumer: dynval %s, %zu-byte samples, crest %.6f (sqrt 2 = 1.414214)\n",
           DV_VERSION_STRING, sizeof(dv_real_t), (double)st.crest);
    return fabs((double)st.crest - 1.4142135623730951) < 1e-4 ? 0 : 1;
}
