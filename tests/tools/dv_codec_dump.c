/* Line-oriented driver of the C codec for tests/py/test_dbc.py (not part of the library).
 * stdin, one request per line; stdout, one answer per line:
 *   E <kind> <fields...>   ->  OK <id hex> <8 data bytes hex> | ERR <status>
 *   D <id hex> <dlc> <hex> ->  OK <kind> <fields...>          | ERR <status>
 * kinds and fields (floats as the hex of their binary32 bits):
 *   status state beat lost dup late bad_dlc unknown | ctrl cmd record_id
 *   chcfg channel flags fs_hz lsb_bits | samples channel seq s0 s1 s2
 *   feature feat_id channel index value_bits | resid channel flags step value_bits
 * Build: cc -std=c99 -Iinclude tests/tools/dv_codec_dump.c src/dv_codec.c src/dv_common.c -lm */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dynval/dv_codec.h"

static float f_of(unsigned long bits)
{
    union {
        uint32_t u;
        float f;
    } b;
    b.u = (uint32_t)bits;
    return b.f;
}

static unsigned long bits_of(float f)
{
    union {
        uint32_t u;
        float f;
    } b;
    b.f = f;
    return (unsigned long)b.u;
}

static void encode(char *rest)
{
    char kind[16];
    long v[8] = {0};
    unsigned long fb = 0;
    dv_msg_t m;
    memset(&m, 0, sizeof m);
    if (sscanf(rest, "%15s", kind) != 1) {
        puts("ERR parse");
        return;
    }
    const char *p = rest + strlen(kind) + 1;
    if (strcmp(kind, "status") == 0) {
        sscanf(p, "%ld %ld %ld %ld %ld %ld %ld", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6]);
        m.kind = DV_MSG_STATUS;
        m.u.status.state = (uint8_t)v[0];
        m.u.status.beat = (uint8_t)v[1];
        m.u.status.lost = (uint16_t)v[2];
        m.u.status.dup = (uint8_t)v[3];
        m.u.status.late = (uint8_t)v[4];
        m.u.status.bad_dlc = (uint8_t)v[5];
        m.u.status.unknown = (uint8_t)v[6];
    } else if (strcmp(kind, "ctrl") == 0) {
        sscanf(p, "%ld %ld", &v[0], &v[1]);
        m.kind = DV_MSG_CTRL;
        m.u.ctrl.cmd = (uint8_t)v[0];
        m.u.ctrl.record_id = (uint32_t)v[1];
    } else if (strcmp(kind, "chcfg") == 0) {
        sscanf(p, "%ld %ld %ld %lx", &v[0], &v[1], &v[2], &fb);
        m.kind = DV_MSG_CHCFG;
        m.u.chcfg.channel = (uint8_t)v[0];
        m.u.chcfg.flags = (uint8_t)v[1];
        m.u.chcfg.fs_hz = (uint16_t)v[2];
        m.u.chcfg.lsb = f_of(fb);
    } else if (strcmp(kind, "samples") == 0) {
        sscanf(p, "%ld %ld %ld %ld %ld", &v[0], &v[1], &v[2], &v[3], &v[4]);
        m.kind = DV_MSG_SAMPLES;
        m.u.samples.channel = (uint8_t)v[0];
        m.u.samples.seq = (uint8_t)v[1];
        for (int i = 0; i < 3; i++) {
            m.u.samples.raw[i] = (int16_t)v[2 + i];
        }
    } else if (strcmp(kind, "feature") == 0 || strcmp(kind, "resid") == 0) {
        sscanf(p, "%ld %ld %ld %lx", &v[0], &v[1], &v[2], &fb);
        if (kind[0] == 'f') {
            m.kind = DV_MSG_FEATURE;
            m.u.feature.feat_id = (uint8_t)v[0];
            m.u.feature.channel = (uint8_t)v[1];
            m.u.feature.index = (uint16_t)v[2];
            m.u.feature.value = f_of(fb);
        } else {
            m.kind = DV_MSG_RESID;
            m.u.resid.channel = (uint8_t)v[0];
            m.u.resid.flags = (uint8_t)v[1];
            m.u.resid.step = (uint16_t)v[2];
            m.u.resid.value = f_of(fb);
        }
    }
    dv_can_frame_t f;
    const dv_status_t st = dv_codec_encode(&m, &f);
    if (st != DV_OK) {
        printf("ERR %s\n", dv_status_str(st));
        return;
    }
    printf("OK %03X ", (unsigned)f.id);
    for (int i = 0; i < f.dlc; i++) {
        printf("%02X", f.data[i]);
    }
    putchar('\n');
}

static void decode(char *rest)
{
    unsigned long id = 0;
    int dlc = 0;
    char hex[64] = "";
    if (sscanf(rest, "%lx %d %63s", &id, &dlc, hex) < 2) {
        puts("ERR parse");
        return;
    }
    dv_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = (uint32_t)id;
    f.dlc = (uint8_t)dlc;
    for (int i = 0; i < 8 && hex[2 * i] != '\0' && hex[2 * i + 1] != '\0'; i++) {
        char b[3] = {hex[2 * i], hex[2 * i + 1], '\0'};
        f.data[i] = (uint8_t)strtoul(b, NULL, 16);
    }
    dv_msg_t m;
    const dv_status_t st = dv_codec_decode(&f, &m);
    if (st != DV_OK) {
        printf("ERR %s\n", dv_status_str(st));
        return;
    }
    switch (m.kind) {
    case DV_MSG_STATUS:
        printf("OK status %u %u %u %u %u %u %u\n", m.u.status.state, m.u.status.beat,
               m.u.status.lost, m.u.status.dup, m.u.status.late, m.u.status.bad_dlc,
               m.u.status.unknown);
        break;
    case DV_MSG_CTRL:
        printf("OK ctrl %u %lu\n", m.u.ctrl.cmd, (unsigned long)m.u.ctrl.record_id);
        break;
    case DV_MSG_CHCFG:
        printf("OK chcfg %u %u %u %08lX\n", m.u.chcfg.channel, m.u.chcfg.flags, m.u.chcfg.fs_hz,
               bits_of(m.u.chcfg.lsb));
        break;
    case DV_MSG_SAMPLES:
        printf("OK samples %u %u %d %d %d\n", m.u.samples.channel, m.u.samples.seq,
               m.u.samples.raw[0], m.u.samples.raw[1], m.u.samples.raw[2]);
        break;
    case DV_MSG_FEATURE:
        printf("OK feature %u %u %u %08lX\n", m.u.feature.feat_id, m.u.feature.channel,
               m.u.feature.index, bits_of(m.u.feature.value));
        break;
    case DV_MSG_RESID:
        printf("OK resid %u %u %u %08lX\n", m.u.resid.channel, m.u.resid.flags, m.u.resid.step,
               bits_of(m.u.resid.value));
        break;
    default:
        puts("ERR kind");
    }
}

int main(void)
{
    char line[256];
    while (fgets(line, sizeof line, stdin) != NULL) {
        line[strcspn(line, "\r\n")] = '\0';
        if (line[0] == 'E' && line[1] == ' ') {
            encode(line + 2);
        } else if (line[0] == 'D' && line[1] == ' ') {
            decode(line + 2);
        } else {
            puts("ERR parse");
        }
    }
    return 0;
}
