/* Modbus TCP port of firmware_sim. Each client's bytes are gathered without blocking until a
 * whole request is in (see sim_modbus.h); libmodbus then answers it (modbus_reply with a
 * mapping: reads, illegal functions and addresses). Writes to the holding registers (0x06,
 * 0x10, 0x16 mask write, 0x17) are checked here first: a register outside the map gets
 * exception 0x02, a bad value exception 0x03, and either changes nothing. */
#define _GNU_SOURCE
#include "sim_modbus.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define MBAP_LEN 7 /* transaction id, protocol id, length, unit id */

int sim_modbus_open(struct sim_modbus *m, const char *addr, int port, char *err, size_t err_len)
{
    memset(m, 0, sizeof *m);
    m->listen_fd = -1;
    for (int i = 0; i < SIM_MB_MAX_CLIENTS; i++) {
        m->clients[i].fd = -1;
    }
    struct in_addr ip;
    if (inet_pton(AF_INET, addr, &ip) != 1) { /* libmodbus would bind INADDR_NONE quietly */
        snprintf(err, err_len, "Modbus listen address '%s' is not an IPv4 address", addr);
        return -1;
    }
    m->ctx = modbus_new_tcp(addr, port);
    if (m->ctx == NULL) {
        snprintf(err, err_len, "modbus_new_tcp(%s, %d): %s", addr, port, modbus_strerror(errno));
        return -1;
    }
    m->map = modbus_mapping_new_start_address(0, 0, 0, 0, 0, SIM_N_HOLDING, 0, SIM_N_INPUT);
    if (m->map == NULL) {
        snprintf(err, err_len, "modbus_mapping_new: %s", modbus_strerror(errno));
        modbus_free(m->ctx);
        m->ctx = NULL;
        return -1;
    }
    m->listen_fd = modbus_tcp_listen(m->ctx, SIM_MB_MAX_CLIENTS);
    if (m->listen_fd < 0 || fcntl(m->listen_fd, F_SETFL, O_NONBLOCK) != 0) {
        snprintf(err, err_len, "cannot listen on Modbus TCP %s:%d: %s%s", addr, port,
                 modbus_strerror(errno),
                 errno == EADDRINUSE ? " (port busy: another server running?)" : "");
        if (m->listen_fd >= 0) {
            close(m->listen_fd);
            m->listen_fd = -1;
        }
        modbus_mapping_free(m->map);
        modbus_free(m->ctx);
        m->map = NULL;
        m->ctx = NULL;
        return -1;
    }
    return 0;
}

static void drop_client(struct sim_modbus *m, int i)
{
    close(m->clients[i].fd);
    m->clients[i].fd = -1;
    m->clients[i].len = 0;
}

void sim_modbus_accept(struct sim_modbus *m, uint64_t now_ns)
{
    for (int k = 0; k < 4 * SIM_MB_MAX_CLIENTS; k++) { /* bounded: a connect flood waits */
        const int fd = accept4(m->listen_fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            return; /* EAGAIN: none left (or a transient error: the next poll retries) */
        }
        const int one = 1;
        (void)setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        int slot = 0;
        for (int i = 0; i < SIM_MB_MAX_CLIENTS; i++) {
            if (m->clients[i].fd < 0) {
                slot = i;
                break;
            }
            if (m->clients[i].t_active_ns < m->clients[slot].t_active_ns) {
                slot = i; /* all taken: the one idle longest makes room */
            }
        }
        if (m->clients[slot].fd >= 0) {
            drop_client(m, slot);
            m->evicted++;
        }
        m->clients[slot].fd = fd;
        m->clients[slot].len = 0;
        m->clients[slot].t_active_ns = now_ns;
    }
}

static int get16(const uint8_t *p)
{
    return (p[0] << 8) | p[1];
}

/* Holding registers that hold a configuration value (sim_regmap.h); the gaps are unmapped. */
static int hr_mapped(int r)
{
    return (r >= 0 && r <= SIM_HR_RECORDING && r != 4) ||
           (r >= SIM_HR_LSB && r < SIM_HR_LSB + 2 * SIM_MAX_CHAN) ||
           (r >= SIM_HR_FS_CH && r < SIM_HR_FS_CH + SIM_MAX_CHAN) ||
           (r >= SIM_HR_MODEL && r < SIM_N_HOLDING);
}

/* For a write to holding registers (0x06, 0x10, 0x16 mask write, 0x17): apply it to a copy
 * of the registers and check the result. Returns 0 when the request is no write or is
 * acceptable (*is_write says which), else the Modbus exception code: 0x02 when a register is
 * outside the map, 0x03 for a value out of range. Malformed writes are left to libmodbus. */
