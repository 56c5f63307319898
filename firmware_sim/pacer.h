/* dv_pacer's records and deadline arithmetic (pacer.c; the gateway side: dynval.pacing). */
#ifndef DV_PACER_H
#define DV_PACER_H

#include <linux/can.h>
#include <stdint.h>
#include <time.h>

#define PACER_MAX_BATCH 64             /* frames per sendmmsg */
#define PACER_SETTLE_NS 2000000        /* start = first record + 2 ms */
#define PACER_MARGIN_NS 100000         /* sleep to 100 us before a deadline, poll the rest */
#define PACER_NS_PER_S 1000000000LL

/* One frame to send (24 bytes, host byte order). */
struct pacer_in {
    int64_t offset_ns;      /* due time from the start, at speed 1 */
    struct can_frame frame; /* can_id (CAN_EFF_FLAG for 29-bit ids), len, data */
};

/* One batch sent (24 bytes, host byte order). */
struct pacer_out {
    int64_t offset_ns; /* due time from the start, at the replay's speed */
    int64_t error_ns;  /* sendmmsg returned minus the deadline */
    uint32_t frames;   /* sent */
    uint32_t failed;   /* not sent */
};

/* A recorded offset at a replay speed: truncated like the gateway's int(offset / speed). */
static inline int64_t pacer_offset_ns(int64_t offset_ns, double speed)
{
    return (int64_t)((double)offset_ns / speed);
}

static inline int64_t pacer_now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * PACER_NS_PER_S + t.tv_nsec;
}

static inline struct timespec pacer_timespec(int64_t ns)
{
    struct timespec t;
    t.tv_sec = (time_t)(ns / PACER_NS_PER_S);
    t.tv_nsec = (long)(ns % PACER_NS_PER_S);
    return t;
}

/* Return at an absolute CLOCK_MONOTONIC deadline: sleep (absolute, so an interrupted or late
 * sleep does not add up) to margin_ns before it, then poll the clock. */
static inline void pacer_wait_until(int64_t deadline_ns, int64_t margin_ns)
{
    if (deadline_ns - pacer_now_ns() > margin_ns) {
        struct timespec t = pacer_timespec(deadline_ns - margin_ns);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, NULL) != 0) {
        }
    }
    while (pacer_now_ns() < deadline_ns) {
    }
}

#endif
