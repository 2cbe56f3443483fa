#!/usr/bin/env python3
"""Plots of one microdrive session from its LCM log (docs/telemetry.md).

    .venv/bin/python tools/plots/plot_session.py LOG --out DIR [--types <build>/common/lcm/python]

Writes into DIR (one row of panels per electrode in every figure):
  tracks_pc.png   track means in PC1/PC2 (plane, and each against time), IDs, missed detections as x
  waveforms.png   mean waveform of every track, one curve per cycle (light = early, dark = late)
  status.png      SFSM state, SNR and IQM, depth / target depth / Hall depth / true tip against time
  hypotheses.png  log-probability of every hypothesis rank, and the probability mass per rank
  truth.png       tracks against the simulator's ground truth: SNR, depth, spike matching
Prints the files written. Exit 1 if the log holds no telemetry at all.
"""
import argparse
import os
import sys
import textwrap

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: E402
    import numpy as np  # noqa: E402

    from microdrive.lcmlog import SFSM_STATES, hall_readings, read_log  # noqa: E402
except ImportError as e:
    sys.exit(f"plot_session.py: the Python module {e.name!r} is missing from {sys.executable}; the project venv "
             f"has it: run scripts/setup-venv.sh in the checkout (microdrive-session uses its .venv)")

MATCH_TOL_S = 0.0005  # a detection matches a true spike within 0.5 ms
MAX_LEGEND = 10       # more tracks than this: IDs only at the trajectories' ends, no legend
MAX_NEURONS = 4       # truth panels: the neurons with the highest true SNR at this electrode
MAX_ROWS = 12         # matrix rows / waveform panels: the tracks with the most data, the rest pooled


def minutes(utime):
    return utime / 60e6


def track_color(track_id, ids=None):
    """Colour of a track: distinct among the tracks `ids` of one electrode (tab10, then tab20), so that two
    track IDs never share a colour in one panel (T1 and T11 did with id % 10)."""
    ids = sorted(ids) if ids else [track_id]
    k = ids.index(track_id) if track_id in ids else track_id
    return plt.get_cmap("tab10")(k % 10) if len(ids) <= 10 else plt.get_cmap("tab20")(k % 20)


def caption(fig, text):
    """A caption under the panels saying what the figure shows and how to read it."""
    fig.text(0.01, 0.005, text, ha="left", va="bottom", fontsize=8, wrap=True, color="0.25")


def common_basis(waves):
    """PC1/PC2 of one electrode's track mean waveforms (all tracks, all cycles): a basis shared by the whole
    session, so a track's trajectory is comparable across intervals. The controller's own PCA basis is refit
    every interval (eq. 3.1 on that interval's spikes) and its axes may flip sign from one interval to the
    next, which makes the per-interval means jump. Returns (centre, 2 x n basis) or None."""
    rows = [w for ws in waves.values() for _, w, _ in ws]
    if len(rows) < 2:
        return None
    n = max(len(w) for w in rows)
    x = np.zeros((len(rows), n))
    for i, w in enumerate(rows):
        x[i, :len(w)] = w
    centre = x.mean(axis=0)
    _, _, vt = np.linalg.svd(x - centre, full_matrices=False)
    basis = vt[:2] if vt.shape[0] >= 2 else np.vstack([vt, np.zeros((1, n))])
    for k in range(basis.shape[0]):      # sign convention: the trough (most negative sample) loads positively
        if basis[k, int(np.argmin(centre))] < 0:
            basis[k] = -basis[k]
    return centre, basis


def project(w, cb):
    centre, basis = cb
    x = np.zeros(len(centre))
    x[:min(len(w), len(x))] = w[:len(x)]
    return basis @ (x - centre)


def electrodes_of(s):
    found = set()
    for ch in ("MD_STATUS", "MD_TRACKS", "MD_HYPOTHESES", "MD_TRUTH_STATE"):
        found.update(m.electrode for m in s[ch])
    return sorted(found) or [0]


def interval_starts(s):
    """{(electrode, cycle): start time of the interval (us)} from MD_CYCLE."""
    return {(m.electrode, m.cycle): m.start_time_us for m in s["MD_CYCLE"]}


