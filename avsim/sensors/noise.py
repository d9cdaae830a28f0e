"""Camera sensor noise: additive Gaussian read noise on 8-bit RGB frames, drawn from a seeded generator.

A run's noise comes from its own `numpy.random.Generator` (seeded from `scenario.seed`), drawn
frame by frame in the loop's fixed order, so the same config and seed give the same noise, bit
for bit. Recorders render their own copies of a frame and never draw from it: recording a
run does not change the noise its perception sees (nor does the recording show that noise).
"""

from __future__ import annotations

import hashlib

import numpy as np

# Second word of the noise generator's seed: independent of the start jitter (seeded by
# scenario.seed alone) and of an experiment's [vary] draws (stream 1).
SENSOR_NOISE_STREAM = 2


class SensorNoise:
    """Adds N(0, std_levels²) per pixel and channel to (H, W, 3) uint8 frames; std_levels in 8-bit levels.

    Drawing a fresh Gaussian per pixel costs about 10 ms a 640x480 frame here, as much as the
    detector. So the noise is drawn once, as a rounded bank twice a frame's size, and each frame
    takes a window of it at a random offset: every pixel still gets an independent-looking
    N(0, std²) value, and frames differ, at the cost of one integer add.
    """

    def __init__(self, std_levels: float, seed: int) -> None:
        if std_levels < 0:
            raise ValueError(f"sensor noise std must be >= 0 levels, got {std_levels}")
        self.std_levels = std_levels
        self.rng = np.random.default_rng((seed, SENSOR_NOISE_STREAM))
        self._bank = np.empty(0, np.int16)
        self._bank_digest = b""

    def state_key(self) -> bytes:
        """What the next frame's noise is drawn from: the level, the generator's state and the bank's
        contents. Two instances with equal keys draw the same noise for a frame of the same size, and
        are left in the same state (`avsim.frame_sharing`)."""
        return b"/".join((repr(self.std_levels).encode(), repr(self.rng.bit_generator.state).encode(), self._bank_digest))

    def follow(self, other: SensorNoise) -> None:
        """Take `other`'s state: for an instance whose `state_key` equalled `other`'s before `other`
        drew a frame's noise, in place of drawing the same noise itself."""
        self.rng.bit_generator.state = other.rng.bit_generator.state
        self._bank, self._bank_digest = other._bank, other._bank_digest  # the bank is never written in place

    def apply(self, rgb: np.ndarray, region_px: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """A noisy copy of `rgb` (the input itself when the std is 0), clipped to [0, 255].

        region_px: (x0, y0, x1, y1) [px], end-exclusive: add noise there only, and leave the rest of
        the copy zero (a frame of which only that part was rendered, `CameraRig.render_rgb`). The
        region gets the very values it gets when the whole frame is noised: the draws are the same.
        """
        if self.std_levels == 0:
            return rgb
        size = rgb.size
        if self._bank.size < 2 * size:
            self._bank = np.rint(self.rng.standard_normal(2 * size) * self.std_levels).astype(np.int16)
            self._bank_digest = hashlib.blake2b(self._bank.tobytes(), digest_size=16).digest()
        offset = int(self.rng.integers(0, self._bank.size - size + 1))
        window = self._bank[offset:offset + size].reshape(rgb.shape)
        if region_px is None:
            noisy = rgb.astype(np.int16) + window
            return np.clip(noisy, 0, 255, out=noisy).astype(np.uint8)
        x0, y0, x1, y1 = region_px
        noisy = rgb[y0:y1, x0:x1].astype(np.int16) + window[y0:y1, x0:x1]
        out = np.zeros_like(rgb)
        out[y0:y1, x0:x1] = np.clip(noisy, 0, 255, out=noisy)
        return out
