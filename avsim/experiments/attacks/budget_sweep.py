"""`avsim attack sweep`: attack strength against camouflage as the budget grows.

For each budget the method is optimised afresh (one shared view bank), saved, and
measured in MuJoCo renders: the front camera's mean stop-sign confidence at the fixed
distances and the first-detection distance, in town07 at the standard placement. With
`--closed-loop FILE` each texture (and the clean sign) is also driven past under that
attack-success protocol (`avsim.experiments.attacks.budget_success`), and the sweep reports the closed-loop
success rate with its Wilson 95 % interval, the overrun and the braking delay per budget.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

from avsim.experiments.attacks.budget_success import closed_loop_success
from avsim.experiments.attacks.texture_eval import evaluate_texture
from avsim.attacks.generate import check_hyperparameters, default_bank, generate, prepare
from avsim.experiments.attacks.success import Success
from avsim.config import SimConfig
from avsim.experiments.spec import Experiment
from avsim.metrics import write_text_atomic

# The hyperparameter that is each method's budget.
BUDGET_KEY = {"chen": "eps", "lu_v2": "eps", "lu_v3": "eps", "yang": "eps_peak", "eykholt": "max_area_fraction",
              "driveby": "ssim_floor", "range_inflation": "ssim_floor"}


def budget_sweep(method: str, budgets: list[float], out_dir: Path, steps: int, seed: int = 0,
                 weights_path: str = "", detector: str = "detector", protocol: Experiment | None = None,
                 workers: int = 1, progress: bool = True, rrd: str = "failed", mcap: str = "none") -> tuple[Path, Path]:
    """Write OUT/sweep_METHOD.csv and .png; textures land in OUT/textures/ (each with its record,
    so a closed-loop sweep can drive past them: `experiments/sweeps/speed_sweep.toml`).

    protocol: an attack-success experiment file with a "clean" cell; when given, every texture
    and the clean sign are driven past under it (`workers` runs at once), the runs are written
    to OUT/runs_METHOD.jsonl, and the CSV gains a row for the clean sign and the success columns.
    rrd, mcap: which of those runs are recorded (`avsim.experiments.recordings`), under OUT/rrd/, OUT/mcap/.
    """
    key = BUDGET_KEY[method]
    for budget in budgets:
        check_hyperparameters(method, seed, {key: budget, "steps": steps})
    bank_spec, photometric = default_bank(method, ("front",), 85.0)
    setup = prepare(weights_path, bank_spec, detector, photometric)
    threshold = SimConfig().policy.conf_threshold
    rows = []
    for budget in budgets:
        png = out_dir / "textures" / f"{method}_{key}_{budget:g}.png"
        png.parent.mkdir(parents=True, exist_ok=True)
        _, record = generate(method, png, seed=seed, setup=setup, hyperparameters={key: budget, "steps": steps})
        report = evaluate_texture(str(png), "town07", ("standard",), threshold)
        rows.append({"method": method, key: budget, "ssim": record["ssim"], "linf": record["linf"],
                     "mean_conf_front": round(report.mean_conf("front"), 4),
                     "first_detection_front_m": report.first_detection_m["front"]["standard"]})
        rows[-1]["texture"] = str(png)
        print(rows[-1], flush=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    if protocol is not None:
        rows = _with_success(rows, key, protocol, out_dir / f"runs_{method}.jsonl", workers, progress, (rrd, mcap))
    csv_path = out_dir / f"sweep_{method}.csv"
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(rows[-1]))
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(csv_path, text.getvalue())
    return csv_path, _plot(rows, key, method, out_dir / f"sweep_{method}.png")


def _with_success(rows: list[dict], key: str, protocol: Experiment, runs_jsonl: Path, workers: int,
                  progress: bool, recordings: tuple[str, str]) -> list[dict]:
    """The rows with the clean sign's row first and every row's closed-loop success columns."""
    threshold = SimConfig().policy.conf_threshold
    clean_report = evaluate_texture("clean", "town07", ("standard",), threshold)
    clean = {"method": "clean", key: "", "ssim": 1.0, "linf": 0.0,
             "mean_conf_front": round(clean_report.mean_conf("front"), 4),
             "first_detection_front_m": clean_report.first_detection_m["front"]["standard"], "texture": "clean"}
    labels = {f"{key}={row[key]:g}": row["texture"] for row in rows}
    results = closed_loop_success(protocol, labels, runs_jsonl, workers, progress, rrd=recordings[0], mcap=recordings[1])
    rows = [clean, *rows]
    for row, label in zip(rows, ["clean", *labels]):
        row.update(_success_columns(results[label]))
    return rows


def _success_columns(s: Success) -> dict:
    return {"runs": s.runs, "ran_past": s.past, "success_rate": round(s.rate, 4), "ci95_low": round(s.ci95[0], 4),
            "ci95_high": round(s.ci95[1], 4),
            "overrun_mean_m": None if s.overrun_mean_m is None else round(s.overrun_mean_m, 2),
            "overrun_worst_m": None if s.overrun_worst_m is None else round(s.overrun_worst_m, 2),
            "brake_delay_mean_m": None if s.brake_delay_mean_m is None else round(s.brake_delay_mean_m, 2)}


def _plot(rows: list[dict], key: str, method: str, path: Path) -> Path:
    """Confidence against SSIM; with closed-loop columns, also the success rate (Wilson 95 % bars)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    closed_loop = "success_rate" in rows[-1]
    fig, axes = plt.subplots(1, 2 if closed_loop else 1, figsize=(11 if closed_loop else 5.5, 3.8), dpi=120, squeeze=False)
    ssims = [r["ssim"] for r in rows]
    labels = ["clean" if r["method"] == "clean" else f"{key}={r[key]:g}" for r in rows]
    panels = [("mean_conf_front", "mean stop-sign confidence, front camera")]
    if closed_loop:
        panels.append(("success_rate", f"runs past the sign (of {rows[-1]['runs']}), Wilson 95 %"))
    for ax, (column, ylabel) in zip(axes[0], panels):
        values = [r[column] for r in rows]
        if column == "success_rate":
            errors = [[v - r["ci95_low"] for v, r in zip(values, rows)], [r["ci95_high"] - v for v, r in zip(values, rows)]]
            ax.errorbar(ssims, values, yerr=errors, fmt="o-", capsize=3)
            ax.set_ylim(-0.05, 1.05)
        else:
            ax.plot(ssims, values, "o-")
        for label, x, y in zip(labels, ssims, values):
            ax.annotate(label, (x, y), fontsize=7, xytext=(4, 4), textcoords="offset points")
        ax.axvline(0.7, color="grey", ls=":", lw=0.8, label="camouflage floor (SSIM 0.7)")
        ax.set_xlabel("SSIM to the clean sign (higher: better camouflaged)")
        ax.set_ylabel(ylabel)
        ax.invert_xaxis()
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.suptitle(f"{method}: attack strength against camouflage", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
