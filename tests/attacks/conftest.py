"""Drive-by view banks shared by the attack tests: Town07 standard, one lighting each, rendered once."""

import dataclasses

import pytest

from avsim.attacks.generate import clean_stop_texture, downsample
from avsim.attacks.view_bank import build_view_bank, closed_loop_bank_spec


def town07_drive_by_bank(seed: int):
    spec = dataclasses.replace(closed_loop_bank_spec(seed=seed), towns=("town07",), placements=("standard",),
                               lightings_per_cell=1)
    return build_view_bank(spec, downsample(clean_stop_texture()))


@pytest.fixture(scope="session")
def drive_by_bank():
    """One drive-by (about 35 frames from 50 m to where the sign leaves the front camera)."""
    return town07_drive_by_bank(0)


@pytest.fixture(scope="session")
def held_out_drive_by_bank():
    """Another drive-by: its own lighting, frame phase, lane offsets and pitch (seed 1)."""
    return town07_drive_by_bank(1)
