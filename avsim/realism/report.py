"""The realism benchmark's report: markdown tables and a recall-against-distance figure.

Rows are those of `avsim.realism.benchmark.run_job` (one per frame and network). Recall cells give
found/signs and the 95 % Wilson interval; "pooled" is 10-40 m, the range the issue's targets name.
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from avsim.perception.ap import average_precision
from avsim.realism.frame_set import BIN_WIDTH_M, DEFAULT_MAX_DIST_M, bin_edges_m
from avsim.realism.scoring import FALSE_ON, FALSE_SIGN_COVER
from avsim.realism.settings import NETWORKS, SETTINGS
from avsim.stats import rate_with_interval, sign_test_p, wilson_interval

POOLED_RANGE_M = (10.0, 40.0)


def _max_dist_m(rows: list[dict]) -> int:
    """The farthest bin's end [m] of the set these rows come from (`--max-dist-m`; at least the default)."""
    farthest = max((r["dist_m"] for r in rows if r["dist_m"] is not None), default=0.0)
    return max(DEFAULT_MAX_DIST_M, BIN_WIDTH_M * math.ceil(farthest / BIN_WIDTH_M))


def distance_bins(rows: list[dict]) -> list[tuple[int, int]]:
    """The 5-m bins (lo, hi) [m] of the set these rows come from."""
    edges = bin_edges_m(_max_dist_m(rows))
    return list(zip(edges[:-1], edges[1:]))


def distance_spans(rows: list[dict]) -> list[tuple[float, float]]:
    """The pooled spans [m] the summary reports: 10-40 (the issue's targets), 40-60, and 60 to the
    farthest bin where the set runs beyond 60 m."""
    spans = [POOLED_RANGE_M, (POOLED_RANGE_M[1], float(DEFAULT_MAX_DIST_M))]
    farthest_m = _max_dist_m(rows)
    if farthest_m > DEFAULT_MAX_DIST_M:
        spans.append((float(DEFAULT_MAX_DIST_M), float(farthest_m)))
    return spans


def _span_name(span: tuple[float, float]) -> str:
    return f"{span[0]:.0f}–{span[1]:.0f} m"


def _in_bin(dist_m: float, lo: float, hi: float) -> bool:
    return lo <= dist_m < hi


def _recall_cell(found: list[bool]) -> str:
    return rate_with_interval(sum(found), len(found))


def sign_rows(rows: list[dict]) -> list[dict]:
    """Rows of frames that look at the stop sign from a bin's distance and see it (the recall population)."""
    return [r for r in rows if r["dist_m"] is not None and r["n_truth"] > 0]


def _ordered(values: set[str], order: list[str]) -> list[str]:
    return [v for v in order if v in values] + sorted(values - set(order))


def recall_table(rows: list[dict], network: str, camera: str, key: str = "found") -> list[str]:
    """Per setting and town (and all towns): found/signs per 5-m bin and pooled 10-40 m."""
    population = [r for r in sign_rows(rows) if r["network"] == network and r["camera"] == camera]
    settings = _ordered({r["setting"] for r in population}, list(SETTINGS))
    towns = sorted({r["town"] for r in population})
    bins = distance_bins(rows)
    lines = ["| setting | town | " + " | ".join(f"{lo}–{hi}" for lo, hi in bins) + " | pooled 10–40 m |",
             "|---|---|" + "---|" * (len(bins) + 1)]
    for setting in settings:
        for town in towns + ["all"]:
            mine = [r for r in population if r["setting"] == setting and town in (r["town"], "all")]
            cells = [_recall_cell([r[key] for r in mine if _in_bin(r["dist_m"], lo, hi)]) for lo, hi in bins]
            pooled = [r[key] for r in mine if _in_bin(r["dist_m"], *POOLED_RANGE_M)]
            lines.append(f"| {setting} | {town} | " + " | ".join(cells) + f" | {_recall_cell(pooled)} |")
    return lines


def false_stop_table(rows: list[dict]) -> list[str]:
    """Per network and setting: false stop signs per frame per town, what they sit on, and how many of
    them cover part of a labelled stop sign (a box displaced from the sign, not one apart from it)."""
    towns = sorted({r["town"] for r in rows})
    lines = ["| network | setting | " + " | ".join(towns) + " | all | sits on | over a sign |",
             "|---|---|" + "---|" * (len(towns) + 3)]
    for network in _ordered({r["network"] for r in rows}, list(NETWORKS)):
        for setting in _ordered({r["setting"] for r in rows}, list(SETTINGS)):
            mine = [r for r in rows if r["network"] == network and r["setting"] == setting]
            cells = []
            for town in towns + ["all"]:
                frames = [r for r in mine if town in (r["town"], "all")]
                count = sum(len(r["false_stop_signs"]) for r in frames)
                cells.append(f"{count / len(frames):.3f} ({count}/{len(frames)})" if frames else "–")
            false = [f for r in mine for f in r["false_stop_signs"]]
            on = Counter(f[FALSE_ON] for f in false)
            over_sign = sum(f[FALSE_SIGN_COVER] > 0 for f in false)
            lines.append(f"| {network} | {setting} | " + " | ".join(cells) + " | "
                         + (", ".join(f"{name} {n}" for name, n in on.most_common(4)) or "–")
                         + (f" | {over_sign} of {len(false)} |" if false else " | – |"))
    return lines


