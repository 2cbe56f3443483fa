/// @file md_no_heap.h
/// Forced into every firmware translation unit (-include): the heap functions
/// become compile errors. The linked binaries are checked again with nm
/// (scripts/check-no-heap.sh), which also catches heap use pulled in by a
/// library function.
#ifndef MD_NO_HEAP_H
#define MD_NO_HEAP_H
#include <stdlib.h> /* declare first, so the poison below only hits our own code */
#pragma GCC poison malloc calloc realloc free aligned_alloc
#endif
