"""Markdown and figures for `avsim attack eval`."""

from __future__ import annotations

import json
import math
from pathlib import Path

from avsim.experiments.attacks.drive_by_report import disappearance_section, source_of, transfer_section
from avsim.experiments.attacks.texture_eval import FIXED_DISTANCES_M, TextureReport, display_name
from avsim.realism.settings import SETTINGS, RenderSetting


def _fmt(value: float | None, digits: int = 2) -> str:
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.{digits}f}"


def budget_of(sign: str, texture_dir: Path) -> dict:
    """The generation record (OUT.json beside OUT.png) of a texture name, if there is one."""
    path = Path(sign).with_suffix(".json") if sign.lower().endswith(".png") else texture_dir / f"{sign}.json"
    return json.loads(path.read_text()) if path.is_file() else {}


def plot_drive_by(reports: list[TextureReport], placement: str, out_path: Path) -> Path:
    """Plot each texture's drive-by confidence against distance [m] at `placement`, front and side
    camera side by side, to `out_path` (PNG); returns the path.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), dpi=120, sharey=True)
    for ax, camera in zip(axes, ("front", "side")):
        for report in reports:
            points = report.drive_by[camera].get(placement, [])
            if points:
                dist, conf = zip(*points)
                ax.plot(dist, conf, lw=1.2, label=display_name(report.sign), ls="-" if report.sign == "clean" else "--")
        ax.set_title(f"{camera} camera, {placement} placement")
        ax.set_xlabel("front bumper to stop sign [m]")
        ax.invert_xaxis()
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("stop-sign confidence (MuJoCo render)")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_path)
    plt.close(fig)
    return out_path


def _perception_label(perception: str, weights: str) -> str:
    """Who scored the fixed-distance tables, e.g. "The own detector (models/sign_detector.pt)"."""
    if perception != "detector":
        return f"The `{perception}` network"
    return f"The own detector ({weights or 'the shipped models/sign_detector.pt'})"


def write_attack_report(reports: list[TextureReport], town: str, threshold: float, texture_dir: Path,
                        out_dir: Path, fig3_path: Path, drive_bys: dict | None = None,
                        detectors_figure: Path | None = None, setting: RenderSetting = SETTINGS["baseline"],
                        perception: str = "detector", weights: str = "", set_flags: str = "") -> Path:
    """report.md: the fixed-distance tables of `reports` and, with `drive_bys` ((sign, detector)
    -> `DriveBys`), the per-frame drive-by metrics and the transfer matrix; `setting`: the render
    setting every frame was drawn under; `perception`: the kind the fixed-distance tables were
    measured under; `weights`: the own detector's weights file ("" for the shipped ones); `set_flags`: the --set
    values every frame was drawn with, as flags ("" for none)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    placements = list(reports[0].conf_at_m["front"])
    plots = [plot_drive_by(reports, p, out_dir / f"drive_by_{p}.png") for p in placements]
    lines = [f"# Attacked stop signs in MuJoCo renders ({town})", "",
             f"{_perception_label(perception, weights)} on full 640x480 frames; a detection counts if it overlaps the sign's "
             f"ground-truth box (IoU >= 0.3). Threshold for detection rate and first detection: {threshold}.", "",
             f"Render setting: `{setting.name}` ({setting.describe()}): {setting.why}.", "",
             *([f"Every frame drawn with {set_flags}, beside the setting's own values.", ""] if set_flags else []),
             "| sign | SSIM | L-inf | mean conf front | mean conf side | " + " | ".join(f"first det. front {p} [m]" for p in placements) + " |",
             "|---|---|---|---|---|" + "---|" * len(placements)]
    for r in reports:
        budget = budget_of(r.sign, texture_dir)
        lines.append(f"| {display_name(r.sign)} | {_fmt(budget.get('ssim', 1.0 if r.sign == 'clean' else None))} | "
                     f"{_fmt(budget.get('linf', 0.0 if r.sign == 'clean' else None))} | {_fmt(r.mean_conf('front'))} | "
                     f"{_fmt(r.mean_conf('side'))} | " + " | ".join(_fmt(r.first_detection_m["front"][p], 0) for p in placements) + " |")
    for camera in ("front", "side"):
        lines += ["", f"## {camera} camera: confidence at fixed distances", "",
                  "| sign | placement | " + " | ".join(f"{d:.0f} m" for d in FIXED_DISTANCES_M) + " | detection rate | first detection [m] |",
                  "|---|---|" + "---|" * len(FIXED_DISTANCES_M) + "---|---|"]
        for r in reports:
            for p in placements:
                confs = r.conf_at_m[camera][p]
                lines.append(f"| {display_name(r.sign)} | {p} | " + " | ".join(_fmt(confs[d]) for d in FIXED_DISTANCES_M)
                             + f" | {_fmt(r.detection_rate[camera][p])} | {_fmt(r.first_detection_m[camera][p], 0)} |")
    lines += ["", "'-' at a fixed distance: the sign is out of that camera's view there.", "",
              f"![front camera at 30 m]({fig3_path.name})", ""]
    lines += [f"![drive-by, {p}]({plot.name})" for p, plot in zip(placements, plots)]
    if drive_bys:
        budgets = {display_name(sign): budget_of(sign, texture_dir) for sign, _ in drive_bys}
        named = {(display_name(sign), det): result for (sign, det), result in drive_bys.items()}
        lines += ["", *disappearance_section(named, budgets),
                  *transfer_section(named, {name: source_of(b) for name, b in budgets.items()})]
        if detectors_figure is not None:
            lines += [f"![confidence against distance under each detector]({detectors_figure.name})", ""]
    path = out_dir / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