def track_history(s, e, at_interval_start=False):
    """{track id: list of (t_min, pc1, pc2, missed, snr)} of electrode e, stamped with the message time
    or, at_interval_start, with the start of the interval the tracks describe."""
    starts = interval_starts(s) if at_interval_start else {}
    hist = {}
    for m in s["MD_TRACKS"]:
        if m.electrode != e:
            continue
        t = minutes(starts.get((m.electrode, m.cycle), m.utime))
        for k in range(m.num_tracks):
            hist.setdefault(m.track_id[k], []).append((t, m.mean_pc[k][0], m.mean_pc[k][1], m.missed[k], m.snr[k]))
    return hist


def new_figure(rows, cols, w=5.0, h=3.4):
    fig, ax = plt.subplots(rows, cols, figsize=(w * cols, h * rows), squeeze=False)
    return fig, ax


def has_content(ax):
    """A panel shows something: a line with data, a filled area, bars, an image or a note saying why not."""
    return (any(len(ln.get_xdata()) > 0 for ln in ax.lines) or any(len(c.get_paths()) > 0 for c in ax.collections)
            or bool(ax.patches) or bool(ax.images) or bool(ax.texts))


def check_layout(fig, name):
    """Every title and legend lies inside the figure and no panel is empty; raises otherwise, so a cut-off title
    or a blank panel is an error, not a picture a user has to squint at."""
    for ax in fig.axes:
        if ax.get_visible() and ax.axison and not has_content(ax):  # axis("off"): grid filler, not a panel
            raise RuntimeError(f"{name}: panel {ax.get_title()!r} is empty")
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    box = fig.bbox
    texts = [(fig._suptitle, "figure title")] if fig._suptitle is not None else []
    for ax in fig.axes:
        texts.append((ax.title, f"panel title {ax.get_title()!r}"))
        if ax.get_legend() is not None:
            texts.append((ax.get_legend(), f"legend of {ax.get_title()!r}"))
    for artist, what in texts:
        bb = artist.get_window_extent(r)
        if bb.width > 0 and (bb.x0 < box.x0 - 1 or bb.x1 > box.x1 + 1 or bb.y0 < box.y0 - 1 or bb.y1 > box.y1 + 1):
            raise RuntimeError(f"{name}: {what} does not fit in the figure")


def note_empty_panels(fig):
    """A panel left without data (a session that lost its recordings, a cycle range with no tracks) says so
    on itself rather than failing the whole set of plots."""
    for ax in fig.axes:
        if ax.get_visible() and ax.axison and not has_content(ax):
            ax.text(0.5, 0.5, "no data for this panel in this session", ha="center", va="center",
                    transform=ax.transAxes, fontsize=9, color="0.4")


