/// @file fuzz_protocol.c
/// Fuzz target 2: every generated decoder of common/protocol/generated/md_can.h
/// on the same arbitrary bytes and length (the table of messages and signals
/// is extracted from md_can.h at configure time, so a message added to the DBC
/// is fuzzed without touching this file). Checks per message:
///  - unpack never reads past `size` (ASan: the bytes sit in a heap buffer of
///    exactly that size) and fails iff size < the DBC length;
///  - pack(unpack(x)) returns the DBC length and unpacks to the same struct
///    (the decoder loses nothing the encoder needs);
///  - pack refuses a destination shorter than the DBC length;
/// and per signal of a decoded message:
///  - decode of an integer raw value is finite; a raw value that passes
///    is_in_range decodes to a finite value that passes is_in_phys_range
///    (NaN and inf in float signals are out of range).
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_input.h"
#include "md_can.h"
#include "md_frame.h"

/* fuzz_protocol_table.h (generated) defines FUZZ_MESSAGES, a list of
 * MSG(name, LENGTH), and per message FUZZ_SIGNALS_<name>, a list of
 * SIG(name, signal, is_float). Expanded twice: functions, then calls. */
#include "fuzz_protocol_table.h"

#define SIG(msg, sig, is_float)                                           \
    {                                                                     \
        const bool in_range = md_can_##msg##_##sig##_is_in_range(s->sig); \
        const double phys = md_can_##msg##_##sig##_decode(s->sig);        \
        FUZZ_CHECK((is_float) || isfinite(phys));                         \
        if (in_range) {                                                   \
            FUZZ_CHECK(isfinite(phys));                                   \
            FUZZ_CHECK(md_can_##msg##_##sig##_is_in_phys_range(phys));    \
        }                                                                 \
    }

#define MSG(msg, length)                                                       \
    static void check_signals_##msg(const struct md_can_##msg##_t *s)          \
    {                                                                          \
        FUZZ_SIGNALS_##msg                                                     \
    }                                                                          \
    static void fuzz_##msg(const uint8_t *bytes, size_t size)                  \
    {                                                                          \
        struct md_can_##msg##_t a, b;                                          \
        memset(&a, 0, sizeof a);                                               \
        memset(&b, 0, sizeof b);                                               \
        const int rc = md_can_##msg##_unpack(&a, bytes, size);                 \
        FUZZ_CHECK((rc == 0) == (size >= (size_t)(length)));                   \
        if (rc != 0) {                                                         \
            return;                                                            \
        }                                                                      \
        uint8_t buf[MD_FRAME_MAX_DATA];                                        \
        FUZZ_CHECK(md_can_##msg##_pack(buf, &a, (size_t)(length)-1u) < 0);     \
        FUZZ_CHECK(md_can_##msg##_pack(buf, &a, sizeof buf) == (int)(length)); \
        FUZZ_CHECK(md_can_##msg##_unpack(&b, buf, (size_t)(length)) == 0);     \
        FUZZ_CHECK(memcmp(&a, &b, sizeof a) == 0);                             \
        check_signals_##msg(&a);                                               \
    }

FUZZ_MESSAGES

#undef MSG
#define MSG(msg, length) fuzz_##msg(copy, size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > MD_FRAME_MAX_DATA + 8u) {
        return 0; /* longer than any frame: nothing new to learn */
    }
    /* An exact-size heap copy, so ASan sees any read beyond `size`. */
    uint8_t *copy = (uint8_t *)malloc(size); /* ASan: malloc(0) is a valid, empty block */
    if (copy == NULL) {
        return 0;
    }
    memcpy(copy, data, size);
    FUZZ_MESSAGES
    free(copy);
    return 0;
}
