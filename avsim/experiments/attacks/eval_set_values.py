"""`avsim attack eval --set KEY=VALUE`: one config value under every frame the evaluation renders and scores.

The evaluation reads the camera, the scenario's world (materials, fog, a sign's size), the perception's settings
(noise aside) and two policy values: the threshold its detection rates count at and the braking gate its drive-bys
are gated by. It sets some keys itself, so a `--set` of one of these is refused (`avsim.realism.set_scope`):
- the town, placements and signs, chosen by `--town`, `--placements`, `--drive-placement` and `--signs`;
- the perception kind, by `--detectors`, and its weights, by `--weights`;
- every score down to 0.05 (`min_confidence`), so that the curves show a disappearing sign's fall;
- each drive-by's seed, daylight, sensor noise and thread count, drawn as the closed-loop experiment files draw
  them (`avsim.experiments.attacks.disappearance`): a `--set` of one would reach the fixed-distance tables and
  not the drive-bys.
"""

from __future__ import annotations

from avsim.attacks.view_bank import CLOSED_LOOP_LIGHTING
from avsim.realism.set_scope import SetScope

ATTACK_EVAL_SET = SetScope(
    reads=("camera.", "scenario.", "perception.", "policy.conf_threshold", "policy.trigger_dist_m"),
    reads_in_words="camera, scenario and perception keys, policy.conf_threshold and policy.trigger_dist_m",
    own_keys=("scenario.town", "scenario.placement", "scenario.sign", "scenario.seed",
              *(f"scenario.{key}" for key in CLOSED_LOOP_LIGHTING),
              "perception.kind", "perception.weights_path", "perception.min_confidence", "perception.sensor_noise_std",
              "perception.threads"),
    own_fix="choose the town, placements, signs, networks and weights with --town, --placements, --drive-placement, "
            "--signs, --detectors and --weights; each drive-by draws its seed, daylight and sensor noise as the "
            "closed-loop experiment files do",
    command="attack eval")
