/// @file md_status.h
/// Forwarding header for the files that still include "common/md_status.h":
/// the status codes live in common/status/md_status.h (library md_status,
/// shared with the plant). New code includes "md_status.h".
#ifndef MD_STATUS_FORWARD_H
#define MD_STATUS_FORWARD_H

/* Angle brackets: a quoted include would find this file again first. */
#include <md_status.h>

#endif
