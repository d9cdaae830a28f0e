"""`avsim attack sweep`: attack strength against camouflage as the budget grows.

For each budget the method is optimised afresh (one shared view bank), saved, and
measured in MuJoCo renders: the front camera's mean stop-sign confidence at the fixed
distances and the first-detection distance, in town07 at the standard placement.
"""

from __future__ import annotations

import csv
from pathlib import Path

from avsim.attacks.evaluate import evaluate_texture
from avsim.attacks.generate import check_hyperparameters, default_bank, generate, prepare
from avsim.config import SimConfig

# The hyperparameter that is each method's budget.
BUDGET_KEY = {"chen": "eps", "lu_v2": "eps", "lu_v3": "eps", "yang": "eps_peak", "eykholt": "max_area_fraction",
              "driveby": "ssim_floor", "range_inflation": "ssim_floor"}


def budget_sweep(method: str, budgets: list[float], out_dir: Path, steps: int, seed: int = 0,
                 weights_path: str = "", detector: str = "detector") -> tuple[Path, Path]:
    """Write OUT/sweep_METHOD.csv and .png; textures land in OUT/textures/ (each with its record,
    so a closed-loop sweep can drive past them: `experiments/sweeps/speed_sweep.toml`)."""
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
        print(rows[-1], flush=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / f"sweep_{method}.csv"
    with csv_path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return csv_path, _plot(rows, key, method, out_dir / f"sweep_{method}.png")


def _plot(rows: list[dict], key: str, method: str, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.8), dpi=120)
    ax.plot([r["ssim"] for r in rows], [r["mean_conf_front"] for r in rows], "o-")
    for r in rows:
        ax.annotate(f"{key}={r[key]:g}", (r["ssim"], r["mean_conf_front"]), fontsize=7, xytext=(4, 4), textcoords="offset points")
    ax.axvline(0.7, color="grey", ls=":", lw=0.8, label="camouflage floor (SSIM 0.7)")
    ax.set_xlabel("SSIM to the clean sign (higher: better camouflaged)")
    ax.set_ylabel("mean stop-sign confidence, front camera")
    ax.set_title(f"{method}: attack strength against camouflage")
    ax.invert_xaxis()
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
