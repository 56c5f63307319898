/* firmware_sim: the dynval library in a DAQ firmware loop. One thread, one poll loop over a
 * raw SocketCAN socket and a Modbus TCP server; see README.md. */
#define _GNU_SOURCE
#include <errno.h>
#include <getopt.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sim_can.h"
#include "sim_core.h"
#include "sim_modbus.h"

enum { EXIT_USAGE = 2, EXIT_CAN = 3, EXIT_MODBUS = 4 };

/* The one piece of state a signal handler may touch (async-signal-safe); all else is in ctx. */
static volatile sig_atomic_t g_stop;

struct sim_ctx {
    const char *ifname;    /* CAN interface, NULL = none */
    const char *mb_addr;   /* Modbus listen address */
    int mb_port;           /* Modbus TCP port */
    const char *log_path;  /* candump -L log, NULL = none */
    const char *replay;    /* candump -L file fed in before the loop, NULL = none */
    int verbose;
    unsigned long replay_bad; /* unparsable replay lines (reported on stderr) */
    FILE *log;
    struct sim_can can;
    int have_can;
    struct sim_modbus mb;
    struct sim_core core;
    dv_can_frame_t out[SIM_CORE_MAX_OUT];
};

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

static void usage(const char *argv0)
{
    fprintf(stderr,
            "usage: %s [options]\n"
            "  -i, --iface NAME     SocketCAN interface (default vcan0; 'none' = Modbus only)\n"
            "  -p, --port N         Modbus TCP port (default 1502)\n"
            "  -a, --addr A         Modbus listen address (default 127.0.0.1; 0.0.0.0 = all)\n"
            "  -l, --log FILE       log every frame in and out, candump -L format\n"
            "  -r, --replay FILE    feed the frames of a candump -L file in before the loop\n"
            "  -c, --channels N     channels (default 5)\n"
            "  -w, --win N          sliding window, samples (default 256)\n"
            "  -s, --seg N          segment length, samples (default 64)\n"
            "  -n, --nseg N         segments per record (default 64)\n"
            "  -f, --fs HZ          sample rate of every channel (default 640)\n"
            "  -H, --heartbeat MS   DV_STATUS period, 0 = off (default 1000)\n"
            "  -A, --ar-order P     AR stage order, 0 = off (default 0)\n"
            "  -o, --outlier X100   AR outlier threshold, sigma x 100 (default 600)\n"
            "  -F, --force-chan CH  observer input channel (default 0)\n"
            "  -d, --resid-decim N  residual frame every N observer steps, 0 = none (default 1)\n"
            "  -m, --model LIST     observer model: comma-separated floats in the order of\n"
            "                       SIM_MODEL_* (sim_regmap.h): n_dof, 8 masses, 8 k, 8 zeta,\n"
            "                       q, r, input_dof; missing values are 0\n"
            "  -v, --verbose        report startup and shutdown on stderr\n"
            "  -h, --help\n"
            "exit status: 0 clean shutdown (SIGINT/SIGTERM), 1 runtime error (a log write failed,\n"
            "             e.g. disk full; an unreadable replay file), 2 usage,\n"
            "             3 CAN interface unusable, 4 Modbus port unusable (e.g. busy)\n",
            argv0);
}

static int parse_u16(const char *s, unsigned lo, unsigned hi, uint16_t *out)
{
    char *end;
    errno = 0;
    unsigned long v = strtoul(s, &end, 10);
    if (errno != 0 || *s == '\0' || *end != '\0' || v < lo || v > hi) {
        return -1;
    }
    *out = (uint16_t)v;
    return 0;
}

static int parse_model(const char *s, float *model)
{
    char *end;
    int i = 0;
    memset(model, 0, SIM_N_MODEL * sizeof *model);
    while (*s != '\0') {
        if (i == SIM_N_MODEL) {
            return -1;
        }
        errno = 0;
        model[i++] = strtof(s, &end);
        if (errno != 0 || end == s || (*end != ',' && *end != '\0')) {
            return -1;
        }
        s = *end == ',' ? end + 1 : end;
    }
    return 0;
}

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static void send_frames(struct sim_ctx *x, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        if (x->have_can && sim_can_write(&x->can, &x->out[i]) != 0) {
            x->core.n.tx_errors++;
            continue;
        }
        x->core.n.tx_frames++;
        if (x->log != NULL) {
            sim_can_log(x->log, x->ifname != NULL ? x->ifname : "none", &x->out[i]);
        }
    }
}

