"""Many cars in one process (`avsim.lockstep`): a run's result does not depend on its batch."""

import dataclasses

import pytest

from avsim.experiments.batch import run_batch
from avsim.experiments.plan import group_size, lockstep_groups
from avsim.lockstep import run_lockstep
from avsim.perception.cpu_bf16 import auto_arithmetic
from avsim.runner import run_config
from helpers import SHORT_RUN, make_config, short_run_spec

# Short runs that see the sign and brake within their 3 s: a batch's cars step through the
# network call, the policy, the brakes and the physics together.
SHORT = {**SHORT_RUN, "speed_kmh": 60.0, "start_speed_kmh": 60.0}


def _mixed_cells(perception: dict) -> list:
    """Eight cells: both cameras, every town, an attack texture, sensor noise, and an oracle car."""
    cells = [
        ({"town": "town07"}, "baseline", {}),
        ({"town": "town10", "seed": 3}, "side_camera", {"sensor_noise_std": 3.0}),
        ({"town": "town03", "placement": "far", "sign": "yang"}, "adjusted", {"sensor_noise_std": 2.0}),
        ({"town": "town07", "seed": 2, "sign": "driveby_detector"}, "baseline", {}),
        ({"town": "town10", "placement": "near"}, "combined", {}),
        ({"town": "town03", "seed": 5}, "study_stack", {}),
        ({"town": "town07", "seed": 1}, "side_camera", {"sensor_noise_std": 1.0}),
    ]
    configs = [make_config(scenario={**SHORT, **scenario}, policy={"name": policy}, loop={"max_time_s": 3.0},
                           perception={**perception, **extra}) for scenario, policy, extra in cells]
    oracle = make_config(scenario={**SHORT, "town": "town10"}, policy={"name": "baseline"}, loop={"max_time_s": 3.0})
    return [*configs, oracle]


# The default arithmetic ("auto": bf16 where the CPU runs it, whose frames share network calls, else fp32)
# in the default pass; fp32 in the slow pass where the default is bf16 (elsewhere the first case ran it).
@pytest.mark.parametrize("perception", [
    {"kind": "detector", "detector_precision": "auto"},
    pytest.param({"kind": "detector", "detector_precision": "fp32"},
                 marks=[pytest.mark.slow, pytest.mark.skipif(auto_arithmetic() == "fp32", reason="auto ran fp32 already")]),
    pytest.param({"kind": "detector", "detector_precision": "auto", "purify": "jpeg"}, marks=pytest.mark.slow),
], ids=["detector-auto", "detector-fp32", "detector-auto-jpeg"])
def test_a_mixed_batch_of_eight_gives_each_run_its_lone_result_bit_for_bit(perception):
    configs = _mixed_cells(perception)
    alone = [run_config(config)[0] for config in configs]
    together = run_lockstep(configs)
    assert [output.result.to_json_dict() for output in together] == [result.to_json_dict() for result in alone]
    # the batch really perceived: some car saw a stop sign
    assert any(output.result.to_json_dict()["first_detection_dist_m"] is not None for output in together[:-1])


# Two cars a kind: Town07 with one camera and Town10 with both, under sensor noise. Neither kind has a shared network
# call (`detect_many`): a batch runs their frames one after another, so what a batch could change here is which car's
# frame and state go where, which two cars show; the textures, placements and the oracle car of the mixed eight are
# the own detector's test above. Four cars a kind took 124 and 138 CPU-s on a 2-core AVX2 machine (fp32).
@pytest.mark.slow
@pytest.mark.parametrize("kind", ["coco", "ensemble"])
def test_the_real_detectors_batch_without_changing_a_run(kind):
    configs = _mixed_cells({"kind": kind})[:2]
    alone = [run_config(config)[0] for config in configs]
    assert [o.result.to_json_dict() for o in run_lockstep(configs)] == [r.to_json_dict() for r in alone]


def test_a_failing_run_fails_alone_and_the_batch_goes_on():
    good = make_config(scenario=SHORT, loop={"max_time_s": 1.0})
    bad = dataclasses.replace(good, scenario=dataclasses.replace(good.scenario, sign="no_such_texture"))
    outputs = run_lockstep([good, bad, good])
    assert isinstance(outputs[1], Exception) and "no_such_texture" in str(outputs[1])
    assert outputs[0].result.to_json_dict() == outputs[2].result.to_json_dict() == run_config(good)[0].to_json_dict()


def test_batch_records_equal_lone_records_apart_from_wall_time():
    specs = [short_run_spec(f"cell{seed}", seed, perception={"kind": "detector", "detector_precision": "auto"},
                            loop={"max_time_s": 2.0}) for seed in range(3)]
    strip = lambda records: [{k: v for k, v in r.items() if k != "wall_s"} for r in records]  # noqa: E731
    lone = run_batch(specs, workers=1, progress=False)
    batched = run_batch(specs, workers=1, progress=False, batch=8)
    assert strip(batched) == strip(lone)
    assert all(r["status"] == "ok" and r["wall_s"] > 0 for r in batched)


@pytest.mark.parametrize("count, workers, batch, sizes", [
    (10, 2, 8, [5, 5]), (16, 2, 8, [8, 8]), (17, 2, 8, [8, 8, 1]), (3, 1, 1, [1, 1, 1]), (3, 4, 8, [1, 1, 1]),
])
def test_groups_cover_every_run_once_and_feed_every_worker(count, workers, batch, sizes):
    specs = [short_run_spec("alone", seed) for seed in range(count)]  # no two of them siblings
    groups = list(lockstep_groups(iter(specs), group_size(count, workers, batch)))
    assert [len(g) for g in groups] == sizes
    assert [pair for g in groups for pair in g] == list(enumerate(specs))


def test_siblings_are_grouped_together_in_the_order_their_families_first_appear():
    # As a leaderboard's plan lists them: policy by policy, and in each the seeds.
    policies, seeds = ("baseline", "adjusted", "side_camera"), (0, 1, 2, 3)
    specs = [short_run_spec(policy, seed, policy={"name": policy}) for policy in policies for seed in seeds]
    groups = list(lockstep_groups(iter(specs), 3))
    assert [[spec.seed for _, spec in group] for group in groups] == [[seed] * 3 for seed in seeds]
    assert all([spec.cell for _, spec in group] == list(policies) for group in groups)
    assert sorted(pair[0] for group in groups for pair in group) == list(range(len(specs)))
    # ... but only within a window of the plan: beyond it, the plan's own order
    far_apart = list(lockstep_groups(iter(specs), 3, window=4))
    assert [[spec.seed for _, spec in group] for group in far_apart] == [[0, 1, 2], [3], [0, 1, 2], [3], [0, 1, 2], [3]]
