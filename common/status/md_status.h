/// @file md_status.h
/// Status codes shared by every firmware unit and by the simulated plant
/// (host_sim), so that the plant needs no firmware library.
///
/// Every fallible firmware function returns an md_status_t. Zero is success,
/// every failure is negative so that `if (st < 0) { return st; }` reads as a
/// ladder (littlefs style). Callers count failures; nothing is dropped silently.
#ifndef MD_STATUS_H
#define MD_STATUS_H

typedef enum {
    MD_OK = 0,
    MD_E_ARG = -1,         ///< an argument is out of range or NULL
    MD_E_CAPACITY = -2,    ///< a compile-time capacity would be exceeded
    MD_E_NUMERIC = -3,     ///< a matrix was singular / not positive definite, or a NaN appeared
    MD_E_DEGENERATE = -4,  ///< too few or collinear points for the requested model
    MD_E_NOCONVERGE = -5,  ///< the iteration bound was reached without convergence
    MD_E_STATE = -6,       ///< the call is not valid in the unit's current state
    MD_E_FRAME = -7,       ///< an external frame failed validation (id, length, range, sequence)
    MD_E_TIMEOUT = -8,     ///< a deadline passed (heartbeat, stream, motion)
    MD_E_IO = -9           ///< the platform failed to send/receive
} md_status_t;

/// Short constant name of a status code, for logs and test messages.
const char *md_status_name(md_status_t status);

#endif
