"""One-off probe: is it the buildings behind Town10's stop sign that keep the COCO CenterNet's recall under
issue 28's target in the realism benchmark? The closed-loop counterfactual (town10_backdrop.py) had 3 clean
runs; this one renders the benchmark's own fixed frame set for Town10 (the same scene draws, poses, light and
sensor noise as `avsim realism --towns town10`) under three backdrops:

- `brick`: as the town is (the default renders; its rows are `avsim realism`'s, bit for bit);
- `concrete`: every brick facade given the concrete facade's material (a grey wall, the same windows);
- `plain`: every facade one flat colour, the mean of its checker's wall and window colours (the same
  buildings, without the pattern that reads as windows);
- `none`: no facade at all (every geom with a facade material left out of the scene), so that the sign
  stands against the sky, as in Town07.

These are counterfactuals about the scene, not realism settings: the towns keep their buildings. Each
backdrop's frames go through the networks and the scoring of `avsim realism`, and the report is its report,
with each backdrop in the place of a render setting (`backdrop_brick`, ...), paired tables included.

    MUJOCO_GL=egl nice -n 5 python experiments/probes/town10_backdrop_benchmark.py 18 results/town10_backdrop brick,none
    MUJOCO_GL=egl nice -n 5 python experiments/probes/town10_backdrop_benchmark.py 18 results/town10_backdrop concrete

Each call renders its backdrops in one process and writes `rows_BACKDROP.jsonl`; the report (`report.md`)
is written afresh over every backdrop's rows in the folder, so two calls can share the machine's two cores.

Measured here: docs/realism_closed_loop.md, "Measured: Town10's facades in the benchmark".
"""

import json
import sys
from pathlib import Path
from types import MappingProxyType

from avsim.realism import frame_set
from avsim.realism import report as report_module
from avsim.realism.benchmark import BenchmarkPlan, run_benchmark
from avsim.realism.settings import RenderSetting
from avsim.world.props import FACADE_COLOURS, FACADES

BACKDROPS = ("brick", "concrete", "plain", "none")
NETWORKS = ("coco", "nanodet")
THRESHOLD = 0.5

_compose_scene = frame_set.compose_scene
SETTINGS = {b: RenderSetting(f"backdrop_{b}", {}, f"Town10's facades: {b}") for b in BACKDROPS}
# The report names, orders and pairs settings by the registry: the backdrops go first, brick (as built) leading.
report_module.SETTINGS = MappingProxyType({**{s.name: s for s in SETTINGS.values()}, **report_module.SETTINGS})


def _with_backdrop(backdrop: str):
    """compose_scene, then the facades changed in the uncompiled spec as `backdrop` says."""
    def compose(config, *args, **kwargs):
        spec, info = _compose_scene(config, *args, **kwargs)
        if backdrop == "plain":
            for name, (wall, window) in FACADE_COLOURS.items():
                spec.add_material(name=f"{name}_plain", rgba=[*((a + b) / 2 for a, b in zip(wall, window)), 1.0])
        for geom in spec.geoms:
            if geom.material not in FACADES:
                continue
            if backdrop == "concrete" and geom.material == "facade_brick":
                geom.material = "facade_concrete"
            elif backdrop == "plain":
                geom.material = f"{geom.material}_plain"
            elif backdrop == "none":
                geom.material = ""
                geom.rgba = [*geom.rgba[:3], 0.0]  # a geom of alpha 0 is left out of the scene
        return spec, info
    return compose


def main(draws_per_town: int, out_dir: Path, backdrops: list[str]) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    for backdrop in backdrops:
        frame_set.compose_scene = _with_backdrop(backdrop)  # one process (workers=1): the patch holds in it
        plan = BenchmarkPlan((SETTINGS[backdrop],), ("town10",), draws_per_town, NETWORKS, THRESHOLD)
        rows = run_benchmark(plan, workers=1)
        with open(out_dir / f"rows_{backdrop}.jsonl", "w") as out:
            out.writelines(json.dumps(row) + "\n" for row in rows)
    frame_set.compose_scene = _compose_scene
    rows = [json.loads(line) for b in BACKDROPS if (out_dir / f"rows_{b}.jsonl").exists()
            for line in open(out_dir / f"rows_{b}.jsonl")]
    (out_dir / "report.md").write_text(report_module.report(rows, THRESHOLD))
    print(f"wrote {out_dir / 'report.md'} over {len({r['setting'] for r in rows})} backdrops")


if __name__ == "__main__":
    chosen = sys.argv[3].split(",") if len(sys.argv) > 3 else list(BACKDROPS)
    if set(chosen) - set(BACKDROPS):
        sys.exit(f"error: unknown backdrop {sorted(set(chosen) - set(BACKDROPS))[0]!r}; choose from {', '.join(BACKDROPS)}")
    main(int(sys.argv[1]), Path(sys.argv[2]), chosen)