static void handle_frame(struct sim_ctx *x, const dv_can_frame_t *f)
{
    if (x->log != NULL) {
        sim_can_log(x->log, x->ifname != NULL ? x->ifname : "none", f);
    }
    send_frames(x, sim_core_handle(&x->core, f, x->out));
}

static int replay_file(struct sim_ctx *x)
{
    FILE *in = fopen(x->replay, "r");
    if (in == NULL) {
        fprintf(stderr, "firmware_sim: cannot open replay file %s: %s\n", x->replay,
                strerror(errno));
        return -1;
    }
    char line[256];
    dv_can_frame_t f;
    unsigned long lineno = 0, bad = 0, first_bad = 0;
    while (fgets(line, sizeof line, in) != NULL) {
        lineno++;
        const size_t len = strlen(line);
        int long_line = len == sizeof line - 1 && line[len - 1] != '\n';
        if (sim_can_parse_log_line(line, &f) && !long_line) {
            handle_frame(x, &f);
        } else if (line[strspn(line, " \t\r\n")] != '\0') { /* blank lines are no error */
            bad++;
            first_bad = first_bad != 0 ? first_bad : lineno;
        }
        while (long_line && fgets(line, sizeof line, in) != NULL) { /* skip the rest */
            long_line = line[strlen(line) - 1] != '\n';
        }
    }
    const int read_err = ferror(in);
    fclose(in);
    if (read_err) {
        fprintf(stderr, "firmware_sim: cannot read replay file %s\n", x->replay);
        return -1;
    }
    if (bad != 0) { /* counted and reported; the good lines were fed in */
        fprintf(stderr, "firmware_sim: replay file %s: %lu unparsable line(s) skipped, first "
                        "at line %lu\n", x->replay, bad, first_bad);
    }
    x->replay_bad = bad;
    return 0;
}

