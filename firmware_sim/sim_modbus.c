/* Modbus TCP port of firmware_sim. libmodbus answers reads and refuses illegal functions and
 * addresses itself (modbus_reply with a mapping); writes to the holding registers are checked
 * here first, so a bad value gets exception 0x03 and changes nothing. */
#define _GNU_SOURCE
#include "sim_modbus.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

int sim_modbus_open(struct sim_modbus *m, const char *addr, int port, char *err, size_t err_len)
{
    memset(m, 0, sizeof *m);
    m->listen_fd = -1;
    for (int i = 0; i < SIM_MB_MAX_CLIENTS; i++) {
        m->clients[i] = -1;
    }
    m->ctx = modbus_new_tcp(addr, port);
    if (m->ctx == NULL) {
        snprintf(err, err_len, "modbus_new_tcp(%s, %d): %s", addr, port, modbus_strerror(errno));
        return -1;
    }
    /* a client that stalls mid-request must not hang the CAN loop for long */
    modbus_set_indication_timeout(m->ctx, 0, 200000);
    m->map = modbus_mapping_new_start_address(0, 0, 0, 0, 0, SIM_N_HOLDING, 0, SIM_N_INPUT);
    if (m->map == NULL) {
        snprintf(err, err_len, "modbus_mapping_new: %s", modbus_strerror(errno));
        modbus_free(m->ctx);
        m->ctx = NULL;
        return -1;
    }
    m->listen_fd = modbus_tcp_listen(m->ctx, SIM_MB_MAX_CLIENTS);
    if (m->listen_fd < 0) {
        snprintf(err, err_len, "cannot listen on Modbus TCP %s:%d: %s%s", addr, port,
                 modbus_strerror(errno),
                 errno == EADDRINUSE ? " (port busy: another server running?)" : "");
        modbus_mapping_free(m->map);
        modbus_free(m->ctx);
        m->map = NULL;
        m->ctx = NULL;
        return -1;
    }
    return 0;
}

void sim_modbus_accept(struct sim_modbus *m)
{
    int s = m->listen_fd;
    int fd = modbus_tcp_accept(m->ctx, &s); /* does not touch listen_fd on success */
    if (fd < 0) {
        return;
    }
    for (int i = 0; i < SIM_MB_MAX_CLIENTS; i++) {
        if (m->clients[i] < 0) {
            m->clients[i] = fd;
            return;
        }
    }
    close(fd); /* full: the client sees the connection closed */
}

static void drop_client(struct sim_modbus *m, int i)
{
    close(m->clients[i]);
    m->clients[i] = -1;
}

static int get16(const uint8_t *p)
{
    return (p[0] << 8) | p[1];
}

/* For a write to holding registers: apply it to a copy of the registers and check the result.
 * Returns 0 when the request is no write or is acceptable, else the Modbus exception code.
 * Address errors are left to libmodbus (exception 0x02). */
static int check_write(struct sim_modbus *m, int len, struct sim_config *next, int *is_write)
{
    const int h = modbus_get_header_length(m->ctx);
    const uint8_t *q = m->query;
    const int fc = q[h];
    int addr, count;
    const uint8_t *vals;
    *is_write = 0;
    if (fc == MODBUS_FC_WRITE_SINGLE_REGISTER && len >= h + 5) {
        addr = get16(q + h + 1);
        count = 1;
        vals = q + h + 3;
    } else if (fc == MODBUS_FC_WRITE_MULTIPLE_REGISTERS && len >= h + 6) {
        addr = get16(q + h + 1);
        count = get16(q + h + 3);
        vals = q + h + 6;
        if (len < h + 6 + 2 * count) {
            return 0; /* malformed: libmodbus answers it */
        }
    } else if (fc == MODBUS_FC_WRITE_AND_READ_REGISTERS && len >= h + 10) {
        addr = get16(q + h + 5);
        count = get16(q + h + 7);
        vals = q + h + 10;
        if (len < h + 10 + 2 * count) {
            return 0;
        }
    } else {
        return 0;
    }
    if (addr < 0 || count < 1 || addr + count > SIM_N_HOLDING) {
        return 0;
    }
    uint16_t regs[SIM_N_HOLDING];
    memcpy(regs, m->map->tab_registers, sizeof regs);
    for (int i = 0; i < count; i++) {
        regs[addr + i] = (uint16_t)get16(vals + 2 * i);
    }
    sim_config_from_regs(next, regs);
    if (sim_config_check(next) >= 0) {
        return MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE;
    }
    *is_write = 1;
    return 0;
}

void sim_modbus_serve(struct sim_modbus *m, int i, struct sim_core *core)
{
    modbus_set_socket(m->ctx, m->clients[i]);
    const int len = modbus_receive(m->ctx, m->query);
    if (len < 0) {
        drop_client(m, i); /* EOF, timeout mid-request, or garbage framing */
        return;
    }
    if (len == 0) {
        return; /* a request for another unit: ignored */
    }
    m->requests++;
    sim_core_input_regs(core, m->map->tab_input_registers);
    sim_config_to_regs(&core->cfg, m->map->tab_registers);
    struct sim_config next = core->cfg;
    int is_write = 0;
    const int exc = check_write(m, len, &next, &is_write);
    if (exc != 0) {
        m->exceptions++;
        modbus_reply_exception(m->ctx, m->query, (unsigned)exc);
        return;
    }
    if (is_write) {
        /* apply first, so a failed re-init (no memory) can still be refused */
        if (sim_core_configure(core, &next) != 0) {
            m->exceptions++;
            modbus_reply_exception(m->ctx, m->query, MODBUS_EXCEPTION_SLAVE_OR_SERVER_FAILURE);
            return;
        }
    }
    if (modbus_reply(m->ctx, m->query, len, m->map) < 0) {
        if (errno >= MODBUS_ENOBASE) {
            m->exceptions++; /* libmodbus sent an exception (illegal function/address) */
        } else {
            drop_client(m, i);
        }
    }
}

void sim_modbus_close(struct sim_modbus *m)
{
    for (int i = 0; i < SIM_MB_MAX_CLIENTS; i++) {
        if (m->clients[i] >= 0) {
            drop_client(m, i);
        }
    }
    if (m->listen_fd >= 0) {
        close(m->listen_fd);
        m->listen_fd = -1;
    }
    if (m->map != NULL) {
        modbus_mapping_free(m->map);
        m->map = NULL;
    }
    if (m->ctx != NULL) {
        modbus_free(m->ctx);
        m->ctx = NULL;
    }
}
