"""avsim as a Gymnasium environment: `avsim/StopSign-v0` (`avsim.gym.env.StopSignEnv`).

Importing this package registers the environment, so after `import avsim.gym`,
`gymnasium.make("avsim/StopSign-v0", ...)` makes it. Without the import,
`gymnasium.make("avsim.gym:avsim/StopSign-v0", ...)` imports the package itself (Gymnasium 1.x
has no plugin entry points: an id is registered by importing the module that registers it).
`gymnasium.make_vec("avsim/StopSign-v0", num_envs=N, vectorization_mode="vector_entry_point")`
makes N environments perceived together (`avsim.gym.vector.StopSignVectorEnv`).
"""

from gymnasium.envs.registration import register, registry

from avsim.gym.env import StopSignEnv

ENV_ID = "avsim/StopSign-v0"

if ENV_ID not in registry:  # importing twice (e.g. after importlib.reload) must not warn
    # Without Gymnasium's passive checker: in Gymnasium 1.4 it breaks every later step() once a first reset() has
    # raised (a refused seed), as it then holds no reset data to compare the step's with. avsim's tests run
    # Gymnasium's full `check_env` on the environment instead; `disable_env_checker=False` in `make` brings it back.
    register(id=ENV_ID, entry_point="avsim.gym.env:StopSignEnv", vector_entry_point="avsim.gym.vector:StopSignVectorEnv",
             disable_env_checker=True)

__all__ = ["ENV_ID", "StopSignEnv"]
