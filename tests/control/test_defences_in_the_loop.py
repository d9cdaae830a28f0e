"""The defences of the leaderboard in the closed loop: each new one stops before a clean sign in
Town07 standard at 85 km/h, none brakes for a junction with no stop sign, and the map prior's
two map failure modes (a sign the camera cannot see; a sign missing from the map)."""

import pytest

from avsim.experiments.leaderboard import DEFAULT_FILE, load_leaderboard, place_overrides
from avsim.metrics import PHANTOM_BRAKE_LEVEL
from avsim.runner import run_recorded
from helpers import make_config

BOARD = load_leaderboard(DEFAULT_FILE)
DEFENCES = {d.name: d for d in BOARD.defences}
NEW_DEFENCES = ("temporal_vote", "map_prior", "ensemble_or", "ensemble_and", "purify_jpeg", "purify_median")
TOWN07 = next(p for p in BOARD.places if p.label == "town07 standard")
# Short oracle runs at speed: enough road for the gate (40 m) and a full stop (about 35 m).
SHORT = {"start_speed_kmh": 85.0, "start_dist_m": 100.0}


def board_config(defence: str, *layers):
    """The defence as the leaderboard runs it (the learned detector, sensor noise), seed 0."""
    return BOARD.compose(place_overrides(TOWN07), DEFENCES[defence].overrides, *layers)


@pytest.mark.slow
@pytest.mark.parametrize("defence", NEW_DEFENCES)
def test_each_new_defence_stops_before_a_clean_sign_in_town07_at_85_kmh(defence):
    config = board_config(defence, BOARD.conditions["clean"].overrides)
    assert (config.scenario.town, config.scenario.placement, config.scenario.speed_kmh) == ("town07", "standard", 85.0)
    assert config.scenario.sign == "clean" and config.perception.kind in ("detector", "ensemble")
    result = run_recorded(config).result
    assert result.stopped_before_sign, (result.outcome, result.sign_margin_m)


@pytest.mark.slow
@pytest.mark.parametrize("defence", sorted(DEFENCES))
def test_no_defence_brakes_above_0_3_with_no_stop_sign_in_town07_at_seed_0(defence):
    config = board_config(defence, {"scenario": {"sign": "none"}})
    assert config.scenario.town == "town07" and config.scenario.seed == 0 and not config.scenario.stop_required
    result = run_recorded(config).result
    assert result.max_brake <= PHANTOM_BRAKE_LEVEL, (result.outcome, result.max_brake, result.first_detection_dist_m)
    assert result.outcome == "drove_through"


# ---- the map prior's failure modes ---------------------------------------------------------------

def blind(**scenario):
    """An oracle the camera never reports a sign through: no box is ever 1000 px tall."""
    return make_config(scenario={**SHORT, **scenario}, perception={"oracle_min_box_height_px": 1000.0},
                       policy={"name": "map_prior"})


def test_the_map_prior_stops_for_a_sign_the_camera_cannot_see_at_all():
    result = run_recorded(blind()).result
    assert result.first_detection_dist_m is None  # the camera never saw it
    assert result.stopped_before_sign


def test_the_map_prior_does_not_stop_for_a_sign_missing_from_the_map_unless_the_camera_sees_it():
    unseen = run_recorded(blind(map_error="missing_stop")).result
    assert unseen.outcome == "never_braked"
    seen = run_recorded(make_config(scenario={**SHORT, "map_error": "missing_stop"}, policy={"name": "map_prior"})).result
    assert seen.stopped_before_sign and seen.first_detection_dist_m is not None


def test_the_map_prior_stops_for_a_mapped_sign_that_is_absent_from_the_world():
    result = run_recorded(make_config(scenario={**SHORT, "sign": "none", "map_error": "phantom_stop"},
                                      policy={"name": "map_prior"})).result
    assert not result.stop_required and result.outcome == "phantom_stop" and result.phantom_brake


@pytest.mark.slow
def test_the_map_prior_stops_for_an_attacked_sign_with_the_detector_disabled():
    # A threshold no detector score reaches: the camera confirms nothing, attacked or not.
    config = board_config("map_prior", {"scenario": {"sign": "yang"}, "policy": {"conf_threshold": 0.999}})
    result = run_recorded(config).result
    assert result.first_detection_dist_m is None and result.stopped_before_sign
    missing = run_recorded(board_config("map_prior", {"scenario": {"sign": "yang", "map_error": "missing_stop"},
                                                      "policy": {"conf_threshold": 0.999}})).result
    assert missing.outcome == "never_braked"
