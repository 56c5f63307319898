/* SocketCAN port of firmware_sim: a raw CAN socket on one interface, frames as dv_can_frame_t,
 * the kernel's receive-overflow count, and candump -L logging. */
#ifndef SIM_CAN_H
#define SIM_CAN_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "dynval/dv_codec.h"

struct sim_can {
    int fd;              /* raw CAN socket, -1 when closed */
    char ifname[32];     /* interface name */
    uint32_t ovfl;       /* frames dropped by the kernel (SO_RXQ_OVFL), cumulative */
};

/* Open and bind. 0, or -1 with a message in @p err (no such interface, no CAN support...). */
int sim_can_open(struct sim_can *s, const char *ifname, char *err, size_t err_len);

/* Read one frame without blocking: 1 = got one, 0 = none waiting, -1 = error (errno). */
int sim_can_read(struct sim_can *s, dv_can_frame_t *f);

/* Write one frame: 0, or -1 (errno). */
int sim_can_write(struct sim_can *s, const dv_can_frame_t *f);

void sim_can_close(struct sim_can *s);

/* One line of `candump -L` format: "(sec.usec) IFNAME ID#DATA". */
void sim_can_log(FILE *log, const char *ifname, const dv_can_frame_t *f);

/* Parse one candump -L line into @p f: 1 on success, 0 if the line is not a well-formed frame
 * (3 or 8 hex digits of id, whole hex bytes, at most 8 of them, nothing else on the line). */
int sim_can_parse_log_line(const char *line, dv_can_frame_t *f);

#endif /* SIM_CAN_H */
