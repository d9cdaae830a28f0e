"""The values each attack hyperparameter may take, declared once for every attack.

`avsim attack generate --set NAME=VALUE`, `--steps`, `--views-per-step`, a `--from` record and
`avsim attack sweep --budgets` all pass through `check_hyperparameters` before anything is
rendered: an unknown name, a value of the wrong type (`eps_peak=abc`), NaN, infinity or a value
out of range (`eps_peak=-1`) is one ConfigError line. Each attack's constructor keeps its own
checks too, for the Python API; these are the same limits, stated with units for the user.
"""

from __future__ import annotations

import inspect
from typing import Any

from avsim.errors import ConfigError
from avsim.validation import Range

# Name -> Range, shared by every attack that takes the name. Textures are in [0, 1], so an
# L-infinity budget lies in (0, 1]; weights are >= 0; counts are >= 1.
HYPERPARAMETER_RANGES: dict[str, Range] = {
    "steps": Range(1, 100_000, integer=True),
    "views_per_step": Range(1, 1000, integer=True),
    "lr": Range(0, 1, lo_open=True),
    "eps": Range(0, 1, lo_open=True, note="an L-infinity budget on textures in [0, 1]"),
    "eps_peak": Range(0, 1, lo_open=True, note="an L-infinity budget on textures in [0, 1]"),
    "gamma": Range(0, 10),
    "saliency_views": Range(1, 1000, integer=True),
    "max_area_fraction": Range(0, 1, lo_open=True, note="a share of the sign's face"),
    "n_stickers": Range(1, 64, integer=True),
    "similarity_weight": Range(0, 1000),
    "nps_weight": Range(0, 1000),
    "tv_weight": Range(0, 1000),
    "norm_weight": Range(0, 1000),
    "range_weight": Range(0, 1000),
    "logit_floor": Range(-50, 50),
    "temperature": Range(0, 100, lo_open=True),
    "ssim_floor": Range(0, 1, lo_open=True, hi_open=True),
    "trigger_dist_m": Range(0, 1000, lo_open=True, unit="m"),
    "gate_softness_m": Range(0, 100, lo_open=True, unit="m"),
    "sequences_per_step": Range(1, 1000, integer=True),
    "grad_frames": Range(1, 1000, integer=True),
    "vote_k": Range(1, 100, integer=True),
    "vote_n": Range(1, 100, integer=True),
}


def check_hyperparameter_values(method: str, attack_class: type, hyperparameters: dict[str, Any]) -> None:
    """Each given hyperparameter's type (the constructor's annotation) and declared range.

    Raises a one-line ConfigError naming the attack, the hyperparameter and its range.
    """
    parameters = inspect.signature(attack_class).parameters
    for name, value in hyperparameters.items():
        declared = parameters.get(name)
        if declared is None:
            continue  # an unknown name is the signature check's to refuse
        kind = type(declared.default)
        where = f"attack '{method}' hyperparameter {name}"
        if kind in (int, float):
            spec = HYPERPARAMETER_RANGES.get(name)
            if spec is None:
                raise AssertionError(f"{where} has no declared range in HYPERPARAMETER_RANGES")
            if kind is float and type(value) is int:
                value = float(value)
            if type(value) is not kind:
                raise ConfigError(f"{where} must be {'an integer' if kind is int else 'a number'}, got {value!r}")
            spec.check(value, where)
        elif type(value) is not kind:
            raise ConfigError(f"{where} must be a {kind.__name__}, got {value!r}")