def save(fig, out, name, title):
    note_empty_panels(fig)
    # wrap the title to the figure's width (12 pt characters are ~6.6 pt wide)
    width_chars = max(24, int(fig.get_figwidth() * 72 / 6.6))
    fig.suptitle(textwrap.fill(title, width_chars))
    fig.tight_layout(rect=(0, 0.06, 1, 1))   # room for the caption
    check_layout(fig, name)
    path = os.path.join(out, name)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def plot_tracks_pc(s, out, els, label=""):
    fig, ax = new_figure(len(els), 4, w=4.6, h=3.4)
    for r, e in enumerate(els):
        waves = track_waves(s, e)
        cb = common_basis(waves)
        hist = track_history(s, e)
        ids = sorted(set(hist) | set(waves))
        labelled = set(sorted(ids, key=lambda t: -len(hist.get(t, [])))[:MAX_ROWS])  # IDs of the longest tracks
        for tid in ids:
            c = track_color(tid, ids)
            if cb is not None and tid in waves:
                a = np.array([(t, *project(w, cb), miss) for t, w, miss in waves[tid]])
                det, miss = a[:, 3] == 0, a[:, 3] > 0
                ax[r, 0].plot(a[:, 1], a[:, 2], "-", color=c, lw=0.8)
                ax[r, 0].plot(a[det, 1], a[det, 2], "o", color=c, ms=3)
                ax[r, 0].plot(a[miss, 1], a[miss, 2], "x", color="k", ms=6, mew=1.5)
                for col, dim in ((1, 1), (2, 2)):
                    ax[r, col].plot(a[:, 0], a[:, dim], "-", color=c, lw=0.8, label=f"T{tid}")
                    ax[r, col].plot(a[det, 0], a[det, dim], "o", color=c, ms=3)
                    ax[r, col].plot(a[miss, 0], a[miss, dim], "x", color="k", ms=6, mew=1.5)
                    if tid in labelled:
                        ax[r, col].annotate(f"T{tid}", (a[0, 0], a[0, dim]), xytext=(-4, 4), ha="right",
                                            textcoords="offset points", color=c, fontsize=8)
                if tid in labelled:
                    ax[r, 0].annotate(f"T{tid}", (a[-1, 1], a[-1, 2]), xytext=(4, 4), textcoords="offset points",
                                      color=c)
            if tid in hist:
                h = np.array(hist[tid])
                det, miss = h[:, 3] == 0, h[:, 3] > 0
                ax[r, 3].plot(h[det, 0], h[det, 1], "o", color=c, ms=3, label=f"T{tid}")
                ax[r, 3].plot(h[miss, 0], h[miss, 1], "x", color="k", ms=6, mew=1.5)
        ax[r, 0].set(xlabel="PC1 (session basis)", ylabel="PC2 (session basis)",
                     title=f"electrode {e}: track means, PC1-PC2")
        ax[r, 1].set(xlabel="time (min)", ylabel="PC1", title=f"electrode {e}: PC1 over time")
        ax[r, 2].set(xlabel="time (min)", ylabel="PC2", title=f"electrode {e}: PC2 over time")
        ax[r, 3].set(xlabel="time (min)", ylabel="PC1 (interval basis)",
                     title=f"electrode {e}: PC1 as the tracker saw it")
        if not ids:
            ax[r, 0].text(0.5, 0.5, "no tracks", ha="center", transform=ax[r, 0].transAxes)
        elif len(ids) <= MAX_LEGEND:
            ax[r, 1].legend(fontsize=7, loc="best")
    caption(fig, "Track means of the leading hypothesis, one colour per track ID; o = detected in that interval, "
                 "x = missed detection (the track lives on its prediction). Columns 1-3: the tracks' mean waveforms "
                 "projected on one PCA basis per electrode fitted to all of them (comparable across intervals). "
                 "Column 4: PC1 of the track mean in each interval's own PCA basis, as the tracker used it (the "
                 "basis is refit every interval and may flip sign).")
    return save(fig, out, "tracks_pc.png", f"{label}Tracks in PC1/PC2 over time, IDs and missed detections")


def sample_rate(s):
    rates = [m.sample_rate_hz for m in s["MD_CYCLE"] if m.sample_rate_hz > 0]
    return float(rates[0]) if rates else 0.0


def track_waves(s, e):
    """{track id: list of (t_min, wave, missed)}, trailing samples that are zero in every cycle of a track
    removed (TLM_WAVE parts are padded to 28 samples)."""
    waves = {}
    for m in s["MD_TRACKS"]:
        if m.electrode != e:
            continue
        for k in range(m.num_tracks):
            if m.wave_samples[k] > 0:
                waves.setdefault(m.track_id[k], []).append(
                    (minutes(m.utime), np.array(m.mean_wave_uv[k][:m.wave_samples[k]]), m.missed[k] > 0))
    for tid, rows in waves.items():
        n = max(len(w) for _, w, _ in rows)
        stack = np.zeros((len(rows), n))
        for i, (_, w, _) in enumerate(rows):
            stack[i, :len(w)] = w
        nz = np.nonzero(np.any(stack != 0, axis=0))[0]
        keep = int(nz[-1]) + 1 if len(nz) else n
        waves[tid] = [(t, w[:keep], miss) for t, w, miss in rows]
    return waves


