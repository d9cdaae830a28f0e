"""`gymnasium.make_vec("avsim/StopSign-v0", vectorization_mode="vector_entry_point")`: N episodes
perceived together give what Gymnasium's own synchronous vector of the same environments gives."""

import gymnasium
import numpy as np
import pytest

import avsim.gym
import avsim.gym.vector
from avsim.errors import ConfigError

# Episodes of a few dozen steps that see the sign, so an autoreset happens within the test.
SHORT = {"scenario": {"start_dist_m": 45.0, "speed_kmh": 40.0, "start_speed_kmh": 40.0}, "loop": {"max_time_s": 1.5}}


def _make_vec(mode: str, num_envs: int, **kwargs):
    # The detector at its default arithmetic: bf16 where the CPU runs it, whose frames share one network
    # call (the batched path), else fp32, one call a frame.
    return gymnasium.make_vec(avsim.gym.ENV_ID, num_envs=num_envs, vectorization_mode=mode,
                              config_overrides=SHORT, **kwargs)


def _rollout(envs, steps: int, seed: int):
    """reset(seed) then `steps` steps of fixed, seeded actions; every output kept."""
    actions = np.random.default_rng(7).uniform(0, 1, (steps, *envs.action_space.shape)).astype(np.float32)
    out = [envs.reset(seed=seed)]
    for action in actions:
        out.append(envs.step(action))
    envs.close()
    return out


def _assert_same(a, b):
    if isinstance(a, dict):
        assert sorted(a) == sorted(b)
        for key in a:
            _assert_same(a[key], b[key])
    elif isinstance(a, (tuple, list)):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _assert_same(x, y)
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert a.shape == b.shape
        for x, y in zip(a, b):
            _assert_same(x, y)
    else:
        np.testing.assert_array_equal(a, b)


# Both in the slow pass (about 30 CPU-s each), with the other end-to-end checks, so the default run stays under its
# 10 minutes; the vector env's spaces and autoreset metadata are checked in the default pass below.
@pytest.mark.slow
@pytest.mark.parametrize("kwargs", [{"perception": "detector", "images": False},
                                    {"perception": "oracle", "cameras": ("front", "side")}], ids=["detector", "oracle"])
def test_the_vector_entry_point_gives_the_same_episodes_as_gymnasiums_sync_vector(kwargs):
    # An episode is 30 steps (SHORT's 1.5 s at 20 Hz): 34 steps hold the first ends, the autoreset step after
    # each, and the first steps of the next episodes.
    together = _rollout(_make_vec("vector_entry_point", 4, **kwargs), 34, seed=3)
    alone = _rollout(_make_vec("sync", 4, **kwargs), 34, seed=3)
    _assert_same(together, alone)
    ends = np.array([step[2] | step[3] for step in together[1:]])
    assert ends[:-2].any(), "an episode should end, and autoreset, within the rollout"
    seeds = together[0][1]["seed"]
    assert list(seeds) == [3, 4, 5, 6]


def test_the_vector_env_has_gymnasiums_batched_spaces_and_autoreset_metadata():
    envs = _make_vec("vector_entry_point", 3, perception="oracle", images=False)
    assert envs.num_envs == 3
    assert envs.observation_space.contains(envs.reset(seed=0)[0])
    assert envs.action_space.shape == (3, 2)
    assert envs.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP
    envs.close()


@pytest.mark.parametrize("num_envs", [0, -2, 1.5])
def test_a_bad_count_of_environments_is_one_line(num_envs):
    with pytest.raises(ConfigError, match="num_envs"):
        avsim.gym.vector.StopSignVectorEnv(num_envs=num_envs, perception="oracle")


@pytest.mark.parametrize("num_envs", [True, avsim.gym.vector.MAX_NUM_ENVS + 1])
def test_a_count_that_is_a_bool_or_would_exhaust_memory_is_refused_before_any_environment_is_built(num_envs):
    with pytest.raises(ConfigError, match="num_envs"):
        avsim.gym.vector.StopSignVectorEnv(num_envs=num_envs, perception="oracle")


def _times(envs):
    return [env.loop.time_s for env in envs.envs]


def test_bad_actions_and_seeds_are_refused_before_any_environment_moves():
    envs = avsim.gym.vector.StopSignVectorEnv(num_envs=2, perception="oracle", images=False)
    envs.reset(seed=[5, 6])
    assert [env.loop.config.scenario.seed for env in envs.envs] == [5, 6]
    for actions in (np.zeros((1, 2)), np.zeros((3, 2)), np.array([[0.1, 0.0], [np.nan, 0.0]]), "x"):
        with pytest.raises(ConfigError, match=r"shape \(2, 2\)"):
            envs.step(actions)
    assert _times(envs) == [0.0, 0.0]  # too few rows once stepped the first car alone, unseen
    for seed in (2**32 - 1, 1.5, "3", True, [1]):  # the first overflows in the second environment (seed + 1)
        with pytest.raises(ConfigError, match="seed"):
            envs.reset(seed=seed)
    assert [env.loop.config.scenario.seed for env in envs.envs] == [5, 6]
    envs.close()
