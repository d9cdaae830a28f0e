"""Differentiable image-space transformations for expectation over transformation (EOT).

Applied to composited camera images (B, 3, H, W) in [0, 1] after the sign is warped in,
so the texture must survive what the camera pipeline does to it: exposure and contrast,
fog, defocus or motion blur, sensor noise and JPEG re-encoding. Every draw comes from the
`torch.Generator` passed in, so a seed fixes the whole sequence.

Two sets of ranges: `PhotometricRanges()` (the study textures': a generic camera pipeline) and
`CLOSED_LOOP_PHOTOMETRIC`, what the closed loop really does to a frame before the detector sees
it: 8-bit quantisation and the seeded Gaussian read noise of `avsim.sensors.noise` (the
experiment files' 2 levels, rounded to whole levels), with a small exposure jitter as a margin
for the fitted lighting of each view. No blur, fog or JPEG: the loop has none (its fog is
rendered into the views themselves).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from kornia.enhance import jpeg_codec_differentiable
from kornia.filters import gaussian_blur2d, motion_blur

from avsim.errors import ConfigError
from avsim.validation import Range, check_span


@dataclass(frozen=True)
class PhotometricRanges:
    """Ranges the transformations are drawn from, uniformly."""

    gain: tuple[float, float] = (0.7, 1.3)  # exposure (the study's and ShapeShifter's brightness range)
    contrast: tuple[float, float] = (0.8, 1.2)
    fog_density: tuple[float, float] = (0.0, 0.3)  # blend weight toward the fog colour
    blur_probability: float = 0.5
    blur_sigma_px: tuple[float, float] = (0.3, 1.2)
    motion_blur_probability: float = 0.3
    motion_blur_kernel_px: int = 5
    noise_std: tuple[float, float] = (0.0, 0.03)
    jpeg_probability: float = 0.5
    jpeg_quality: tuple[float, float] = (50.0, 95.0)
    # The closed loop's sensor (`avsim.sensors.noise.SensorNoise`): whole 8-bit levels of
    # Gaussian read noise, after rounding the frame to 8 bits. 0 and False: neither.
    sensor_noise_std_levels: float = 0.0
    quantise_8bit: bool = False

    def __post_init__(self) -> None:
        # Checked before any view is rendered (a texture's record carries these: `avsim attack generate --from`).
        check_span(self.gain, "photometric gain", Range(0, 4, lo_open=True))
        check_span(self.contrast, "photometric contrast", Range(0, 4, lo_open=True))
        check_span(self.fog_density, "photometric fog_density", Range(0, 1))
        check_span(self.blur_sigma_px, "photometric blur_sigma_px", Range(0.01, 10, unit="px"))
        check_span(self.noise_std, "photometric noise_std", Range(0, 1))
        check_span(self.jpeg_quality, "photometric jpeg_quality", Range(1, 100))
        for name in ("blur_probability", "motion_blur_probability", "jpeg_probability"):
            Range(0, 1).check(getattr(self, name), f"photometric {name}")
        kernel_px = Range(3, 31, integer=True, unit="px").check(self.motion_blur_kernel_px, "photometric motion_blur_kernel_px")
        if kernel_px % 2 == 0:
            raise ConfigError(f"photometric motion_blur_kernel_px must be odd (a kernel centred on its pixel), got {kernel_px}")
        Range(0, 64, unit="levels").check(self.sensor_noise_std_levels, "photometric sensor_noise_std_levels")
        if not isinstance(self.quantise_8bit, bool):
            raise ConfigError(f"photometric quantise_8bit must be true or false, got {self.quantise_8bit!r}")


# The experiment files' perception.sensor_noise_std.
LOOP_SENSOR_NOISE_STD_LEVELS = 2.0
CLOSED_LOOP_PHOTOMETRIC = PhotometricRanges(
    gain=(0.95, 1.05), contrast=(1.0, 1.0), fog_density=(0.0, 0.0), blur_probability=0.0, motion_blur_probability=0.0,
    noise_std=(0.0, 0.0), jpeg_probability=0.0, sensor_noise_std_levels=LOOP_SENSOR_NOISE_STD_LEVELS, quantise_8bit=True)


FOG_RGB = (0.75, 0.78, 0.8)


def _uniform(n: int, bounds: tuple[float, float], generator: torch.Generator) -> torch.Tensor:
    lo, hi = bounds
    return lo + (hi - lo) * torch.rand(n, generator=generator)


def apply_photometric(images: torch.Tensor, ranges: PhotometricRanges, generator: torch.Generator) -> torch.Tensor:
    """(B, 3, H, W) in [0, 1] -> the same shape, each image with its own random draw.

    Gradients flow through every step (JPEG through kornia's differentiable codec).
    """
    b = images.shape[0]
    gain = _uniform(b, ranges.gain, generator).view(b, 1, 1, 1)
    contrast = _uniform(b, ranges.contrast, generator).view(b, 1, 1, 1)
    mean = images.mean(dim=(1, 2, 3), keepdim=True)
    out = ((images - mean) * contrast + mean) * gain
    fog = _uniform(b, ranges.fog_density, generator).view(b, 1, 1, 1)
    out = out * (1 - fog) + fog * torch.tensor(FOG_RGB, dtype=out.dtype).view(1, 3, 1, 1)

    blur = torch.rand(b, generator=generator) < ranges.blur_probability
    sigma = _uniform(b, ranges.blur_sigma_px, generator)
    motion = torch.rand(b, generator=generator) < ranges.motion_blur_probability
    angle_deg = _uniform(b, (-10.0, 10.0), generator)  # the car moves forward: streaks are nearly radial
    blurred = []
    for i in range(b):
        image = out[i:i + 1]
        if blur[i]:
            s = float(sigma[i])
            image = gaussian_blur2d(image, (5, 5), (s, s))
        if motion[i]:
            image = motion_blur(image, ranges.motion_blur_kernel_px, float(angle_deg[i]), 0.0)
        blurred.append(image)
    out = torch.cat(blurred)

    noise_std = _uniform(b, ranges.noise_std, generator).view(b, 1, 1, 1)
    out = out + noise_std * torch.randn(out.shape, generator=generator, dtype=out.dtype)
    out = out.clamp(0.0, 1.0)

    jpeg = torch.rand(b, generator=generator) < ranges.jpeg_probability
    if bool(jpeg.any()):
        quality = _uniform(b, ranges.jpeg_quality, generator)
        idx = torch.nonzero(jpeg).squeeze(1)
        encoded = jpeg_codec_differentiable(out[idx], quality[idx])
        out = out.index_copy(0, idx, encoded.clamp(0.0, 1.0))
    return apply_sensor(out, ranges, generator)


def apply_sensor(images: torch.Tensor, ranges: PhotometricRanges, generator: torch.Generator) -> torch.Tensor:
    """The loop's sensor on (B, 3, H, W) images in [0, 1]: rounding to 8-bit levels, then
    independent N(0, std^2) read noise per pixel and channel rounded to whole levels, then
    clipping, as `SensorNoise.apply` does to a uint8 frame. Rounding passes the gradient
    straight through (its derivative is zero almost everywhere, which would stop the attack)."""
    out = images
    if ranges.quantise_8bit:
        out = out + ((out * 255).round() / 255 - out).detach()
    if ranges.sensor_noise_std_levels > 0:
        noise = torch.randn(out.shape, generator=generator, dtype=out.dtype) * ranges.sensor_noise_std_levels
        out = (out + noise.round() / 255).clamp(0.0, 1.0)
    return out
