#include "md_status.h"

const char *md_status_name(md_status_t status)
{
    switch (status) {
    case MD_OK: return "MD_OK";
    case MD_E_ARG: return "MD_E_ARG";
    case MD_E_CAPACITY: return "MD_E_CAPACITY";
    case MD_E_NUMERIC: return "MD_E_NUMERIC";
    case MD_E_DEGENERATE: return "MD_E_DEGENERATE";
    case MD_E_NOCONVERGE: return "MD_E_NOCONVERGE";
    case MD_E_STATE: return "MD_E_STATE";
    case MD_E_FRAME: return "MD_E_FRAME";
    case MD_E_TIMEOUT: return "MD_E_TIMEOUT";
    case MD_E_IO: return "MD_E_IO";
    default: return "MD_E_UNKNOWN";
    }
}
