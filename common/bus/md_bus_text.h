/// @file md_bus_text.h
/// Frames as text, in can-utils syntax, so the project's buses read and write
/// like SocketCAN with candump/cansend (and logs load in cantools/python-can):
///   classic   123#DEADBEEF        1ABCDEF0#00.11.22   (3 hex digits = 11-bit,
///   CAN FD    123##1<hex data>    8 hex digits = 29-bit id; after "##" one hex
///                                 flag nibble: 1 = BRS, 2 = ESI, 4 = FDF)
/// Parsing takes BRS from the nibble and ignores ESI/FDF; formatting writes
/// 4 | BRS (4 or 5), exactly what candump -L prints on Linux >= 6.1.
/// No I/O, no allocation.
#ifndef MD_BUS_TEXT_H
#define MD_BUS_TEXT_H

#include <stddef.h>

#include "md_frame.h"

/// Longest text md_bus_text_format writes: 8 id + "##" + flag + 128 hex + NUL.
#define MD_BUS_TEXT_MAX 140u

/// Parses cansend syntax into *frame. Data bytes may be separated by '.'.
/// An FD payload whose length is not a CAN FD length is zero-padded up to the
/// next one, as cansend does. Refused (-EINVAL, *why set when non-NULL):
/// RTR frames ("123#R"), an 11-bit id above 0x7FF, a classic frame over 8
/// bytes, odd hex digits, trailing characters. Returns 0 or -EINVAL.
int md_bus_text_parse(const char *text, md_frame_t *frame, const char **why);

/// Formats a valid frame as candump -L does (uppercase hex, "ID#DATA" or
/// "ID##<flags>DATA", flags 4 or 5). Returns the text length, or -EINVAL for an invalid
/// frame or -ENOSPC if out_cap is too small.
int md_bus_text_format(const md_frame_t *frame, char *out, size_t out_cap);

#endif
