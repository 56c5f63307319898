/**
 * @file dv_types.h
 * @brief The sample type, status codes and small macros shared by every dynval module.
 *
 * dv_real_t is float unless DV_REAL_DOUBLE is defined (CMake: DV_REAL_TYPE=double).
 * The artefact name carries the type (libdynval-f32.a / libdynval-f64.a), so linking
 * code compiled for one type against the other fails loudly at link time.
 */
#ifndef DV_TYPES_H
#define DV_TYPES_H

#include <stddef.h>
#include <stdint.h>
#include <stdbool.h>

#ifdef __cplusplus
extern "C" {
#endif

#ifdef DV_REAL_DOUBLE
/** The sample type: double (DV_REAL_DOUBLE defined), else float. */
typedef double dv_real_t;
/** A literal of the sample type: DV_R(0.5) is 0.5 (double) or 0.5f (float). */
#define DV_R(x) (x)
/** Machine epsilon of the sample type. */
#define DV_REAL_EPS 2.220446049250313e-16
/** Largest finite value of the sample type. */
#define DV_REAL_MAX 1.7976931348623157e308
#else
/** The sample type: float (DV_REAL_DOUBLE not defined), else double. */
typedef float dv_real_t;
/** A literal of the sample type: DV_R(0.5) is 0.5f (float) or 0.5 (double). */
#define DV_R(x) (x##f)
/** Machine epsilon of the sample type. */
#define DV_REAL_EPS 1.1920929e-07f
/** Largest finite value of the sample type. */
#define DV_REAL_MAX 3.4028235e38f
#endif

/** Status of every fallible call. DV_OK is 0, errors are negative, information positive. */
typedef enum {
    DV_OK = 0,          /**< success */
    DV_DONE = 1,        /**< success, and this sample completed a segment */
    DV_RECORD = 2,      /**< success, and this sample completed a segment and its record */
    DV_EINVAL = -1,     /**< bad argument: NULL pointer, zero length, out-of-range config */
    DV_ESIZE = -2,      /**< caller buffer too small */
    DV_ENOTREADY = -3,  /**< not enough samples yet; outputs left untouched */
    DV_ENUMERIC = -4,   /**< NaN/Inf input (dropped), or an undefined result (e.g. x/0) */
    DV_EUNSTABLE = -5,  /**< singular, ill-conditioned or unstable model */
    DV_ERANGE = -6      /**< value outside the representable or configured range */
} dv_status_t;

/** @brief Text for a status code ("DV_OK", ...); never NULL, "DV_E?" for unknown codes. */
const char *dv_status_str(dv_status_t st);

/** @brief Size of dv_real_t in bytes (4 or 8): lets bindings check the build they load. */
size_t dv_real_size(void);

#ifndef DV_ASSERT
#if defined(DV_DEBUG_ASSERT)
#include <assert.h>
/** Hot-path argument checks: a hook, active in Debug builds only (no abort in release). */
#define DV_ASSERT(c) assert(c)
#else
/** Hot-path argument checks: a hook, active in Debug builds only (no abort in release). */
#define DV_ASSERT(c) ((void)0)
#endif
#endif

#ifdef DV_CDEF
#define DV_STATIC_ASSERT(cond, msg)
#else
/** C99 compile-time check: a negative array size fails the build. (Empty for the cffi cdef,
 * which is the preprocessed headers and has no use for it.) */
#define DV_STATIC_ASSERT(cond, msg) typedef char dv_static_assert_##msg[(cond) ? 1 : -1]
#endif

#ifdef __cplusplus
}
#endif

#endif /* DV_TYPES_H */
