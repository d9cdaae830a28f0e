"""`avsim realism --set KEY=VALUE`: one config value under every frame of the benchmark.

The benchmark draws its frames from `camera` and `scenario` keys alone (`avsim.realism.frame_set.scene_config`) and
scores them with networks of its own choosing (`--networks`), so a `--set` may give a `camera` or `scenario` key: a
sensor's noise, a field of view, a material, fog. What is refused, in one line before anything renders
(`avsim.realism.set_scope`):
- a key of another section (a policy, a perception, the vehicle): no frame or score would read it;
- a key every scene draw sets itself (town, placement, sign, seed, the sun: `FRAME_SET_KEYS`), which `--towns` and
  `--seed` choose;
- a key one of the `--settings` sets: the --set would quietly undo part of that setting;
- an unknown key or a bad value, checked under every setting.
"""

from __future__ import annotations

from avsim.realism.frame_set import FRAME_SET_KEYS
from avsim.realism.set_scope import SetScope

REALISM_SET = SetScope(reads=("camera.", "scenario."), reads_in_words="camera and scenario keys",
                       own_keys=FRAME_SET_KEYS, command="the realism benchmark", setting_flag="--settings",
                       own_fix="every scene draw sets it (docs/realism.md, the frame set); choose the towns with "
                               "--towns and the draws with --seed")