def plot_waveforms(s, out, els, label=""):
    per_el = {e: track_waves(s, e) for e in els}
    cols = max(1, min(6, max(len(v) for v in per_el.values())))
    fig, ax = new_figure(len(els), cols, w=3.6, h=3.0)
    fs = sample_rate(s)
    cmap = plt.get_cmap("viridis_r")   # yellow = early, purple = late
    for r, e in enumerate(els):
        # the tracks followed for the most cycles, in id order
        items = sorted(sorted(per_el[e].items(), key=lambda kv: -len(kv[1]))[:cols])
        for c in range(cols):
            a = ax[r, c]
            if c >= len(items):
                a.axis("off")
                continue
            tid, rows = items[c]
            for i, (_, w, _) in enumerate(rows):
                x = np.arange(len(w)) * (1e3 / fs if fs > 0 else 1.0)
                a.plot(x, w, color=cmap(i / max(1, len(rows) - 1)), lw=0.8)
            a.plot(x, rows[-1][1], color="k", lw=1.6)
            missed = sum(1 for _, _, miss in rows if miss)
            a.set(title=f"e{e} T{tid}: {len(rows)} cycles ({missed} missed)", xlabel="ms" if fs > 0 else "sample",
                  ylabel="uV")
        if not items:
            ax[r, 0].axis("on")
            ax[r, 0].text(0.5, 0.5, f"electrode {e}: no waveforms", ha="center", transform=ax[r, 0].transAxes)
    caption(fig, "Mean waveform of each track (the tracks followed for the most cycles, at most 6 per electrode), "
                 "one curve per cycle it lived: yellow = early, purple = late, black = its last cycle; the title "
                 "counts the cycles in which the track was missed.")
    return save(fig, out, "waveforms.png", f"{label}Mean waveform per track over the session")


def series(msgs, e, *fields):
    rows = [(minutes(m.utime),) + tuple(getattr(m, f) for f in fields) for m in msgs if m.electrode == e]
    return np.array(rows) if rows else np.zeros((0, 1 + len(fields)))


def plot_status(s, out, els, label=""):
    fig, ax = new_figure(3, len(els), w=5.2, h=3.0)
    for c, e in enumerate(els):
        st = series(s["MD_STATUS"], e, "sfsm_state", "snr", "iqm", "depth_um", "target_depth_um")
        ax[0, c].step(st[:, 0], st[:, 1], where="post", color="C0")
        ax[0, c].set_yticks(range(len(SFSM_STATES)), SFSM_STATES, fontsize=7)
        ax[0, c].set_ylim(-0.5, len(SFSM_STATES) - 0.5)
        ax[0, c].set(title=f"electrode {e}: SFSM state", xlabel="time (min)")
        ax[1, c].plot(st[:, 0], st[:, 2], "o-", ms=3, color="C1", label="SNR")
        ax[1, c].set(title=f"electrode {e}: SNR and IQM (dominant track)", xlabel="time (min)", ylabel="SNR")
        iqm = ax[1, c].twinx()
        iqm.plot(st[:, 0], st[:, 3], "s--", ms=3, color="C2", label="IQM")
        iqm.set_ylabel("IQM", color="C2")
        ax[1, c].legend(loc="upper left", fontsize=7)
        iqm.legend(loc="lower right", fontsize=7)
        hall = series([r for r in hall_readings(s["MD_HALL"]) if r.calibrated], e, "depth_um")
        tip = series(s["MD_TRUTH_STATE"], e, "tip_um")
        ax[2, c].plot(hall[:, 0], hall[:, 1], "-", color="0.7", lw=2.5, label="Hall depth")
        ax[2, c].plot(st[:, 0], st[:, 4], "o-", ms=3, color="C0", label="depth (controller)")
        ax[2, c].plot(st[:, 0], st[:, 5], "v", ms=4, color="C3", label="target depth")
        if len(tip):
            ax[2, c].plot(tip[:, 0], tip[:, 1], ":", color="k", label="true tip")
        ax[2, c].invert_yaxis()
        ax[2, c].set(title=f"electrode {e}: depth", xlabel="time (min)", ylabel="depth (um)")
        ax[2, c].legend(fontsize=7)
    caption(fig, "Per electrode (column), from TLM_STATUS once per cycle: the SFSM state; SNR and IQM (isolation "
                 "quality, ID_g) of the dominant track; the controller's depth and target depth against the "
                 "calibrated Hall depth (grey) and the simulator's true tip (dotted). Depth grows downwards.")
    return save(fig, out, "status.png", f"{label}SFSM state, SNR, IQM and depth against time")