def false_stop_by_distance_table(rows: list[dict]) -> list[str]:
    """Per network and setting: the frames with at least one false stop sign, of the sign views in each
    of `distance_spans` (camera to sign) and of the roadside views, all towns and cameras together."""
    spans = distance_spans(rows)
    lines = ["| network | setting | " + " | ".join(_span_name(span) for span in spans) + " | roadside views |",
             "|---|---|" + "---|" * (len(spans) + 1)]
    for network in _ordered({r["network"] for r in rows}, list(NETWORKS)):
        for setting in _ordered({r["setting"] for r in rows}, list(SETTINGS)):
            mine = [r for r in rows if r["network"] == network and r["setting"] == setting]
            groups = [[r for r in mine if r["dist_m"] is not None and _in_bin(r["dist_m"], *span)] for span in spans]
            groups.append([r for r in mine if r["dist_m"] is None])
            cells = [rate_with_interval(sum(bool(r["false_stop_signs"]) for r in frames), len(frames)) for frames in groups]
            lines.append(f"| {network} | {setting} | " + " | ".join(cells) + " |")
    return lines


def _stop_sign_ap(rows: list[dict]) -> float:
    """AP at IoU 0.5 of the stop-sign detections of these rows against their labelled stop signs."""
    detections = [d for r in rows for d in r["ap_detections"]]
    scores = np.asarray([d[0] for d in detections], float)
    is_tp = np.asarray([d[1] for d in detections], bool)
    return average_precision(scores, is_tp, sum(r["n_truth"] for r in rows))


def ap_table(rows: list[dict]) -> list[str]:
    """Stop-sign AP at IoU 0.5 per network and setting, over every frame of the set."""
    settings = _ordered({r["setting"] for r in rows}, list(SETTINGS))
    lines = ["| network | " + " | ".join(settings) + " |", "|---|" + "---|" * len(settings)]
    for network in _ordered({r["network"] for r in rows}, list(NETWORKS)):
        cells = []
        for setting in settings:
            cells.append(f"{_stop_sign_ap([r for r in rows if r['network'] == network and r['setting'] == setting]):.3f}")
        lines.append(f"| {network} | " + " | ".join(cells) + " |")
    return lines


def summary_table(rows: list[dict]) -> list[str]:
    """One line per network and setting: pooled recall per camera (all towns) over each of
    `distance_spans`, false stop signs per frame, stop-sign AP."""
    population = sign_rows(rows)
    spans = distance_spans(rows)
    lines = ["| network | setting | " + " | ".join(f"{camera} {_span_name(span)}" for camera in ("front", "side") for span in spans)
             + " | false stop signs / frame | AP |", "|---|---|" + "---|" * (2 * len(spans) + 2)]
    settings = _ordered({r["setting"] for r in rows}, list(SETTINGS))
    for network in _ordered({r["network"] for r in rows}, list(NETWORKS)):
        for setting in settings:
            cells = []
            for camera in ("front", "side"):
                for span in spans:
                    cells.append(_recall_cell([r["found"] for r in population if r["network"] == network and r["setting"] == setting
                                               and r["camera"] == camera and _in_bin(r["dist_m"], *span)]))
            frames = [r for r in rows if r["network"] == network and r["setting"] == setting]
            false = sum(len(r["false_stop_signs"]) for r in frames)
            lines.append(f"| {network} | {setting} | " + " | ".join(cells)
                         + f" | {false / len(frames):.3f} ({false}/{len(frames)}) | {_stop_sign_ap(frames):.3f} |")
    return lines


# Braking thresholds above the run's at which the report recounts from the kept scores: the study's 0.5
# is a constant of the study, and a target met at one threshold may not be at another (docs/realism.md).
HIGHER_THRESHOLDS = (0.55, 0.6, 0.7)


