/* Modbus TCP port of firmware_sim (libmodbus): the register map of sim_regmap.h served from
 * struct sim_core, several clients at once, driven by the caller's poll loop. */
#ifndef SIM_MODBUS_H
#define SIM_MODBUS_H

#include <modbus.h>
#include <stddef.h>

#include "sim_core.h"

#define SIM_MB_MAX_CLIENTS 8

struct sim_modbus {
    modbus_t *ctx;
    modbus_mapping_t *map;
    int listen_fd;
    int clients[SIM_MB_MAX_CLIENTS]; /* -1 = free slot */
    uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    unsigned long requests, exceptions;
};

/* Listen on @p addr:@p port. 0, or -1 with a message in @p err (port busy, bad address). */
int sim_modbus_open(struct sim_modbus *m, const char *addr, int port, char *err, size_t err_len);

/* Accept a waiting client (listen_fd readable). */
void sim_modbus_accept(struct sim_modbus *m);

/* Serve one request of client slot @p i (its fd readable); closes it on EOF or error. */
void sim_modbus_serve(struct sim_modbus *m, int i, struct sim_core *core);

void sim_modbus_close(struct sim_modbus *m);

#endif /* SIM_MODBUS_H */