static int run(struct sim_ctx *x)
{
    struct pollfd pfd[2 + SIM_MB_MAX_CLIENTS];
    while (!g_stop) {
        int n = 0;
        int can_i = -1;
        if (x->have_can) {
            can_i = n;
            pfd[n++] = (struct pollfd){.fd = x->can.fd, .events = POLLIN};
        }
        const int lis_i = n;
        pfd[n++] = (struct pollfd){.fd = x->mb.listen_fd, .events = POLLIN};
        int slot[SIM_MB_MAX_CLIENTS];
        const int cli0 = n;
        for (int i = 0; i < SIM_MB_MAX_CLIENTS; i++) {
            if (x->mb.clients[i].fd >= 0) {
                slot[n - cli0] = i;
                pfd[n++] = (struct pollfd){.fd = x->mb.clients[i].fd, .events = POLLIN};
            }
        }
        const int rc = poll(pfd, (nfds_t)n, 50);
        if (rc < 0) {
            if (errno == EINTR) {
                continue;
            }
            perror("firmware_sim: poll");
            return 1;
        }
        if (can_i >= 0 && (pfd[can_i].revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
            fprintf(stderr, "firmware_sim: CAN interface %s failed (down or removed)\n",
                    x->ifname);
            return EXIT_CAN;
        }
        if (can_i >= 0 && (pfd[can_i].revents & POLLIN) != 0) {
            /* drain the queue (bounded, so Modbus is served under a flood) */
            dv_can_frame_t f;
            for (int k = 0; k < 4096 && !g_stop; k++) {
                const int r = sim_can_read(&x->can, &f);
                if (r < 0) {
                    perror("firmware_sim: CAN read");
                    return EXIT_CAN;
                }
                if (r == 0) {
                    break;
                }
                handle_frame(x, &f);
            }
            x->core.n.dropped = x->can.ovfl;
            if (x->can.ovfl != 0u) {
                x->core.overflowed = 1;
            }
        }
        const uint64_t now = now_ns();
        /* clients first, then new ones (which may take the slot of the one idle longest) */
        for (int k = cli0; k < n; k++) {
            if ((pfd[k].revents & (POLLIN | POLLHUP | POLLERR | POLLNVAL)) != 0 &&
                x->mb.clients[slot[k - cli0]].fd == pfd[k].fd) {
                sim_modbus_serve(&x->mb, slot[k - cli0], &x->core, now);
            }
        }
        if ((pfd[lis_i].revents & POLLIN) != 0) {
            sim_modbus_accept(&x->mb, now);
        }
        sim_modbus_tick(&x->mb, now);
        send_frames(x, sim_core_tick(&x->core, now, x->out));
        if (x->log != NULL && (fflush(x->log) != 0 || ferror(x->log))) {
            fprintf(stderr, "firmware_sim: cannot write log %s: %s\n", x->log_path,
                    strerror(errno));
            return 1; /* a log that silently stops is worse than no firmware_sim */
        }
    }
    return 0;
}

/* The command line into x and cfg: -1 to go on, else the exit status (--help: 0; a bad
 * option, value or configuration: EXIT_USAGE, said on stderr). */
static int parse_args(int argc, char **argv, struct sim_ctx *x, struct sim_config *cfg)
{
    static const struct option opts[] = {
        {"iface", required_argument, NULL, 'i'},   {"port", required_argument, NULL, 'p'},
        {"addr", required_argument, NULL, 'a'},    {"log", required_argument, NULL, 'l'},
        {"replay", required_argument, NULL, 'r'},  {"channels", required_argument, NULL, 'c'},
        {"win", required_argument, NULL, 'w'},     {"seg", required_argument, NULL, 's'},
        {"nseg", required_argument, NULL, 'n'},    {"fs", required_argument, NULL, 'f'},
        {"heartbeat", required_argument, NULL, 'H'}, {"verbose", no_argument, NULL, 'v'},
        {"ar-order", required_argument, NULL, 'A'}, {"outlier", required_argument, NULL, 'o'},
        {"force-chan", required_argument, NULL, 'F'},
        {"resid-decim", required_argument, NULL, 'd'}, {"model", required_argument, NULL, 'm'},
        {"help", no_argument, NULL, 'h'},          {NULL, 0, NULL, 0}};
    x->ifname = "vcan0";
    x->mb_addr = "127.0.0.1";
    x->mb_port = 1502;
    sim_config_default(cfg);
    uint16_t port = 1502, fs = 640;
    int c;
    while ((c = getopt_long(argc, argv, "i:p:a:l:r:c:w:s:n:f:H:A:o:F:d:m:vh", opts, NULL)) != -1) {
        int bad = 0;
        switch (c) {
        case 'i': x->ifname = strcmp(optarg, "none") == 0 ? NULL : optarg; break;
        case 'p': bad = parse_u16(optarg, 1, 65535, &port); break;
        case 'a': x->mb_addr = optarg; break;
        case 'l': x->log_path = optarg; break;
        case 'r': x->replay = optarg; break;
        case 'c': bad = parse_u16(optarg, 1, SIM_MAX_CHAN, &cfg->n_chan); break;
        case 'w': bad = parse_u16(optarg, 2, 65535, &cfg->win_len); break;
        case 's': bad = parse_u16(optarg, 2, 65535, &cfg->seg_len); break;
        case 'n': bad = parse_u16(optarg, 1, 4096, &cfg->n_seg); break;
        case 'f': bad = parse_u16(optarg, 1, 65535, &fs); break;
        case 'H': bad = parse_u16(optarg, 0, 65535, &cfg->heartbeat_ms); break;
        case 'A': bad = parse_u16(optarg, 0, 32, &cfg->ar_order); break;
        case 'o': bad = parse_u16(optarg, 0, 65535, &cfg->outlier_x100); break;
        case 'F': bad = parse_u16(optarg, 0, SIM_MAX_CHAN - 1, &cfg->force_chan); break;
        case 'd': bad = parse_u16(optarg, 0, 65535, &cfg->resid_decim); break;
        case 'm': bad = parse_model(optarg, cfg->model); break;
        case 'v': x->verbose = 1; break;
        case 'h': usage(argv[0]); return 0;
        default: usage(argv[0]); return EXIT_USAGE;
        }
        if (bad) {
            fprintf(stderr, "firmware_sim: bad value '%s' for -%c\n", optarg, c);
            usage(argv[0]);
            return EXIT_USAGE;
        }
    }
    if (optind != argc) {
        fprintf(stderr, "firmware_sim: unexpected argument '%s'\n", argv[optind]);
        usage(argv[0]);
        return EXIT_USAGE;
    }
    x->mb_port = port;
    for (int i = 0; i < SIM_MAX_CHAN; i++) {
        cfg->fs_hz[i] = fs;
    }
    const int bad_reg = sim_config_check(cfg);
    if (bad_reg >= 0) {
        fprintf(stderr, "firmware_sim: bad configuration (holding register %d)\n", bad_reg);
        usage(argv[0]);
        return EXIT_USAGE;
    }
    return -1;
}

int main(int argc, char **argv)
{
    struct sim_ctx *x = calloc(1, sizeof *x);
    if (x == NULL) {
        fprintf(stderr, "firmware_sim: out of memory\n");
        return 1;
    }
    struct sim_config cfg;
    const int parsed = parse_args(argc, argv, x, &cfg);
    if (parsed >= 0) {
        free(x);
        return parsed;
    }
    if (sim_core_init(&x->core, &cfg) != 0) {
        fprintf(stderr, "firmware_sim: out of memory\n");
        free(x);
        return EXIT_USAGE;
    }

    char err[256];
    int status = 0;
    x->mb.listen_fd = -1;
    if (x->ifname != NULL) {
        if (sim_can_open(&x->can, x->ifname, err, sizeof err) != 0) {
            fprintf(stderr, "firmware_sim: %s\n", err);
            status = EXIT_CAN;
            goto out;
        }
        x->have_can = 1;
    }
    if (sim_modbus_open(&x->mb, x->mb_addr, x->mb_port, err, sizeof err) != 0) {
        fprintf(stderr, "firmware_sim: %s\n", err);
        status = EXIT_MODBUS;
        goto out;
    }
    if (x->log_path != NULL) {
        x->log = fopen(x->log_path, "w");
        if (x->log == NULL) {
            fprintf(stderr, "firmware_sim: cannot write log %s: %s\n", x->log_path,
                    strerror(errno));
            status = 1;
            goto out;
        }
    }
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal; /* no SA_RESTART: poll() returns EINTR at once */
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN); /* a Modbus client vanishing must not kill us */

    if (x->replay != NULL && replay_file(x) != 0) {
        status = 1;
        goto out;
    }
    if (x->log != NULL && (fflush(x->log) != 0 || ferror(x->log))) {
        /* the replayed part is complete in the log once "ready" is out */
        fprintf(stderr, "firmware_sim: cannot write log %s: %s\n", x->log_path, strerror(errno));
        status = 1;
        goto out;
    }
    if (x->verbose) {
        fprintf(stderr,
                "firmware_sim: CAN %s, Modbus TCP %s:%d, %u channels, real %zu bytes, "
                "AR order %u, observer %s\n",
                x->ifname != NULL ? x->ifname : "none", x->mb_addr, x->mb_port,
                (unsigned)cfg.n_chan, dv_real_size(), (unsigned)cfg.ar_order,
                x->core.obs_status == SIM_STAGE_RUNNING ? "running"
                : x->core.obs_status == SIM_STAGE_ERROR ? "FAILED (model or gain)"
                                                        : "off");
    }
    /* the "ready" line test fixtures wait for, instead of sleeping */
    printf("firmware_sim ready can=%s modbus=%s:%d\n", x->ifname != NULL ? x->ifname : "none",
           x->mb_addr, x->mb_port);
    fflush(stdout);
    status = run(x);
    if (x->verbose) {
        fprintf(stderr, "firmware_sim: stopping: rx %u tx %u frames\n",
                (unsigned)x->core.n.rx_frames, (unsigned)x->core.n.tx_frames);
    }
out:
    if (x->log != NULL && fclose(x->log) != 0 && status == 0) {
        fprintf(stderr, "firmware_sim: cannot write log %s: %s\n", x->log_path, strerror(errno));
        status = 1;
    }
    if (x->mb.ctx != NULL) {
        sim_modbus_close(&x->mb);
    }
    if (x->have_can) {
        sim_can_close(&x->can);
    }
    sim_core_free(&x->core);
    free(x);
    return status;
}
