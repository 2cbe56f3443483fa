/// @file fuzz_bus_text.c
/// Fuzz target 3b: the cansend/candump text codec (common/bus/md_bus_text.h).
/// Control bit 0 of the first byte chooses the direction:
///  - parse: the rest of the input is the text (NUL-terminated, exact-size
///    heap copy so ASan sees any over-read). A refusal is -EINVAL with a
///    reason; an accepted text is a valid frame, and format → parse gives the
///    same frame back;
///  - format: the rest is a raw md_frame_t (any id, flags, len). An invalid
///    frame is refused; a valid one formats to exactly the returned length,
///    refuses a buffer one byte short without writing past it, and parses
///    back to itself.
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_input.h"
#include "md_bus_text.h"

/* BRS only means something on an FD frame: md_frame_valid accepts it on a
 * classic frame, but the text syntax has no place for it (docs/fuzzing.md). */
static uint8_t meaningful_flags(const md_frame_t *f)
{
    const bool fd = (f->flags & MD_FRAME_FLAG_FD) != 0u;
    return (uint8_t)(fd ? f->flags : (f->flags & (uint8_t)~MD_FRAME_FLAG_BRS));
}

static bool same_frame(const md_frame_t *a, const md_frame_t *b)
{
    return a->id == b->id && a->len == b->len && meaningful_flags(a) == meaningful_flags(b) &&
           memcmp(a->data, b->data, a->len <= MD_FRAME_MAX_DATA ? a->len : MD_FRAME_MAX_DATA) == 0;
}

/* Formats a valid frame, checks the exact-size and one-short cases, and parses it back. */
static void format_and_reparse(const md_frame_t *f)
{
    char text[MD_BUS_TEXT_MAX];
    const int n = md_bus_text_format(f, text, sizeof text);
    FUZZ_CHECK(n > 0 && (size_t)n < sizeof text && strlen(text) == (size_t)n);
    char *exact = (char *)malloc((size_t)n + 1u);
    FUZZ_CHECK(exact != NULL);
    FUZZ_CHECK(md_bus_text_format(f, exact, (size_t)n) == -ENOSPC);
    FUZZ_CHECK(md_bus_text_format(f, exact, (size_t)n + 1u) == n);
    FUZZ_CHECK(strcmp(exact, text) == 0);
    free(exact);
    md_frame_t back;
    const char *why = NULL;
    FUZZ_CHECK(md_bus_text_parse(text, &back, &why) == 0);
    FUZZ_CHECK(same_frame(f, &back));
}

static void fuzz_parse(const uint8_t *data, size_t size)
{
    char *text = (char *)malloc(size + 1u);
    if (text == NULL) {
        return;
    }
    memcpy(text, data, size);
    text[size] = '\0';
    md_frame_t f;
    const char *why = NULL;
    const int rc = md_bus_text_parse(text, &f, &why);
    if (rc == 0) {
        FUZZ_CHECK(md_frame_valid(&f));
        format_and_reparse(&f);
    } else {
        FUZZ_CHECK(rc == -EINVAL && why != NULL && why[0] != '\0');
    }
    free(text);
}

static void fuzz_format(const uint8_t *data, size_t size)
{
    fz_t in;
    fz_init(&in, data, size);
    md_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = fz_u32(&in);
    f.len = fz_u8(&in);
    f.flags = fz_u8(&in);
    fz_bytes(&in, f.data, MD_FRAME_MAX_DATA);
    char text[MD_BUS_TEXT_MAX];
    if (!md_frame_valid(&f)) {
        FUZZ_CHECK(md_bus_text_format(&f, text, sizeof text) == -EINVAL);
        return;
    }
    /* The text carries no bytes beyond len; the parser zero-fills them. */
    memset(&f.data[f.len], 0, MD_FRAME_MAX_DATA - f.len);
    format_and_reparse(&f);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1u || size > 4096u) {
        return 0;
    }
    if ((data[0] & 1u) == 0u) {
        fuzz_parse(data + 1, size - 1u);
    } else {
        fuzz_format(data + 1, size - 1u);
    }
    return 0;
}
