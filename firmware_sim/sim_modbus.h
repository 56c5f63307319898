/* Modbus TCP port of firmware_sim (libmodbus): the register map of sim_regmap.h served from
 * struct sim_core, several clients at once, driven by the caller's poll loop.
 *
 * No client can stall the loop or lock others out: sockets are non-blocking and each client's
 * bytes are gathered in its own buffer until a whole request is in (never a blocking
 * modbus_receive()); a request not complete SIM_MB_REQ_DEADLINE_MS after its first byte, a
 * client idle for SIM_MB_IDLE_MS, bad framing and a client that does not read its replies
 * (its socket buffer full) are closed; when every slot is taken, a new client takes the slot
 * of the one idle longest. */
#ifndef SIM_MODBUS_H
#define SIM_MODBUS_H

#include <modbus.h>
#include <stddef.h>
#include <stdint.h>

#include "sim_core.h"

#define SIM_MB_MAX_CLIENTS 8
#define SIM_MB_REQ_DEADLINE_MS 500 /* a whole request: < 1 ms on a LAN, 500 ms on a bad link */
#define SIM_MB_IDLE_MS 60000       /* a connection with no request for this long is closed */
#define SIM_MB_MAX_PER_SERVE 16    /* pipelined requests answered per readable event */

struct sim_mb_client {
    int fd;               /* -1 = free slot */
    int len;              /* bytes of the pending request in buf */
    uint64_t t_first_ns;  /* arrival of the pending request's first byte */
    uint64_t t_active_ns; /* accept or last complete request */
    uint8_t buf[MODBUS_TCP_MAX_ADU_LENGTH];
};

struct sim_modbus {
    modbus_t *ctx;
    modbus_mapping_t *map;
    int listen_fd;
    struct sim_mb_client clients[SIM_MB_MAX_CLIENTS];
    unsigned long requests, exceptions;
    unsigned long evicted; /* closed: deadline, idle, bad framing, replies not read, slot taken */
};

/* Listen on @p addr:@p port. 0, or -1 with a message in @p err (port busy, bad address). */
int sim_modbus_open(struct sim_modbus *m, const char *addr, int port, char *err, size_t err_len);

/* Accept the waiting clients (listen_fd readable); @p now_ns a monotonic clock. */
void sim_modbus_accept(struct sim_modbus *m, uint64_t now_ns);

/* Read what client slot @p i sent (its fd readable), answer every complete request in it;
 * closes the client on EOF, error or bad framing. Never blocks. */
void sim_modbus_serve(struct sim_modbus *m, int i, struct sim_core *core, uint64_t now_ns);

/* Close clients past their request deadline or idle too long; call at least every 100 ms. */
void sim_modbus_tick(struct sim_modbus *m, uint64_t now_ns);

void sim_modbus_close(struct sim_modbus *m);

#endif /* SIM_MODBUS_H */