def threshold_table(rows: list[dict], threshold: float) -> list[str]:
    """One line per network, setting and town: front-camera recall at 10-40 m and false stop signs per
    frame at the run's `threshold` and at each of HIGHER_THRESHOLDS above it, recounted from the scores the
    rows keep. A sign counts as found at t when the best score of a detection matching it (IoU >= 0.5)
    reaches t, which is the count a run at t gives for a frame with one stop sign, as every frame of the
    set has; a false stop sign counts at t when its own score reaches t."""
    thresholds = [threshold, *(t for t in HIGHER_THRESHOLDS if t > threshold)]
    lines = ["| network | setting | town | " + " | ".join(f"front 10–40 m at {t:g} | false at {t:g}" for t in thresholds) + " |",
             "|---|---|---|" + "---|---|" * len(thresholds)]
    towns = sorted({r["town"] for r in rows})
    for network in _ordered({r["network"] for r in rows}, list(NETWORKS)):
        for setting in _ordered({r["setting"] for r in rows}, list(SETTINGS)):
            for town in towns:
                frames = [r for r in rows if (r["network"], r["setting"], r["town"]) == (network, setting, town)]
                if not frames:
                    continue
                signs = [r for r in sign_rows(frames) if r["camera"] == "front" and _in_bin(r["dist_m"], *POOLED_RANGE_M)]
                cells = []
                for t in thresholds:
                    false = sum(1 for r in frames for box in r["false_stop_signs"] if box[0] >= t)
                    cells += [_recall_cell([r["best_score"] >= t for r in signs]), f"{false / len(frames):.3f} ({false})"]
                lines.append(f"| {network} | {setting} | {town} | " + " | ".join(cells) + " |")
    return lines


def _frame_key(row: dict) -> tuple:
    return row["town"], row["scene"], row["frame"], row["camera"], row["network"]


def paired_table(rows: list[dict]) -> list[str]:
    """Each setting against the first (in SETTINGS' order), on the same sign frames: per network, camera and
    span of `distance_spans`, "gained / lost" (signs found only under the setting / only under the first)
    with the exact two-sided sign test's p over the pairs that changed. Empty with one setting."""
    settings = _ordered({r["setting"] for r in rows}, list(SETTINGS))
    if len(settings) < 2:
        return []
    signs = sign_rows(rows)
    reference = {_frame_key(r): r for r in signs if r["setting"] == settings[0]}
    spans = distance_spans(rows)
    lines = ["| network | setting | " + " | ".join(f"{camera} {_span_name(span)}" for camera in ("front", "side") for span in spans)
             + " |", "|---|---|" + "---|" * (2 * len(spans))]
    for network in _ordered({r["network"] for r in rows}, list(NETWORKS)):
        for setting in settings[1:]:
            cells = []
            for camera in ("front", "side"):
                for span in spans:
                    pairs = [(r["found"], reference[_frame_key(r)]["found"]) for r in signs
                             if r["setting"] == setting and r["network"] == network and r["camera"] == camera
                             and _in_bin(r["dist_m"], *span) and _frame_key(r) in reference]
                    gained = sum(found and not was for found, was in pairs)
                    lost = sum(was and not found for found, was in pairs)
                    cells.append(f"{gained} / {lost} (p {sign_test_p(gained, lost):.2g})" if pairs else "–")
            lines.append(f"| {network} | {setting} | " + " | ".join(cells) + " |")
    return lines


def cost_table(rows: list[dict]) -> list[str]:
    """Per setting: CPU time of a frame's render (median and mean [ms]), each frame counted once."""
    first = min({r["network"] for r in rows}, key=list(NETWORKS).index)
    lines = ["| setting | what it sets | why | frames | render CPU median [ms] | mean [ms] |", "|---|---|---|---|---|---|"]
    for setting in _ordered({r["setting"] for r in rows}, list(SETTINGS)):
        times = np.asarray([r["render_cpu_ms"] for r in rows if r["setting"] == setting and r["network"] == first])
        spec = SETTINGS[setting]
        lines.append(f"| {setting} | {spec.describe()} | {spec.why} | {len(times)} | {np.median(times):.1f} | {times.mean():.1f} |")
    return lines


