"""`gymnasium.make_vec("avsim/StopSign-v0", num_envs=N, vectorization_mode="vector_entry_point")`:
N episodes in one process, perceived together.

    import gymnasium
    import avsim.gym

    envs = gymnasium.make_vec("avsim/StopSign-v0", num_envs=8, vectorization_mode="vector_entry_point",
                              perception="detector", images=False)
    obs, info = envs.reset(seed=0)               # episode seeds 0..7
    obs, rewards, terminated, truncated, info = envs.step(envs.action_space.sample())

Each of the N environments is a `StopSignEnv` with the keyword arguments given; they share one
network per perception (`FrameDetectorCache`), and at every step all N cars' frames go through
it in one call (`avsim.lockstep.perceive_together`), so a step costs less than N steps of N
separate environments. Everything else is each environment's own, and each gives what it gives
alone: N environments here and `gymnasium.make_vec(..., vectorization_mode="sync")` give the same
episodes, bit for bit (tests/gym/test_gym_vector.py).

Gymnasium's conventions hold: `reset(seed=k)` seeds environment i with k + i (a list seeds each);
observations, rewards and ends are batched along a first axis of N; infos are dicts of arrays with
a `_key` mask each. Autoreset is Gymnasium's default, next step: the step after an episode ends
resets that environment (its action is ignored, its reward is 0) and returns the new episode's
first observation.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array, iterate

from avsim.config import check_seed
from avsim.errors import ConfigError
from avsim.gym.env import StopSignEnv
from avsim.lockstep import perceive_together
from avsim.perception.factory import FrameDetectorCache


# Each environment holds its own MuJoCo model, renderers and loop (about 130 MB with images): a bound that
# catches a mistyped count before it builds for minutes and exhausts memory.
MAX_NUM_ENVS = 256


class StopSignVectorEnv(VectorEnv):
    """N `StopSignEnv`s stepped together (module docstring); kwargs are `StopSignEnv`'s."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, **kwargs: Any) -> None:
        if not isinstance(num_envs, int) or isinstance(num_envs, bool) or not 1 <= num_envs <= MAX_NUM_ENVS:
            raise ConfigError(f"num_envs must be a whole number in 1 .. {MAX_NUM_ENVS}, got {num_envs!r}")
        kwargs.pop("max_episode_steps", None)  # the episode length is the config's loop.max_time_s
        if kwargs.get("render_mode") is not None:
            raise ConfigError("the vector environment renders no frames; observe images with images=True")
        self._detectors = FrameDetectorCache()
        self.envs = [StopSignEnv(**kwargs, detectors=self._detectors) for _ in range(num_envs)]
        self.num_envs = num_envs
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.metadata = {**self.metadata, "render_fps": self.envs[0].metadata["render_fps"]}
        self._observations = create_empty_array(self.single_observation_space, num_envs)
        self._autoreset = np.zeros(num_envs, dtype=np.bool_)

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Any, dict[str, Any]]:
        """Start an episode in every sub-environment (`seed`: an int gives env i seed + i, a list one
        seed each); the batched observations and infos.
        """
        seeds = _seeds(seed, self.num_envs)
        for env_seed in seeds:  # every seed before any environment resets: a refusal leaves them all as they were
            if env_seed is not None:
                check_seed(env_seed, "reset(seed=...)'s seed of an environment (seed + i, or the list's)")
        super().reset(seed=seeds[0])  # the vector's own generator, which Gymnasium seeds with an int
        infos: dict[str, Any] = {}
        for i, (env, env_seed) in enumerate(zip(self.envs, seeds)):
            infos = self._add_info(infos, env.begin_episode(env_seed, options), i)
        self._autoreset[:] = False
        return self._observe_all(), infos

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One control step of every sub-environment with its action; a sub-environment whose episode
        ended on the previous step is reset instead (next-step autoreset).
        """
        try:
            values = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError):
            values = np.full(0, np.nan)
        if values.shape != self.action_space.shape or not np.isfinite(values).all():
            # Checked for every environment before any steps: too few rows would leave the rest unstepped, unseen.
            got = (repr(actions) if not values.size else f"shape {values.shape}" if values.shape != self.action_space.shape
                   else "a value that is not finite")
            raise ConfigError(f"actions must be an array of shape {self.action_space.shape} (one row of "
                              f"{self.single_action_space.shape[0]} finite numbers per environment), got {got}")
        rewards = np.zeros(self.num_envs, dtype=np.float64)
        terminated = np.zeros(self.num_envs, dtype=np.bool_)
        truncated = np.zeros(self.num_envs, dtype=np.bool_)
        infos: dict[str, Any] = {}
        for i, (env, action) in enumerate(zip(self.envs, iterate(self.action_space, actions))):
            if self._autoreset[i]:
                info = env.begin_episode(None, None)
            else:
                rewards[i], terminated[i], truncated[i], info = env.act(action)
            infos = self._add_info(infos, info, i)
        self._autoreset = terminated | truncated
        return self._observe_all(), rewards, terminated, truncated, infos

    def close_extras(self, **kwargs: Any) -> None:
        """Close every sub-environment's closed loop."""
        for env in self.envs:
            env.close()

    def _observe_all(self) -> Any:
        """Perceive every car together, give each environment its detections, batch the observations."""
        perceived = perceive_together([(env.loop, env.cameras) for env in self.envs])
        observations = []
        for env, detections in zip(self.envs, perceived):
            if isinstance(detections, Exception):
                raise detections
            observations.append(env.observe(detections))
        self._observations = concatenate(self.single_observation_space, observations, self._observations)
        return copy.deepcopy(self._observations)  # the caller's own, as Gymnasium's vectors give by default


def _seeds(seed: int | list[int | None] | None, count: int) -> list[int | None]:
    """Each environment's reset seed, by Gymnasium's vector convention."""
    if seed is None:
        return [None] * count
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return [int(seed) + i for i in range(count)]
    if isinstance(seed, (str, bytes, bool, float)) or not hasattr(seed, "__len__"):
        raise ConfigError(f"reset(seed=...) takes an int (environment i gets seed + i), a list of one int or None per "
                          f"environment, or None; got {seed!r}")
    seeds = [int(s) if isinstance(s, np.integer) else s for s in seed]
    if len(seeds) != count:
        raise ConfigError(f"reset(seed=[...]) needs one seed per environment: {len(seeds)} for {count}")
    return seeds