def best_rank_history(msgs):
    """[(t_min, rank)] of the session's final best hypothesis and its ancestors (thesis Fig. 4.13): from rank
    0 of the last cycle back through the parents. HypId = (tracker interval << 8) | (parent index << 4) | rank
    (firmware/app/md_telemetry.c), the parent index being its rank in the previous generation. The chain
    stops where the tracker's interval count does not step by one (a skipped cycle, a tracker restart)."""
    hist, rank = [], 0
    last = max((i for i, m in enumerate(msgs) if m.num_hypotheses > 0), default=-1)  # a skipped last cycle
    for i in range(last, -1, -1):
        m = msgs[i]
        ks = [k for k in range(m.num_hypotheses) if m.rank[k] == rank]
        if not ks:
            break
        hid = m.hyp_id[ks[0]]
        hist.append((minutes(m.utime), rank))
        if i == 0 or msgs[i - 1].num_hypotheses == 0 or (msgs[i - 1].hyp_id[0] >> 8) != (hid >> 8) - 1:
            break
        rank = (hid >> 4) & 0x0F
    return hist[::-1]


def plot_hypotheses(s, out, els, label=""):
    fig, ax = new_figure(len(els), 3, w=4.6)
    for r, e in enumerate(els):
        msgs = [m for m in s["MD_HYPOTHESES"] if m.electrode == e]
        n_rank = max([m.num_hypotheses for m in msgs] + [1])
        t = np.array([minutes(m.utime) for m in msgs])
        lp = np.full((len(msgs), n_rank), np.nan)
        for i, m in enumerate(msgs):
            for k in range(m.num_hypotheses):
                lp[i, m.rank[k]] = m.log_prob[k]
        cmap = plt.get_cmap("plasma")
        for k in range(n_rank):
            ax[r, 0].plot(t, lp[:, k], "o-", ms=2, lw=2.2 if k == 0 else 0.8, color=cmap(k / max(1, n_rank)),
                          label=f"rank {k + 1}")
        ax[r, 0].set(title=f"electrode {e}: log-probability per rank", xlabel="time (min)", ylabel="log P")
        ax[r, 0].legend(fontsize=6, ncol=2)
        p = np.nan_to_num(np.exp(lp))
        if len(t):
            ax[r, 1].stackplot(t, p.T, colors=[cmap(k / max(1, n_rank)) for k in range(n_rank)],
                               labels=[f"rank {k + 1}" for k in range(n_rank)])
        ax[r, 1].set(title=f"electrode {e}: probability mass by rank", xlabel="time (min)", ylabel="P")
        ax[r, 1].set_ylim(bottom=0.0)  # the controller's P need not sum to 1 over ranks (eq. 4.30, Remark 4.3)
        msgs.sort(key=lambda m: m.cycle)
        bh = np.array(best_rank_history(msgs)).reshape(-1, 2)
        ax[r, 2].plot(bh[:, 0], bh[:, 1] + 1, "o-", ms=3, color="k", drawstyle="steps-mid")
        if len(bh) == 0:
            ax[r, 2].text(0.5, 0.5, "no hypothesis telemetry (TLM_HYP)\nfor this electrode", ha="center",
                          va="center", transform=ax[r, 2].transAxes, color="0.3")
        ax[r, 2].set_ylim(max(n_rank, 2) + 0.5, 0.5)
        ax[r, 2].set_yticks(range(1, max(n_rank, 2) + 1))
        ax[r, 2].set(title=f"electrode {e}: rank of the final best hypothesis", xlabel="time (min)",
                     ylabel="rank (1 = leading)")
    caption(fig, "MHTC's global hypotheses after every cycle (TLM_HYP): log-probability of each rank (rank 1 = the "
                 "leading hypothesis, bold), the probability mass held by each rank (mass spread over many ranks = "
                 "an ambiguous interval that delayed decision making keeps open), and, as in thesis Fig. 4.13, the "
                 "rank the final best hypothesis's ancestors held at each interval (rank > 1 = the delayed decision "
                 "paid off). Baseline trackers keep one hypothesis.")
    return save(fig, out, "hypotheses.png", f"{label}Hypothesis rank history")


