/* dv_pacer: send CAN frames at absolute deadlines, for `dynval replay` on SocketCAN.
 *
 *   dv_pacer [-i IFACE | -o FILE] [-s SPEED] [-m MARGIN_US] [-r PRIO]  < frames  > report
 *
 * stdin: records of struct pacer_in (below: the offset from the start in ns, then a Linux
 * struct can_frame), in send order; records with equal offsets form one batch, sent by one
 * sendmmsg(2). Batch k is due at start + offset / SPEED on CLOCK_MONOTONIC (start: 2 ms after
 * the first record arrives), waited for by clock_nanosleep(TIMER_ABSTIME) to MARGIN_US before
 * the deadline, then by polling the clock: absolute deadlines, so a late batch never shifts the
 * later ones. -o FILE writes the frames to FILE instead of a CAN socket (a sink for tests and
 * for timing the pacer alone). -r PRIO: SCHED_FIFO at PRIO and memory locked (a warning if the
 * system refuses it).
 * stdout: one struct pacer_out per batch (its due offset, the time sendmmsg returned minus the
 * deadline, frames sent and failed); the gateway turns these into its timing statistics.
 * Exit status: 0 all sent, 1 some frames failed, 2 bad usage or setup. */
#define _GNU_SOURCE
#include "pacer.h"

#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <unistd.h>

#define BUF_RECORDS 4096 /* read-ahead; stdin is a pipe the gateway fills */

struct input {
    struct pacer_in rec[BUF_RECORDS];
    size_t head, count;
    int eof;
};

/* Read when fewer than want records are buffered: as much as the pipe holds and the buffer
 * takes, blocking until want are there or the input ends. */
static int fill(struct input *in, size_t want)
{
    while (!in->eof && in->count < want && in->count < BUF_RECORDS) {
        if (in->head > 0) { /* keep the buffered records at the front */
            memmove(in->rec, in->rec + in->head, in->count * sizeof in->rec[0]);
            in->head = 0;
        }
        size_t room = (BUF_RECORDS - in->count) * sizeof in->rec[0];
        ssize_t n = read(STDIN_FILENO, (char *)in->rec + in->count * sizeof in->rec[0], room);
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n <= 0) {
            in->eof = 1;
            break;
        }
        size_t got = (size_t)n;
        while (got % sizeof in->rec[0] != 0) { /* finish a record split by the pipe */
            ssize_t m = read(STDIN_FILENO, (char *)in->rec + in->count * sizeof in->rec[0] + got,
                             sizeof in->rec[0] - got % sizeof in->rec[0]);
            if (m <= 0) {
                fprintf(stderr, "dv_pacer: input ends inside a record\n");
                in->eof = 1;
                break;
            }
            got += (size_t)m;
        }
        in->count += got / sizeof in->rec[0];
    }
    return in->count > 0;
}

/* The next batch: the buffered records sharing the first one's offset (at most max). */
static size_t next_batch(struct input *in, size_t max)
{
    if (!fill(in, 2)) {
        return 0;
    }
    size_t n = 1;
    for (;;) {
        while (n < in->count && n < max && in->rec[in->head + n].offset_ns ==
                                              in->rec[in->head].offset_ns) {
            n++;
        }
        if (n < in->count || n == max || in->eof || in->count == BUF_RECORDS) {
            return n;
        }
        fill(in, in->count + 1); /* the batch may continue in data not read yet */
    }
}

static int open_can(const char *ifname)
{
    int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (fd < 0) {
        fprintf(stderr, "dv_pacer: cannot open a CAN socket: %s\n", strerror(errno));
        return -1;
    }
    unsigned idx = if_nametoindex(ifname);
    if (idx == 0) {
        fprintf(stderr, "dv_pacer: CAN interface '%s' not found: %s\n", ifname, strerror(errno));
        close(fd);
        return -1;
    }
    /* we only send: receive nothing, so other nodes' traffic cannot fill our queue */
    (void)setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, NULL, 0);
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = (int)idx;
    if (bind(fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        fprintf(stderr, "dv_pacer: cannot bind to '%s': %s\n", ifname, strerror(errno));
        close(fd);
        return -1;
    }
    return fd;
}

/* Send n frames: one sendmmsg, retried while the interface queue is full (ENOBUFS) for up
 * to 100 ms. Returns the frames sent. */
