"""Cars of a lock-step batch that would see the same frames: render and detect those frames once.

Runs that differ only in their policy (a leaderboard's defences, one table's policies on one seed)
drive the same car through the same scene from the same start, and see the same pixels with the
same sensor noise until one of them first acts differently: usually the first brake, 40 m or
less before the sign, after an approach of 150 m or more. Until then each of them rendered and ran
the network on a frame that another car of the batch had just rendered and run. Now the first car
does it (the leader) and the others (its followers) take its detections, through their own range
limit, and its sensor noise's state after the draw, which is the state their own draw would have
left.

Recorded runs render each sensing state whole for their recording before the perception asks for
it; siblings' rigs keep those frames in one store, so a follower's recorder takes its leader's frame
(`KeptFramePools`).

A car's sight key is everything its perception's output at a control tick is a function of:

- its config without the policy section: the scene and its lighting, the cameras and their
  photographic model, the perception and its network, the sensor noise's seed and level, the
  vehicle (the policy alone is what sharing is for; any other difference keeps the cars apart),
  except an ensemble's fusion rule: ensembles of the same networks share what each network finds
  and fuse it each by its own rule (`FUSION_KEYS`);
- the state the frames are drawn from: the time, the joint positions, every geom's, camera's and
  light's pose, and every geom's group and colour (`sensors.camera.render_key`, what a renderer
  reads from the model and data; the rest of the model does not change during a run);
- the cameras asked for, in order;
- the sensor noise's generator state and the contents of its bank (`SensorNoise.state_key`).

Two cars with equal keys get the same frames bit for bit, so a follower's records are those it
gets alone: `tests/test_frame_sharing.py` checks it on a batch of every policy that looks through
the camera, recorded and not, and `tests/test_lockstep.py` on mixed batches. The batch commands put
siblings into the same lock-step group (`avsim.experiments.plan.lockstep_groups`). A car whose perception renders no frames (the oracle,
none) has no key and perceives alone.
"""

from __future__ import annotations

import hashlib
import json
import weakref
from typing import TYPE_CHECKING

from avsim.perception.frame import FramePerception
from avsim.sensors.camera import CameraRig, render_key

if TYPE_CHECKING:  # annotations only: avsim.loop imports nothing from here
    from avsim.config import SimConfig
    from avsim.loop import ClosedLoop


# The perception keys an ensemble reads only after its networks have run, to fuse their boxes: ensembles
# that differ only in them share the networks' output (`EnsembleDetector.detect_members`), each fusing it
# by its own rule. Not behind a purifier, which takes the ensemble's fused detections whole.
FUSION_KEYS = ("ensemble_fusion", "ensemble_k")


def sibling_key(config: SimConfig) -> bytes:
    """A digest of `config` without its policy section (and an ensemble's `FUSION_KEYS`): runs with
    equal keys see the same frames until their cars first move differently (the module docstring)."""
    sections = {name: value for name, value in config.to_dict().items() if name != "policy"}
    if config.perception.kind == "ensemble" and config.perception.purify == "none":
        sections["perception"] = {key: value for key, value in sections["perception"].items() if key not in FUSION_KEYS}
    return hashlib.blake2b(json.dumps(sections, sort_keys=True, default=repr).encode(), digest_size=16).digest()


# A run's `sibling_key`, computed once a run (a run's config does not change).
_sibling_keys: weakref.WeakKeyDictionary[ClosedLoop, bytes] = weakref.WeakKeyDictionary()


class KeptFramePools:
    """Lets sibling runs' camera rigs keep their last frames in one store (`CameraRig.pool_kept_frames`):
    a recorded run's recorder renders each sensing state whole, and a sibling's recorder in the same
    state then takes that frame instead of drawing it again. Join each run before its recorders open,
    since they render the first sensing state when they do."""

    def __init__(self) -> None:
        self._first_rig_of: dict[bytes, CameraRig] = {}  # sibling key -> the rig whose store the family shares

    def join(self, loop: ClosedLoop) -> None:
        """Pool `loop`'s rig with the first joined sibling's, if any."""
        first = self._first_rig_of.setdefault(sibling_key(loop.config), loop.rig)
        if first is not loop.rig:
            loop.rig.pool_kept_frames(first)


# (sibling key, cameras, sensor noise state, render state): `sight_key`.
SightKey = tuple[bytes, tuple[str, ...], bytes, bytes]


def sight_key(loop: ClosedLoop, cameras: tuple[str, ...]) -> SightKey | None:
    """What `loop`'s perception of `cameras` at its current state is a function of (the module
    docstring); None where the perception renders no frames."""
    perception = loop.perception
    if not isinstance(perception, FramePerception):
        return None
    config_key = _sibling_keys.get(loop)
    if config_key is None:
        config_key = _sibling_keys[loop] = sibling_key(loop.config)
    noise = perception.noise.state_key() if perception.noise is not None else b"no noise"
    return config_key, tuple(cameras), noise, render_key(loop.model, loop.data)