def match_spikes(s, e):
    """Counts of (track label, true neuron) over matched detections; unmatched under neuron None."""
    truth = [(m.sample, m.neuron, m.sample_rate_hz) for m in s["MD_TRUTH_SPIKES"] if m.electrode == e]
    if not truth:
        return {}
    fs = truth[0][2]
    t_true = np.concatenate([np.asarray(t, dtype=float) / fs for t, _, _ in truth])
    n_true = np.concatenate([np.asarray(n) for _, n, _ in truth])
    order = np.argsort(t_true)
    t_true, n_true = t_true[order], n_true[order]
    counts = {}
    for m in s["MD_SPIKES"]:
        if m.electrode != e or m.sample_rate_hz <= 0 or m.interval_start_us < 0:
            continue
        t_det = m.interval_start_us / 1e6 + np.asarray(m.sample, dtype=float) / m.sample_rate_hz
        idx = np.clip(np.searchsorted(t_true, t_det), 1, max(1, len(t_true) - 1))
        for j, td in enumerate(t_det):
            cand = [i for i in (idx[j] - 1, idx[j]) if 0 <= i < len(t_true)]
            best = min(cand, key=lambda i: abs(t_true[i] - td))
            neuron = int(n_true[best]) if abs(t_true[best] - td) <= MATCH_TOL_S else None
            key = (int(m.track_id[j]), neuron)
            counts[key] = counts.get(key, 0) + 1
    return counts


def plot_matrix(a, counts, e):
    totals = {}
    for (t, _), n in counts.items():
        totals[t] = totals.get(t, 0) + n
    if len(totals) > MAX_ROWS:  # pool the tracks with the fewest detections under "other" (-3)
        keep = set(sorted(totals, key=lambda t: -totals[t])[:MAX_ROWS - 1])
        pooled = {}
        for (t, n_id), n in counts.items():
            key = (t if t in keep else -3, n_id)
            pooled[key] = pooled.get(key, 0) + n
        counts = pooled
    tracks = sorted({k[0] for k in counts})
    neurons = sorted({k[1] for k in counts if k[1] is not None}) + [None]
    mat = np.array([[counts.get((t, n), 0) for n in neurons] for t in tracks])
    a.imshow(mat, cmap="Blues", aspect="auto")
    for i in range(len(tracks)):
        for j in range(len(neurons)):
            a.text(j, i, str(mat[i, j]), ha="center", va="center", fontsize=7,
                   color="w" if mat[i, j] > mat.max() / 2 else "k")
    a.set_xticks(range(len(neurons)), [("artifact" if n == -1 else f"N{n}") if n is not None else "none"
                                       for n in neurons], fontsize=7)
    a.set_yticks(range(len(tracks)), [{-1: "outlier", -2: "unlabelled", -3: "other"}.get(t, f"T{t}") for t in tracks],
                 fontsize=7)
    a.set(title=f"electrode {e}: detections by track vs true neuron", xlabel="true neuron (0.5 ms)",
          ylabel="track label")


