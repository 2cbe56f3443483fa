/// @file md_interval.c
/// One interval of one electrode through the interval chain
/// (pipeline/interval_chain.h): the electrode's FE_INFO and approach guard
/// make the chain's configuration, its tracker takes the step with the
/// electrode's travel since its last tracked interval. See md_interval.h.
#include "md_interval.h"

#include <string.h>

mhtc_tracker_t md_interval_tracker(const md_params_t *p)
{
    /* Baselines of thesis §4.5 behind the MHTC interface: the cycle, SNR and
     * isolation read the same mhtc_result_t whichever tracker runs. */
    switch (md_params_get_u32(p, MD_P_TRACKER)) {
    case 1u: return MHTC_TRACKER_MAP_NN;
    case 2u: return MHTC_TRACKER_ML_NN;
    case 3u: return MHTC_TRACKER_GNN;
    default: return MHTC_TRACKER_MHTC;
    }
}

md_status_t md_interval_begin(md_workspace_t *ws, const md_electrode_t *el, uint32_t num_samples)
{
    if (ws == NULL || el == NULL || !el->fe_info) {
        return MD_E_ARG;
    }
    const ic_config_t cfg = {el->sample_rate_hz, el->gain_uv, num_samples, el->guard.cfg.top_k};
    return ic_begin(ws, &cfg);
}

md_status_t md_interval_push(md_workspace_t *ws, const int16_t *x, size_t n)
{
    return ic_push(ws, x, n);
}

md_status_t md_interval_run(md_workspace_t *ws, md_electrode_t *el, double duration_s, double min_rate_hz,
                            md_interval_out_t *out)
{
    if (ws == NULL || el == NULL || out == NULL || !(duration_s > 0.0)) {
        return MD_E_ARG;
    }
    memset(out, 0, sizeof *out);
    ic_out_t r;
    const md_status_t st = ic_run(ws, &el->mhtc, el->move_um, &r);
    if (st != MD_OK) {
        return st;
    }
    out->n_spikes = r.n_spikes;
    out->spikes_seen = (double)r.n_windows / duration_s >= min_rate_hz && r.n_windows > 0u;
    out->has_dominant = r.has_dominant;
    out->dominant = r.dominant;
    out->dominant_cluster = r.dominant_cluster;
    out->snr = r.snr;
    out->iqm = r.iqm;
    out->amp = r.amp;
    return MD_OK;
}
