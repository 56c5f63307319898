/* Offline reference for the end-to-end test: the features the library computes on a sample
 * stream, printed as the feature frames firmware_sim should send (written independently of
 * firmware_sim/sim_core.c, from the rules in can/dynval.dbc and firmware_sim/README.md).
 * stdin:  config N_CHAN WIN_LEN SEG_LEN N_SEG
 *         chan CH FS_HZ LSB_BITS_HEX        (one per channel)
 *         s CH RAW                          (accepted samples in arrival order)
 * stdout: F FEAT_ID CH INDEX VALUE_BITS_HEX (one per feature frame, per channel in order) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dynval/dv.h"

#define MAXC 8

static unsigned long bits(dv_real_t v)
{
    union {
        float f;
        unsigned int u;
    } b;
    b.f = (float)v; /* the wire type */
    return b.u;
}

static void emit(int id, int ch, unsigned idx, dv_real_t v)
{
    printf("F %d %d %u %08lX\n", id, ch, idx & 0xFFFFu, bits(v));
}

int main(void)
{
    char line[256];
    unsigned n_chan = 0, win = 0, seg = 0, nseg = 0;
    dv_chan_t ch[MAXC];
    dv_real_t *buf[MAXC] = {0};
    float lsb[MAXC];
    unsigned segs[MAXC] = {0}, recs[MAXC] = {0};
    while (fgets(line, sizeof line, stdin) != NULL) {
        unsigned c, fs;
        unsigned long lb;
        int raw;
        if (sscanf(line, "config %u %u %u %u", &n_chan, &win, &seg, &nseg) == 4) {
            continue;
        }
        if (sscanf(line, "chan %u %u %lx", &c, &fs, &lb) == 3 && c < MAXC) {
            union {
                unsigned int u;
                float f;
            } b;
            b.u = (unsigned int)lb;
            lsb[c] = b.f;
            dv_chan_config_t cc = {win, seg, nseg, (dv_real_t)1 / (dv_real_t)fs};
            size_t len = DV_CHAN_BUF_LEN(win, nseg);
            buf[c] = malloc(len * sizeof(dv_real_t));
            if (buf[c] == NULL || dv_chan_init(&ch[c], &cc, buf[c], len) != DV_OK) {
                fprintf(stderr, "offline: bad channel config\n");
                return 1;
            }
            continue;
        }
        if (sscanf(line, "s %u %d", &c, &raw) != 2 || c >= MAXC || buf[c] == NULL) {
            continue;
        }
        const dv_real_t x = dv_codec_sample_value((int16_t)raw, lsb[c]);
        const dv_status_t st = dv_chan_update(&ch[c], x);
        if (st != DV_DONE && st != DV_RECORD) {
            continue;
        }
        const unsigned s = segs[c]++;
        dv_real_t sd;
        uint32_t si;
        if (dv_segstd_last(&ch[c].seg, &sd, &si) == DV_OK) {
            emit(DV_FEAT_SEG_STD, (int)c, s, sd);
        }
        dv_stats_t w;
        if (dv_chan_get_window(&ch[c], &w) == DV_OK) {
            emit(DV_FEAT_WIN_MEAN, (int)c, s, w.mean);
            emit(DV_FEAT_WIN_STD, (int)c, s, w.std);
            emit(DV_FEAT_WIN_RMS, (int)c, s, w.rms);
            emit(DV_FEAT_WIN_PEAK, (int)c, s, w.peak);
        }
        if (st != DV_RECORD) {
            continue;
        }
        const unsigned r = recs[c]++;
        dv_stats_t rs;
        dv_temporal_out_t tm;
        const dv_status_t gs = dv_chan_get_record(&ch[c], &rs, &tm);
        if (gs != DV_OK && gs != DV_ENUMERIC) {
            continue;
        }
        emit(DV_FEAT_REC_MEAN, (int)c, r, rs.mean);
        emit(DV_FEAT_REC_STD, (int)c, r, rs.std);
        emit(DV_FEAT_REC_RMS, (int)c, r, rs.rms);
        if (!(rs.flags & DV_STATS_NO_SHAPE)) {
            emit(DV_FEAT_REC_SKEW, (int)c, r, rs.skew);
            emit(DV_FEAT_REC_KURT, (int)c, r, rs.kurt);
        }
        emit(DV_FEAT_REC_PEAK, (int)c, r, rs.peak);
        emit(DV_FEAT_REC_MIN, (int)c, r, rs.min);
        emit(DV_FEAT_REC_MAX, (int)c, r, rs.max);
        if (!(rs.flags & DV_STATS_NO_CREST)) {
            emit(DV_FEAT_REC_CREST, (int)c, r, rs.crest);
        }
        emit(DV_FEAT_REC_KFACTOR, (int)c, r, rs.kfactor);
        if (gs == DV_OK) {
            emit(DV_FEAT_TM_ENERGY, (int)c, r, tm.energy);
            emit(DV_FEAT_TM_CTIME, (int)c, r, tm.central_time);
            emit(DV_FEAT_TM_RMSDUR, (int)c, r, tm.rms_duration);
            emit(DV_FEAT_TM_CSKEW, (int)c, r, tm.central_skew);
            emit(DV_FEAT_TM_CKURT, (int)c, r, tm.central_kurt);
            emit(DV_FEAT_TM_AE, (int)c, r, tm.root_energy_amp);
        }
    }
    for (unsigned c = 0; c < MAXC; c++) {
        free(buf[c]);
    }
    (void)n_chan;
    return 0;
}
