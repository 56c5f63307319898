/* Offline reference for the end-to-end test: the features the library computes on a sample
 * stream, printed as the feature frames firmware_sim should send (written independently of
 * firmware_sim/sim_core.c, from the rules in can/dynval.dbc and firmware_sim/README.md).
 * stdin:  config N_CHAN WIN_LEN SEG_LEN N_SEG
 *         chan CH FS_HZ LSB_BITS_HEX        (one per channel)
 *         [ar ORDER OUTLIER_X100]           (AR stage: Burg fit on the first record)
 *         [model FORCE_CH DECIM P0 .. P31]  (observer: the 32 model parameters of
 *                                            firmware_sim/sim_regmap.h, binary32 bits in hex)
 *         s CH RAW                          (accepted samples in arrival order)
 * stdout: F FEAT_ID CH INDEX VALUE_BITS_HEX (feature frames, per channel in order)
 *         R CH STEP VALUE_BITS_HEX          (observer residual frames) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dynval/dv.h"

#define MAXC 8
#define NPAR 32
#define MAXS 200000 /* samples per channel kept for the observer */

static float fbits(unsigned long b)
{
    union {
        unsigned int u;
        float f;
    } x;
    x.u = (unsigned int)b;
    return x.f;
}

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
    unsigned fs_ch[MAXC] = {0};
    /* AR stage */
    unsigned ar_p = 0, ar_k100 = 0;
    dv_real_t *base[MAXC] = {0};
    unsigned nbase[MAXC] = {0};
    int ar_ok[MAXC] = {0};
    dv_ar_model_t arm[MAXC];
    dv_ar_resid_t arr[MAXC];
    dv_real_t arh[MAXC][DV_AR_RESID_BUF_LEN(DV_AR_MAX_ORDER)];
    dv_moments_t armom[MAXC];
    unsigned arout[MAXC] = {0};
    /* observer */
    int have_model = 0;
    unsigned force_ch = 0, decim = 1;
    float par[NPAR];
    static dv_real_t obs_x[MAXC][MAXS];
    size_t obs_n[MAXC] = {0};
    static char line2[2048];
    while (fgets(line2, sizeof line2, stdin) != NULL) {
        unsigned c, fs;
        unsigned long lb;
        int raw;
        memcpy(line, line2, sizeof line - 1);
        line[sizeof line - 1] = '\0';
        if (sscanf(line2, "ar %u %u", &ar_p, &ar_k100) == 2) {
            continue;
        }
        if (strncmp(line2, "model ", 6) == 0) {
            char *p = line2 + 6;
            force_ch = (unsigned)strtoul(p, &p, 10);
            decim = (unsigned)strtoul(p, &p, 10);
            for (int i = 0; i < NPAR; i++) {
                par[i] = fbits(strtoul(p, &p, 16));
            }
            have_model = 1;
            continue;
        }
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
            fs_ch[c] = fs;
            dv_chan_config_t cc = {win, seg, nseg, (dv_real_t)1 / (dv_real_t)fs, false};
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
        if (obs_n[c] < MAXS) {
            obs_x[c][obs_n[c]++] = x; /* NaN too: it keeps its time slot */
        }
        const dv_status_t st = dv_chan_update(&ch[c], x);
        /* AR: first record is the baseline, then residual RMS + outliers per record */
        dv_real_t ar_rms = 0;
        int ar_emit = 0;
        if (ar_p > 0 && st != DV_ENUMERIC) {
            const unsigned rl = seg * nseg;
            if (!ar_ok[c]) {
                if (base[c] == NULL) {
                    base[c] = malloc(rl * sizeof(dv_real_t));
                }
                base[c][nbase[c]++] = x;
                if (nbase[c] == rl) {
                    size_t wl = DV_AR_WORK_LEN(rl, ar_p);
                    dv_real_t *w = malloc(wl * sizeof(dv_real_t));
                    if (dv_ar_fit(&arm[c], DV_AR_BURG, ar_p, base[c], rl, w, wl) != DV_OK ||
                        dv_ar_resid_init(&arr[c], &arm[c], arh[c], DV_AR_RESID_BUF_LEN(ar_p)) !=
                            DV_OK) {
                        fprintf(stderr, "offline: AR fit failed\n");
                        return 1;
                    }
                    free(w);
                    ar_ok[c] = 1;
                    dv_moments_init(&armom[c]);
                }
            } else {
                dv_real_t e;
                if (dv_ar_resid_update(&arr[c], x, &e) == DV_OK) {
                    dv_moments_update(&armom[c], e);
                    const dv_real_t k = (dv_real_t)ar_k100 / (dv_real_t)100;
                    if (ar_k100 != 0 && e * e > k * k * arm[c].sigma2) {
                        arout[c]++;
                    }
                }
                if (st == DV_RECORD) {
                    dv_stats_t es;
                    ar_emit = dv_moments_get(&armom[c], &es) == DV_OK;
                    ar_rms = es.rms;
                }
            }
        }
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
        if (ar_emit) {
            emit(DV_FEAT_AR_RESID_RMS, (int)c, r, ar_rms);
            if (ar_k100 != 0) {
                emit(DV_FEAT_AR_OUTLIERS, (int)c, r, (dv_real_t)arout[c]);
            }
        }
        if (st == DV_RECORD && ar_ok[c]) {
            arout[c] = 0;
            dv_moments_reset(&armom[c]);
        }
    }
    if (have_model && (unsigned)par[0] > 0) {
        const unsigned nd = (unsigned)par[0];
        dv_model_desc_t d;
        dv_model_desc_default(&d);
        d.n_dof = (uint16_t)nd;
        for (unsigned i = 0; i < nd; i++) {
            d.mass_kg[i] = (dv_real_t)par[1 + i];
            d.k_n_per_m[i] = (dv_real_t)par[9 + i];
            d.zeta[i] = (dv_real_t)par[17 + i];
        }
        d.damp_kind = DV_DAMP_MODAL;
        d.input_kind = DV_INPUT_FORCE;
        d.input_dof = (uint16_t)par[27];
        unsigned meas[DV_MAX_OUT], no = 0;
        for (unsigned c = 0; c < n_chan && no < nd; c++) {
            if (c != force_ch) {
                d.out[no].kind = DV_OUT_ACC;
                d.out[no].index = (uint16_t)no;
                meas[no++] = c;
            }
        }
        d.n_out = (uint16_t)no;
        static dv_model_t m;
        static dv_obs_t o;
        const dv_real_t dt = (dv_real_t)1 / (dv_real_t)fs_ch[force_ch];
        size_t ml = dv_model_buf_len(&d);
        dv_real_t *mb = malloc(ml * sizeof(dv_real_t));
        dv_obs_noise_t nz;
        memset(&nz, 0, sizeof nz);
        for (unsigned i = 0; i < DV_MAX_DOF; i++) nz.q_force_n2[i] = (dv_real_t)par[25];
        for (unsigned i = 0; i < DV_MAX_OUT; i++) nz.r_meas[i] = (dv_real_t)par[26];
        if (dv_model_init(&m, &d, dt, mb, ml) != DV_OK) {
            fprintf(stderr, "offline: model init failed\n");
            return 1;
        }
        size_t ol = dv_obs_buf_len(&m);
        dv_real_t *ob = malloc(ol * sizeof(dv_real_t));
        if (dv_obs_init(&o, &m, par[25] > 0.0f ? &nz : NULL, ob, ol) != DV_OK) {
            fprintf(stderr, "offline: observer init failed\n");
            return 1;
        }
        size_t steps = obs_n[force_ch];
        for (unsigned j = 0; j < no; j++) {
            steps = obs_n[meas[j]] < steps ? obs_n[meas[j]] : steps;
        }
        for (size_t k = 0; k < steps; k++) {
            dv_real_t y[DV_MAX_OUT], r[DV_MAX_OUT];
            for (unsigned j = 0; j < no; j++) y[j] = obs_x[meas[j]][k];
            (void)dv_obs_step(&o, obs_x[force_ch][k], y);
            if (dv_obs_get(&o, NULL, r, DV_MAX_OUT) != DV_OK || decim == 0 || k % decim != 0) {
                continue;
            }
            for (unsigned j = 0; j < no; j++) {
                printf("R %u %u %08lX\n", meas[j], (unsigned)(k & 0xFFFFu), bits(r[j]));
            }
        }
        free(mb);
        free(ob);
    }
    for (unsigned c = 0; c < MAXC; c++) {
        free(buf[c]);
        free(base[c]);
    }
    (void)n_chan;
    return 0;
}