def plot_truth(s, out, els, label=""):
    fig, ax = new_figure(len(els), 3)
    have_truth = bool(s["MD_TRUTH_STATE"])
    deaths = s["MD_TRUTH_DEATH"]
    for r, e in enumerate(els):
        states = [m for m in s["MD_TRUTH_STATE"] if m.electrode == e]
        true_snr, peak_depth = {}, {}
        for m in states:
            for k in range(m.num_neurons):
                true_snr.setdefault(m.neuron[k], []).append((minutes(m.utime), m.snr[k]))
                peak_depth.setdefault(m.neuron[k], []).append((minutes(m.utime), m.snr_peak_depth_um[k]))
        # the neurons that matter here: the MAX_NEURONS with the highest true SNR (the rest stay near 0
        # and only bury the labels)
        top = set(sorted(true_snr, key=lambda n: -max(v for _, v in true_snr[n]))[:MAX_NEURONS])
        true_snr = {n: v for n, v in true_snr.items() if n in top}
        peak_depth = {n: v for n, v in peak_depth.items() if n in top}
        for nid, rows in sorted(true_snr.items()):
            a = np.array(rows)
            ax[r, 0].plot(a[:, 0], a[:, 1], "--", color="0.4", lw=1)
            ax[r, 0].annotate(f"N{nid} true", (a[-1, 0], a[-1, 1]), fontsize=7, color="0.3")
        th = track_history(s, e, at_interval_start=True)
        for tid, rows in sorted(th.items()):
            a = np.array(rows)
            snr = np.where(a[:, 3] > 0, np.nan, a[:, 4])   # a missed cycle has no SNR: a gap, not a 0
            ax[r, 0].plot(a[:, 0], snr, "o-", ms=3, color=track_color(tid, th), label=f"T{tid}")
        for d in deaths:
            if d.electrode == e:
                ax[r, 0].axvline(minutes(d.utime), color="r", lw=1)
                ax[r, 0].annotate(f"N{d.neuron} dies", (minutes(d.utime), 0), color="r", fontsize=7)
        ax[r, 0].set(title=f"electrode {e}: track SNR vs true neuron SNR", xlabel="interval start (min)",
                     ylabel="SNR")
        if len(ax[r, 0].get_legend_handles_labels()[0]) <= MAX_LEGEND:
            ax[r, 0].legend(fontsize=7)
        starts = interval_starts(s)
        st = np.array([(minutes(starts.get((m.electrode, m.cycle), m.utime)), m.depth_um)
                       for m in s["MD_STATUS"] if m.electrode == e]).reshape(-1, 2)
        tip = series(states, e, "tip_um")
        ax[r, 1].plot(st[:, 0], st[:, 1], "o-", ms=3, color="C0", label="controller depth")
        ax[r, 1].plot(tip[:, 0], tip[:, 1], ":", color="k", lw=2, label="true tip")
        for nid, rows in sorted(peak_depth.items()):
            a = np.array(rows)
            ax[r, 1].plot(a[:, 0], a[:, 1], "--", color="0.5", lw=1)
            ax[r, 1].annotate(f"N{nid} SNR peak", (a[-1, 0], a[-1, 1]), fontsize=7, color="0.3")
        ax[r, 1].invert_yaxis()
        ax[r, 1].set(title=f"electrode {e}: depth vs true SNR peaks", xlabel="interval start (min)",
                     ylabel="depth (um)")
        ax[r, 1].legend(fontsize=7)
        counts = match_spikes(s, e)
        if counts:
            plot_matrix(ax[r, 2], counts, e)
        else:
            ax[r, 2].axis("off")
            ax[r, 2].text(0.5, 0.5, "no detected or true spikes", ha="center", transform=ax[r, 2].transAxes)
        if not have_truth:
            ax[r, 0].text(0.5, 0.5, "no ground truth in this log", ha="center", transform=ax[r, 0].transAxes)
    caption(fig, "Against the simulator's ground truth. Left: each track's SNR (gaps = missed) and every neuron's "
                 "true SNR at the tip (dashed; the 4 strongest neurons), neuron deaths in red. Middle: controller depth, true tip and each "
                 "neuron's SNR-peak depth. Right: detections counted by track label and the true neuron whose spike "
                 "lies within 0.5 ms ('none' = no true spike: noise; 'artifact' = the simulator's artifacts).")
    return save(fig, out, "truth.png", f"{label}Tracks against the simulator's ground truth")


def main():
    ap = argparse.ArgumentParser(description="Plots of a microdrive session from its LCM log")
    ap.add_argument("log")
    ap.add_argument("--out", required=True, help="directory for the PNG files (the session folder)")
    ap.add_argument("--types", help="lcm-gen -p output dir (<build>/common/lcm/python); default: $MD_LCM_TYPES, "
                    "else the package mdlcm on the import path, else generated with lcm-gen")
    ap.add_argument("--quiet", action="store_true", help="do not print the files written")
    ap.add_argument("--label", default="", help="session name for the titles (e.g. 'single_neuron seed 1')")
    a = ap.parse_args()
    s = read_log(a.log, a.types)
    if not any(s[ch] for ch in ("MD_STATUS", "MD_TRACKS", "MD_HALL", "MD_ACTUATOR", "MD_TRUTH_STATE")):
        print(f"plot_session: {a.log} holds no microdrive telemetry", file=sys.stderr)
        return 1
    os.makedirs(a.out, exist_ok=True)
    els = electrodes_of(s)
    for f in (plot_tracks_pc, plot_waveforms, plot_status, plot_hypotheses, plot_truth):
        path = f(s, a.out, els, f"{a.label}: " if a.label else "")
        if not a.quiet:
            print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
