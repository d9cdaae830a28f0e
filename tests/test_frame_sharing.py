"""Cars of a lock-step batch that would see the same frames render and detect them once
(`avsim.frame_sharing`), and every run's result stays what it is alone, bit for bit."""

import dataclasses

import pytest

from avsim.frame_sharing import sibling_key, sight_key
from avsim.lockstep import run_lockstep
from avsim.loop import ClosedLoop
from avsim.runner import run_config
from avsim.sensors.camera import CameraRig
from helpers import SHORT_RUN, make_config

# Short runs at 60 km/h from 75 m that see the sign and brake within their 4 s, under sensor noise:
# the cars drive alike until a policy first brakes (27-41 m before the line), then apart.
SHORT = {**SHORT_RUN, "speed_kmh": 60.0, "start_speed_kmh": 60.0, "start_dist_m": 75.0}
# Every policy that looks through the camera: front-only ones and front-and-side ones.
CAMERA_POLICIES = ("baseline", "adjusted", "temporal_vote", "map_prior", "side_camera", "combined", "study_stack")


def _config(policy: str, seed: int = 0, **scenario):
    return make_config(scenario={**SHORT, "seed": seed, **scenario}, policy={"name": policy}, loop={"max_time_s": 4.0},
                       perception={"kind": "detector", "sensor_noise_std": 2.0})


def _count_renders(monkeypatch) -> list:
    rendered = []
    real = CameraRig.render_rgb
    monkeypatch.setattr(CameraRig, "render_rgb", lambda self, *a, **k: (rendered.append(1), real(self, *a, **k))[1])
    return rendered


def test_siblings_share_their_frames_until_they_drive_apart_and_each_gets_its_lone_result(monkeypatch):
    configs = [_config(policy) for policy in CAMERA_POLICIES] + [_config("baseline", seed=1)]  # and one not a sibling
    alone = [run_config(config)[0].to_json_dict() for config in configs]
    rendered = _count_renders(monkeypatch)
    unshared = run_lockstep(configs, share_frames=False)
    renders_unshared = len(rendered)
    rendered.clear()
    shared = run_lockstep(configs)
    assert [o.result.to_json_dict() for o in shared] == [o.result.to_json_dict() for o in unshared] == alone
    assert [o.records for o in shared] == [o.records for o in unshared]
    # the policies did not all drive alike to the end: some braked before others
    assert len({(r["dist_at_brake_m"], r["max_brake"]) for r in alone[:-1]}) > 1
    # ... and until they parted, the seven cars' frames were rendered once, not seven times
    assert len(rendered) < 0.6 * renders_unshared, (len(rendered), renders_unshared)


def test_a_sight_key_holds_the_state_the_noise_and_the_cameras_but_not_the_policy():
    loops = [ClosedLoop(_config("baseline")), ClosedLoop(_config("adjusted")), ClosedLoop(_config("baseline", seed=1)),
             ClosedLoop(_config("baseline", town="town03"))]
    try:
        baseline, adjusted, other_seed, other_town = loops
        assert sibling_key(baseline.config) == sibling_key(adjusted.config) != sibling_key(other_seed.config)
        assert sight_key(baseline, ("front",)) == sight_key(adjusted, ("front",))
        assert sight_key(baseline, ("front",)) != sight_key(baseline, ("front", "side"))
        assert sight_key(baseline, ("front",)) not in (sight_key(other_seed, ("front",)), sight_key(other_town, ("front",)))
        baseline.step()  # the car moves and its noise draws: neither matches the car that stayed
        assert sight_key(baseline, ("front",)) != sight_key(adjusted, ("front",))
    finally:
        for loop in loops:
            loop.close()


def test_a_perception_without_frames_has_no_sight_key():
    loop = ClosedLoop(make_config(scenario=SHORT))  # the oracle: boxes from segmentation, nothing to share
    try:
        assert sight_key(loop, ("front",)) is None
    finally:
        loop.close()


def test_siblings_without_sensor_noise_share_every_frame_while_they_drive_alike(monkeypatch):
    # 1 s from 150 m: no policy sees the sign yet, so nothing parts the two cars
    configs = [make_config(scenario={**SHORT, "start_dist_m": 150.0}, policy={"name": policy}, loop={"max_time_s": 1.0},
                           perception={"kind": "detector", "sensor_noise_std": 0.0}) for policy in ("baseline", "adjusted")]
    rendered = _count_renders(monkeypatch)
    shared = run_lockstep(configs)
    assert [len(o.records) for o in shared] == [20, 20] and len(rendered) == 20


def test_recorded_siblings_draw_each_shared_frame_once_for_their_recordings_too(monkeypatch, tmp_path):
    # 1 s from 150 m: the two cars drive alike throughout, and each records its front camera
    configs = [make_config(scenario={**SHORT, "start_dist_m": 150.0}, policy={"name": policy}, loop={"max_time_s": 1.0},
                           perception={"kind": "detector", "sensor_noise_std": 2.0}) for policy in ("baseline", "adjusted")]
    recordings = [{"rrd_path": str(tmp_path / f"{policy}.rrd")} for policy in ("baseline", "adjusted")]
    drawn = []
    real = CameraRig._draw
    monkeypatch.setattr(CameraRig, "_draw", lambda self, *a, **k: (drawn.append(1), real(self, *a, **k))[1])
    alone = [run_config(config)[0] for config in configs]
    drawn.clear()
    shared = run_lockstep(configs, recordings=recordings)
    assert [o.result for o in shared] == alone
    # 21 sensing states (the 20 steps' and the last), each drawn once for both recordings and perceptions
    assert len(drawn) == 21 and all((tmp_path / f"{policy}.rrd").stat().st_size > 0 for policy in ("baseline", "adjusted"))


@pytest.mark.slow
def test_ensembles_that_differ_only_in_fusion_share_their_networks_and_fuse_each_by_its_own_rule(monkeypatch):
    # Town10 standard from 75 m: the two networks disagree on some frames, so "or" and "and" brake at different points
    configs = [make_config(scenario={**SHORT, "town": "town10"}, policy={"name": "baseline"}, loop={"max_time_s": 4.0},
                           perception={"kind": "ensemble", "ensemble_fusion": fusion, "sensor_noise_std": 2.0})
               for fusion in ("or", "and")]
    assert sibling_key(configs[0]) == sibling_key(configs[1])
    alone = [run_config(config)[0].to_json_dict() for config in configs]
    rendered = _count_renders(monkeypatch)
    shared = run_lockstep(configs)
    assert [o.result.to_json_dict() for o in shared] == alone
    assert alone[0]["dist_at_brake_m"] != alone[1]["dist_at_brake_m"]  # they parted
    assert len(rendered) < sum(len(o.records) for o in shared)  # some frames were drawn and detected once for both
    # a purifier takes the ensemble's fused boxes whole: then the fusion keeps them apart
    purified = [dataclasses.replace(c, perception=dataclasses.replace(c.perception, purify="median")) for c in configs]
    assert sibling_key(purified[0]) != sibling_key(purified[1])
