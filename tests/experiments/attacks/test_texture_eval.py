"""`avsim attack eval`'s measurement in MuJoCo renders (not the EOT proxy)."""

import pytest

from avsim.experiments.attacks.texture_eval import evaluate_texture

# The study's five textures, shipped in textures/.
SHIPPED_ATTACKS = ["chen", "eykholt", "lu_v2", "lu_v3", "yang"]


@pytest.mark.slow
def test_every_shipped_attack_lowers_the_mean_confidence_in_mujoco_renders():
    clean = evaluate_texture("clean", "town07", ("standard",), threshold=0.5)
    for method in SHIPPED_ATTACKS:
        attacked = evaluate_texture(method, "town07", ("standard",), threshold=0.5)
        assert attacked.mean_conf("front") < clean.mean_conf("front"), method
