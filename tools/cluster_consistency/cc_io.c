/// @file cc_io.c
/// Ground truth of a simulator export for the clustering-consistency experiment.
#include "cc_io.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static md_status_t truth_push(cc_truth_t *t, size_t *cap, uint64_t s, int32_t id)
{
    if (t->n == *cap) {
        const size_t nc = (*cap == 0u) ? 4096u : 2u * *cap;
        uint64_t *ns = realloc(t->sample, nc * sizeof *ns);
        if (ns == NULL) {
            return MD_E_CAPACITY;
        }
        t->sample = ns;
        int32_t *nn = realloc(t->neuron, nc * sizeof *nn);
        if (nn == NULL) {
            return MD_E_CAPACITY;
        }
        t->neuron = nn;
        *cap = nc;
    }
    t->sample[t->n] = s;
    t->neuron[t->n] = id;
    t->n++;
    if (id > t->max_neuron) {
        t->max_neuron = id;
    }
    return MD_OK;
}

md_status_t cc_read_truth(const char *dir, uint32_t ch, cc_truth_t *truth)
{
    memset(truth, 0, sizeof *truth);
    truth->max_neuron = -1;
    char path[4096];
    (void)snprintf(path, sizeof path, "%s/ground_truth.csv", dir);
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return MD_OK;
    }
    char line[256];
    size_t cap = 0u;
    md_status_t st = MD_OK;
    uint64_t last = 0u;
    while ((st == MD_OK) && (fgets(line, (int)sizeof line, f) != NULL)) {
        unsigned long long s = 0u;
        unsigned c = 0u;
        int id = 0;
        if (sscanf(line, "%llu,%u,%d", &s, &c, &id) != 3) {
            continue; /* header */
        }
        if ((c != ch) || (id < 0)) {
            continue;
        }
        if ((uint64_t)s < last) {
            st = MD_E_FRAME; /* the exporter writes ascending samples */
            break;
        }
        last = (uint64_t)s;
        st = truth_push(truth, &cap, (uint64_t)s, (int32_t)id);
    }
    (void)fclose(f);
    return st;
}

void cc_truth_free(cc_truth_t *truth)
{
    free(truth->sample);
    free(truth->neuron);
    memset(truth, 0, sizeof *truth);
    truth->max_neuron = -1;
}

size_t cc_truth_lower_bound(const cc_truth_t *truth, uint64_t s)
{
    size_t lo = 0u;
    size_t hi = truth->n;
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2u;
        if (truth->sample[mid] < s) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}