static int check_write(struct sim_modbus *m, const uint8_t *q, int len, struct sim_config *next,
                       int *is_write)
{
    const int h = modbus_get_header_length(m->ctx);
    const int fc = q[h];
    int addr, count;
    const uint8_t *vals = NULL;
    *is_write = 0;
    if (fc == MODBUS_FC_WRITE_SINGLE_REGISTER && len >= h + 5) {
        addr = get16(q + h + 1);
        count = 1;
        vals = q + h + 3;
    } else if (fc == MODBUS_FC_MASK_WRITE_REGISTER && len >= h + 7) {
        addr = get16(q + h + 1);
        count = 1;
    } else if (fc == MODBUS_FC_WRITE_MULTIPLE_REGISTERS && len >= h + 6) {
        addr = get16(q + h + 1);
        count = get16(q + h + 3);
        vals = q + h + 6;
        if (len < h + 6 + 2 * count || count < 1 || count > MODBUS_MAX_WRITE_REGISTERS) {
            return 0; /* malformed: libmodbus answers it */
        }
    } else if (fc == MODBUS_FC_WRITE_AND_READ_REGISTERS && len >= h + 10) {
        addr = get16(q + h + 5);
        count = get16(q + h + 7);
        vals = q + h + 10;
        if (len < h + 10 + 2 * count || count < 1 || count > MODBUS_MAX_WR_WRITE_REGISTERS) {
            return 0;
        }
    } else {
        return 0;
    }
    for (int r = addr; r < addr + count; r++) {
        if (!hr_mapped(r)) {
            return MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS;
        }
    }
    uint16_t regs[SIM_N_HOLDING];
    memcpy(regs, m->map->tab_registers, sizeof regs);
    if (vals == NULL) { /* mask write: (current AND and_mask) OR (or_mask AND NOT and_mask) */
        const int and_mask = get16(q + h + 3), or_mask = get16(q + h + 5);
        regs[addr] = (uint16_t)((regs[addr] & and_mask) | (or_mask & ~and_mask));
    } else {
        for (int i = 0; i < count; i++) {
            regs[addr + i] = (uint16_t)get16(vals + 2 * i);
        }
    }
    sim_config_from_regs(next, regs);
    if (sim_config_check(next) >= 0) {
        return MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE;
    }
    *is_write = 1;
    return 0;
}

/* Answer the whole request in client @p c's buffer. Returns -1 when the client must go. */
static int answer(struct sim_modbus *m, struct sim_mb_client *c, struct sim_core *core)
{
    const uint8_t *q = c->buf;
    const int len = c->len;
    modbus_set_socket(m->ctx, c->fd);
    m->requests++;
    sim_core_input_regs(core, m->map->tab_input_registers);
    sim_config_to_regs(&core->cfg, m->map->tab_registers);
    struct sim_config next = core->cfg;
    int is_write = 0;
    int exc = check_write(m, q, len, &next, &is_write);
    /* apply first, so a failed re-init (no memory) can still be refused */
    if (exc == 0 && is_write && sim_core_configure(core, &next) != 0) {
        exc = MODBUS_EXCEPTION_SLAVE_OR_SERVER_FAILURE;
    }
    if (exc != 0) {
        m->exceptions++;
        return modbus_reply_exception(m->ctx, q, (unsigned)exc) < 0 ? -1 : 0;
    }
    if (modbus_reply(m->ctx, q, len, m->map) < 0) {
        if (errno < MODBUS_ENOBASE) {
            return -1; /* could not send (the client does not read its replies): drop it */
        }
        m->exceptions++; /* libmodbus sent an exception (illegal function/address/value) */
    }
    return 0;
}

void sim_modbus_serve(struct sim_modbus *m, int i, struct sim_core *core, uint64_t now_ns)
{
    struct sim_mb_client *c = &m->clients[i];
    for (int k = 0; k < 2 * SIM_MB_MAX_PER_SERVE && c->fd >= 0; k++) {
        /* the header first, then exactly the rest of this request: never past its end */
        const int want = c->len < MBAP_LEN ? MBAP_LEN : 6 + get16(c->buf + 4);
        const ssize_t r = recv(c->fd, c->buf + c->len, (size_t)(want - c->len), 0);
        if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
            return; /* nothing more now */
        }
        if (r <= 0) {
            drop_client(m, i); /* EOF or error */
            return;
        }
        if (c->len == 0) {
            c->t_first_ns = now_ns;
        }
        c->len += (int)r;
        if (c->len == MBAP_LEN) {
            /* protocol id 0; length = unit id + PDU, 2 .. 254 (an ADU of at most 260 bytes) */
            const int n = get16(c->buf + 4);
            if (get16(c->buf + 2) != 0 || n < 2 || 6 + n > MODBUS_TCP_MAX_ADU_LENGTH) {
                drop_client(m, i);
                m->evicted++;
                return;
            }
        }
        if (c->len > MBAP_LEN - 1 && c->len == 6 + get16(c->buf + 4)) {
            if (answer(m, c, core) != 0) {
                drop_client(m, i);
                m->evicted++;
                return;
            }
            c->len = 0;
            c->t_active_ns = now_ns;
        }
    }
}

void sim_modbus_tick(struct sim_modbus *m, uint64_t now_ns)
{
    for (int i = 0; i < SIM_MB_MAX_CLIENTS; i++) {
        const struct sim_mb_client *c = &m->clients[i];
        if (c->fd < 0) {
            continue;
        }
        if ((c->len > 0 && now_ns - c->t_first_ns > SIM_MB_REQ_DEADLINE_MS * 1000000ull) ||
            now_ns - c->t_active_ns > SIM_MB_IDLE_MS * 1000000ull) {
            drop_client(m, i);
            m->evicted++;
        }
    }
}

void sim_modbus_close(struct sim_modbus *m)
{
    for (int i = 0; i < SIM_MB_MAX_CLIENTS; i++) {
        if (m->clients[i].fd >= 0) {
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