def report(rows: list[dict], threshold: float, versions: Mapping[str, str] | None = None, set_flags: str = "") -> str:
    """The benchmark's Markdown report of its `rows` (one per frame and network) at detection
    `threshold`: each setting's render cost [ms], recall (Wilson 95% intervals), stop-sign AP at IoU
    0.5 and false stop signs per frame, then recall against distance per network and camera.
    versions: what drew and scored the frames (`avsim.software.software_versions`: the GL among them,
    since a frame's pixels are those of the GL that drew it), said under the title. set_flags: the `--set` values
    every frame was drawn with, as flags ("" for none), said under the title too."""
    n_frames = len({(r["setting"], r["town"], r["scene"], r["frame"]) for r in rows})
    ran_on = ([f"Drawn by {versions['gl']}; " + ", ".join(f"{k} {v}" for k, v in versions.items() if k != "gl") + ".", ""]
              if versions else [])
    given = [f"Every frame drawn with {set_flags}, beside each setting's own values.", ""] if set_flags else []
    lines = [f"# Render realism benchmark ({n_frames} frames)", "", *ran_on, *given,
             f"Threshold {threshold}. Recall cells: signs found / signs in view (95 % Wilson interval); found = a "
             "`stop_sign` detection at or above the threshold overlapping the labelled sign with IoU >= 0.5. "
             "False stop signs: detections at or above the threshold centred on no labelled stop sign, on every frame "
             "(sign views and roadside views); \"over a sign\": those whose box covers part of a labelled stop sign, a box "
             "displaced from the sign onto what stands beside it rather than one apart from every sign. Render CPU time "
             "includes Mesa's GL threads.", "",
             "## Render settings and their cost", "", *cost_table(rows), "",
             "## Summary: recall pooled over towns (IoU >= 0.5), false stop signs, AP", "", *summary_table(rows), "",
             *_paired_section(rows),
             "## Stop-sign AP at IoU 0.5 (every frame)", "", *ap_table(rows), "",
             "## False stop signs per frame", "", *false_stop_table(rows), "",
             "## Frames with a false stop sign, by distance to the sign", "",
             "Frames with at least one false stop sign / frames (Wilson 95 % interval), every town and camera; the "
             "spans are the sign views' distances, camera to sign.", "", *false_stop_by_distance_table(rows), "",
             "## At higher thresholds", "",
             "Front camera, 10–40 m, and false stop signs per frame (boxes), per town, recounted from the kept scores "
             f"at the run's threshold and above it: what a braking threshold above {threshold:g} would trade.", "",
             *threshold_table(rows, threshold), ""]
    for network in _ordered({r["network"] for r in rows}, list(NETWORKS)):
        for camera in ("front", "side"):
            lines += [f"## {NETWORKS[network]} ({network}), {camera} camera: recall, IoU >= 0.5", "",
                      *recall_table(rows, network, camera), ""]
        lines += [f"## {NETWORKS[network]} ({network}), front camera: recall, box centred on the sign", "",
                  *recall_table(rows, network, "front", "found_centred"), ""]
    return "\n".join(lines)


def _paired_section(rows: list[dict]) -> list[str]:
    table = paired_table(rows)
    if not table:
        return []
    first = _ordered({r["setting"] for r in rows}, list(SETTINGS))[0]
    return [f"## Paired against {first}: signs found only under the setting / only under {first}", "",
            "The same sign frames under both, every town; p: the exact two-sided sign test over the frames whose outcome "
            "differs (a small p says the setting moves recall one way).", "", *table, ""]


def write_figure(rows: list[dict], path: Path) -> None:
    """Recall (IoU >= 0.5, all towns) against distance: one panel per network and camera, a line per setting."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    networks = _ordered({r["network"] for r in rows}, list(NETWORKS))
    settings = _ordered({r["setting"] for r in rows}, list(SETTINGS))
    fig, axes = plt.subplots(2, len(networks), figsize=(4.2 * len(networks), 6.4), sharex=True, sharey=True, squeeze=False)
    population = sign_rows(rows)
    bins = distance_bins(rows)
    centres = [(lo + hi) / 2 for lo, hi in bins]
    for col, network in enumerate(networks):
        for row_index, camera in enumerate(("front", "side")):
            ax = axes[row_index][col]
            for k, setting in enumerate(settings):
                found_by_bin = defaultdict(list)
                for r in population:
                    if r["network"] == network and r["camera"] == camera and r["setting"] == setting:
                        for lo, hi in bins:
                            if _in_bin(r["dist_m"], lo, hi):
                                found_by_bin[lo].append(r["found"])
                xs, ys, lows, highs = [], [], [], []
                for (lo, _), x in zip(bins, centres):
                    found = found_by_bin[lo]
                    if found:
                        low, high = wilson_interval(sum(found), len(found))
                        xs.append(x + 0.4 * (k - (len(settings) - 1) / 2))
                        ys.append(sum(found) / len(found))
                        lows.append(ys[-1] - low)
                        highs.append(high - ys[-1])
                ax.errorbar(xs, ys, yerr=[lows, highs], marker="o", ms=3, capsize=2, label=setting)
            ax.set_title(f"{NETWORKS[network]}, {camera}")
            ax.set_ylim(-0.02, 1.02)
            ax.grid(alpha=0.3)
            if row_index == 1:
                ax.set_xlabel("distance to the sign [m]")
            if col == 0:
                ax.set_ylabel("stop-sign recall (IoU ≥ 0.5)")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