static size_t send_can(int fd, const struct pacer_in *rec, size_t n)
{
    struct mmsghdr msg[PACER_MAX_BATCH];
    struct iovec iov[PACER_MAX_BATCH];
    memset(msg, 0, n * sizeof msg[0]);
    for (size_t k = 0; k < n; k++) {
        iov[k].iov_base = (void *)&rec[k].frame;
        iov[k].iov_len = sizeof rec[k].frame;
        msg[k].msg_hdr.msg_iov = &iov[k];
        msg[k].msg_hdr.msg_iovlen = 1;
    }
    size_t done = 0;
    while (done < n) {
        int r = sendmmsg(fd, msg + done, (unsigned)(n - done), 0);
        if (r > 0) {
            done += (size_t)r;
            continue;
        }
        if (r < 0 && errno == EINTR) {
            continue;
        }
        struct pollfd p = {.fd = fd, .events = POLLOUT, .revents = 0};
        if (r < 0 && (errno == ENOBUFS || errno == EAGAIN) && poll(&p, 1, 100) > 0) {
            continue;
        }
        break;
    }
    return done;
}

static size_t send_file(FILE *f, const struct pacer_in *rec, size_t n)
{
    size_t k = 0;
    while (k < n && fwrite(&rec[k].frame, sizeof rec[k].frame, 1, f) == 1) {
        k++;
    }
    return k;
}

static void go_realtime(int prio)
{
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = prio;
    if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0) {
        fprintf(stderr, "dv_pacer: SCHED_FIFO refused (%s); normal priority\n",
                strerror(errno));
    } else if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
        fprintf(stderr, "dv_pacer: mlockall refused (%s)\n", strerror(errno));
    }
}

static int usage(void)
{
    fprintf(stderr, "usage: dv_pacer (-i IFACE | -o FILE) [-s SPEED] [-m MARGIN_US] [-r PRIO]"
                    " < frames > report\n");
    return 2;
}

int main(int argc, char **argv)
{
    const char *iface = NULL, *out = NULL;
    double speed = 1.0;
    int64_t margin_ns = PACER_MARGIN_NS;
    int prio = 0, opt;
    while ((opt = getopt(argc, argv, "i:o:s:m:r:")) != -1) {
        switch (opt) {
        case 'i': iface = optarg; break;
        case 'o': out = optarg; break;
        case 's': speed = strtod(optarg, NULL); break;
        case 'm': margin_ns = (int64_t)(strtod(optarg, NULL) * 1e3); break;
        case 'r': prio = atoi(optarg); break;
        default: return usage();
        }
    }
    if ((iface == NULL) == (out == NULL) || !(speed > 0.0) || margin_ns < 0) {
        return usage();
    }
    int fd = -1;
    FILE *sink = NULL;
    if (iface != NULL && (fd = open_can(iface)) < 0) {
        return 2;
    }
    if (out != NULL && (sink = fopen(out, "wb")) == NULL) {
        fprintf(stderr, "dv_pacer: cannot write %s: %s\n", out, strerror(errno));
        return 2;
    }
    if (prio > 0) {
        go_realtime(prio);
    }
    static struct input in;
    int64_t start = 0;
    long failed_total = 0;
    size_t n;
    while ((n = next_batch(&in, PACER_MAX_BATCH)) > 0) {
        const struct pacer_in *b = &in.rec[in.head];
        if (start == 0) {
            start = pacer_now_ns() + PACER_SETTLE_NS;
        }
        int64_t due = start + pacer_offset_ns(b->offset_ns, speed);
        pacer_wait_until(due, margin_ns);
        size_t sent = fd >= 0 ? send_can(fd, b, n) : send_file(sink, b, n);
        struct pacer_out rep = {.offset_ns = due - start, .error_ns = pacer_now_ns() - due,
                                .frames = (uint32_t)sent, .failed = (uint32_t)(n - sent)};
        failed_total += (long)(n - sent);
        if (fwrite(&rep, sizeof rep, 1, stdout) != 1) {
            fprintf(stderr, "dv_pacer: cannot write the report: %s\n", strerror(errno));
            return 2;
        }
        in.head += n;
        in.count -= n;
    }
    fflush(stdout);
    if (sink != NULL && fclose(sink) != 0) {
        return 2;
    }
    if (fd >= 0) {
        close(fd);
    }
    return failed_total > 0 ? 1 : 0;
}
