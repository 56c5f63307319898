/* SocketCAN port of firmware_sim. */
#define _GNU_SOURCE
#include "sim_can.h"

#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#ifndef SO_RXQ_OVFL
#define SO_RXQ_OVFL 40
#endif

int sim_can_open(struct sim_can *s, const char *ifname, char *err, size_t err_len)
{
    memset(s, 0, sizeof *s);
    s->fd = -1;
    snprintf(s->ifname, sizeof s->ifname, "%s", ifname);
    if (strlen(ifname) >= IFNAMSIZ) {
        snprintf(err, err_len, "CAN interface name '%s' is too long", ifname);
        return -1;
    }
    int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (fd < 0) {
        snprintf(err, err_len, "cannot open a CAN socket: %s (kernel without CAN support?)",
                 strerror(errno));
        return -1;
    }
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    memcpy(ifr.ifr_name, ifname, strlen(ifname));
    if (ioctl(fd, SIOCGIFINDEX, &ifr) < 0) {
        snprintf(err, err_len, "CAN interface '%s' not found: %s", ifname, strerror(errno));
        close(fd);
        return -1;
    }
    /* a deep receive queue: a burst of sample frames must not be lost while we compute */
    int sz = 8 << 20;
    if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &sz, sizeof sz) < 0) {
        (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &sz, sizeof sz);
    }
    int one = 1;
    (void)setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof one);
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (bind(fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        snprintf(err, err_len, "cannot bind to CAN interface '%s': %s", ifname, strerror(errno));
        close(fd);
        return -1;
    }
    s->fd = fd;
    return 0;
}

int sim_can_read(struct sim_can *s, dv_can_frame_t *f)
{
    struct can_frame cf;
    char ctrl[CMSG_SPACE(sizeof(uint32_t))];
    struct iovec iov = {.iov_base = &cf, .iov_len = sizeof cf};
    struct msghdr msg;
    memset(&msg, 0, sizeof msg);
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = ctrl;
    msg.msg_controllen = sizeof ctrl;
    ssize_t n = recvmsg(s->fd, &msg, MSG_DONTWAIT);
    if (n < 0) {
        return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? 0 : -1;
    }
    for (struct cmsghdr *c = CMSG_FIRSTHDR(&msg); c != NULL; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
            memcpy(&s->ovfl, CMSG_DATA(c), sizeof s->ovfl);
        }
    }
    if ((size_t)n != sizeof cf) {
        /* a CAN FD frame on an FD interface (we did not enable FD): report it as bad DLC */
        memset(f, 0, sizeof *f);
        f->id = cf.can_id;
        f->dlc = 0xFF;
        return 1;
    }
    f->id = cf.can_id;
    f->dlc = cf.can_dlc;
    memcpy(f->data, cf.data, 8);
    return 1;
}

int sim_can_write(struct sim_can *s, const dv_can_frame_t *f)
{
    struct can_frame cf;
    memset(&cf, 0, sizeof cf);
    cf.can_id = f->id;
    cf.can_dlc = f->dlc;
    memcpy(cf.data, f->data, 8);
    for (int tries = 0; tries < 100; tries++) {
        ssize_t n = write(s->fd, &cf, sizeof cf);
        if (n == (ssize_t)sizeof cf) {
            return 0;
        }
        if (n < 0 && errno != ENOBUFS && errno != EAGAIN && errno != EINTR) {
            return -1;
        }
        /* transmit queue full: wait for the driver to drain it */
        struct timespec ts = {0, 100000};
        nanosleep(&ts, NULL);
    }
    errno = ENOBUFS;
    return -1;
}

void sim_can_close(struct sim_can *s)
{
    if (s->fd >= 0) {
        close(s->fd);
    }
    s->fd = -1;
}

void sim_can_log(FILE *log, const char *ifname, const dv_can_frame_t *f)
{
    struct timeval tv;
    gettimeofday(&tv, NULL);
    if ((f->id & DV_CAN_EFF_FLAG) != 0u) {
        fprintf(log, "(%lld.%06ld) %s %08X#", (long long)tv.tv_sec, (long)tv.tv_usec, ifname,
                (unsigned)(f->id & 0x1FFFFFFFu));
    } else {
        fprintf(log, "(%lld.%06ld) %s %03X#", (long long)tv.tv_sec, (long)tv.tv_usec, ifname,
                (unsigned)(f->id & DV_CAN_SFF_MASK));
    }
    if ((f->id & DV_CAN_RTR_FLAG) != 0u) {
        fputc('R', log);
    } else {
        for (unsigned i = 0; i < f->dlc && i < 8u; i++) {
            fprintf(log, "%02X", f->data[i]);
        }
    }
    fputc('\n', log);
}

static int hexval(char c)
{
    return c >= '0' && c <= '9'   ? c - '0'
           : c >= 'A' && c <= 'F' ? c - 'A' + 10
           : c >= 'a' && c <= 'f' ? c - 'a' + 10
                                  : -1;
}

int sim_can_parse_log_line(const char *line, dv_can_frame_t *f)
{
    const char *p = strchr(line, ')');
    if (line[0] != '(' || p == NULL) {
        return 0;
    }
    p++;
    if (*p != ' ') {
        return 0;
    }
    while (*p == ' ') {
        p++;
    }
    p = strchr(p, ' '); /* skip the interface name */
    if (p == NULL) {
        return 0;
    }
    p++;
    const char *hash = strchr(p, '#');
    /* 3 hex digits: standard id, 8: extended; every character a hex digit */
    if (hash == NULL || (hash - p != 3 && hash - p != 8)) {
        return 0;
    }
    memset(f, 0, sizeof *f);
    for (const char *c = p; c < hash; c++) {
        const int v = hexval(*c);
        if (v < 0) {
            return 0;
        }
        f->id = (f->id << 4) | (uint32_t)v;
    }
    if (hash - p == 3 ? f->id > DV_CAN_SFF_MASK : f->id > 0x1FFFFFFFu) {
        return 0;
    }
    if (hash - p == 8) {
        f->id |= DV_CAN_EFF_FLAG;
    }
    const char *d = hash + 1;
    if (*d == 'R') {
        f->id |= DV_CAN_RTR_FLAG;
        d++;
    } else {
        unsigned n = 0;
        while (hexval(d[0]) >= 0) {
            const int lo = hexval(d[1]);
            if (n == 8u || lo < 0) {
                return 0; /* more than 8 bytes, or an odd digit */
            }
            f->data[n++] = (uint8_t)((hexval(d[0]) << 4) | lo);
            d += 2;
        }
        f->dlc = (uint8_t)n;
    }
    /* the end of the line, or candump's optional trailing flag field */
    return *d == '\0' || *d == '\n' || *d == '\r' || *d == ' ';
}
