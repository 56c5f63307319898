/**
 * @file dv_config.h
 * @brief Compile-time limits, each overridable with -D, each with its reason.
 */
#ifndef DV_CONFIG_H
#define DV_CONFIG_H

#include "dynval/dv_types.h"

/** Samples accumulated before a block is merged into the running moments (Chan/Pebay merge).
 * 64 keeps float partial sums within ~1e-6 relative and the merge cost (two divides)
 * amortised to well under one instruction per sample. */
#ifndef DV_BLOCK_LEN
#define DV_BLOCK_LEN 64u
#endif

/** Largest |x| the waveform features (moments, sliding window, segmented STD, temporal moments,
 * the channel bundle, correlation) accept; a larger sample is dropped and counted like NaN/Inf
 * (DV_ENUMERIC). Bound: the fourth power of a deviation (at most 2 DV_FEAT_MAX) summed over the
 * longest sliding window (2^24 samples) must stay finite, and so must a record's fourth central
 * sum for any count a record reaches in practice (float: 2^28 full-scale samples; beyond that
 * dv_moments_get() returns DV_ERANGE, never a NaN). Float: 2^24 = 16777216, every count of a
 * 24-bit ADC. Double: 2^200 (1.6e60): 2^64 samples at full scale stay finite. Powers of two, so
 * that x <= DV_FEAT_MAX is exact. */
#ifndef DV_FEAT_MAX
#ifdef DV_REAL_DOUBLE
#define DV_FEAT_MAX 1.6069380442589903e60 /* 2^200 */
#else
#define DV_FEAT_MAX 16777216.0f /* 2^24 */
#endif
#endif

/** Longest sliding window: ring and deque indices are 32-bit. */
#ifndef DV_SLIDING_MAX_LEN
#define DV_SLIDING_MAX_LEN 16777216u
#endif

DV_STATIC_ASSERT(DV_BLOCK_LEN >= 2u && DV_BLOCK_LEN <= 4096u, block_len_in_range);

/** Highest AR / ARX order. The report fits AR(30..60) (AR(50), and AR(60) for AR-ARX stage 1);
 * 64 covers that, and fixed-size coefficient arrays of 64 keep a model at 0.5 kB in double. */
#ifndef DV_AR_MAX_ORDER
#define DV_AR_MAX_ORDER 64u
#endif

DV_STATIC_ASSERT(DV_AR_MAX_ORDER >= 64u && DV_AR_MAX_ORDER <= 1024u, ar_max_order_in_range);

/** Degrees of freedom of the lumped-mass chain model. The report's frame has 4; 8 covers a
 * refined chain, keeps the state (2n <= 16) in a few cache lines and Jacobi/expm at init cheap. */
#ifndef DV_MAX_DOF
#define DV_MAX_DOF 8u
#endif

/** Nonlinear elements per model (dv_elem.h): the report has one bumper; 4 covers both sides of two. */
#ifndef DV_MAX_ELEM
#define DV_MAX_ELEM 4u
#endif

/** Linear links per model (dv_link_desc_t): springs and dashpots off the chain, e.g. an
 * appendage's mount or a coupling of two DOFs that are not neighbours. */
#ifndef DV_MAX_LINK
#define DV_MAX_LINK 4u
#endif

/** Output channels per model: accelerations of every DOF plus velocities/forces of 8 more. */
#ifndef DV_MAX_OUT
#define DV_MAX_OUT 16u
#endif

/** Contact sub-steps per sample: 16 keeps omega_contact * h <= 0.25 for a contact frequency up
 * to fs (at 640 Hz, the report's bumper needs 8); more only costs time per step. */
#ifndef DV_MAX_SUB
#define DV_MAX_SUB 16u
#endif

DV_STATIC_ASSERT(DV_MAX_DOF >= 8u && DV_MAX_DOF <= 32u, max_dof_in_range);
DV_STATIC_ASSERT(DV_MAX_ELEM >= 1u && DV_MAX_ELEM <= 16u, max_elem_in_range);
DV_STATIC_ASSERT(DV_MAX_LINK >= 1u && DV_MAX_LINK <= 16u, max_link_in_range);
DV_STATIC_ASSERT(DV_MAX_OUT >= 4u && DV_MAX_OUT <= 64u, max_out_in_range);
DV_STATIC_ASSERT(DV_MAX_SUB >= 1u && DV_MAX_SUB <= 64u, max_sub_in_range);

/** Longest FRF segment (dv_frf.h). 4096 points give 6.25 Hz bins at fs = 25.6 kHz and take
 * 7 * 4096 + 4 elements (112 kB in float) of caller storage; longer segments only trade RAM for
 * resolution a firmware FRF rarely needs. A power of two. */
#ifndef DV_FRF_MAX_SEG
#define DV_FRF_MAX_SEG 4096u
#endif

DV_STATIC_ASSERT(DV_FRF_MAX_SEG >= 64u && DV_FRF_MAX_SEG <= 65536u &&
                     (DV_FRF_MAX_SEG & (DV_FRF_MAX_SEG - 1u)) == 0u,
                 frf_max_seg_pow2_in_range);

#endif /* DV_CONFIG_H */
