/**
 * @file dv_version.h
 * @brief The library's version: the one place it is written (CMake's project() reads it).
 *
 * Compare with DV_VERSION_AT_LEAST() at compile time. The shared library's SONAME carries
 * DV_VERSION_MAJOR (libdynval-f64.so.0): a new major version is a new ABI.
 */
#ifndef DV_VERSION_H
#define DV_VERSION_H

/** Major version: incompatible API or ABI changes. */
#define DV_VERSION_MAJOR 0
/** Minor version: additions that keep the API and ABI. */
#define DV_VERSION_MINOR 1
/** Patch version: fixes only. */
#define DV_VERSION_PATCH 0
/** The version as one number, MAJOR * 10000 + MINOR * 100 + PATCH (0.1.0 is 100). */
#define DV_VERSION_NUMBER (DV_VERSION_MAJOR * 10000 + DV_VERSION_MINOR * 100 + DV_VERSION_PATCH)
/** The version as a string, "MAJOR.MINOR.PATCH". */
#define DV_VERSION_STRING "0.1.0"
/** True when the library is at least version @p maj.@p min.@p pat. */
#define DV_VERSION_AT_LEAST(maj, min, pat) \
    (DV_VERSION_NUMBER >= (maj) * 10000 + (min) * 100 + (pat))

#endif /* DV_VERSION_H */
