/**
 * @file dv_config.h
 * @brief Compile-time limits, each overridable with -D, each with its reason.
 */
#ifndef DV_CONFIG_H
#define DV_CONFIG_H

#include "dynval/dv_types.h"

/* Samples accumulated before a block is merged into the running moments (Chan/Pebay merge).
 * 64 keeps float partial sums within ~1e-6 relative and the merge cost (two divides)
 * amortised to well under one instruction per sample. */
#ifndef DV_BLOCK_LEN
#define DV_BLOCK_LEN 64u
#endif

/* Longest sliding window: ring and deque indices are 32-bit. */
#ifndef DV_SLIDING_MAX_LEN
#define DV_SLIDING_MAX_LEN 16777216u
#endif

DV_STATIC_ASSERT(DV_BLOCK_LEN >= 2u && DV_BLOCK_LEN <= 4096u, block_len_in_range);

#endif /* DV_CONFIG_H */
