"""Fair-weather cumulus in the daylight sky (scenario.cloud_oktas > 0 with scenario.sky = "daylight").

A sign on a rural road is often seen against a sky with clouds in it, not against a clear one. This
module lays a seeded field of clouds over the clear daylight sky of `avsim.world.sky`, at a cover
stated in oktas (eighths of the sky, as weather observers report it), lit from the physics of a
cloud seen from below rather than coloured by hand.

**Where the clouds are.** One flat layer at `scenario.cloud_base_m` above the ground (1500 m by
default, where fair-weather cumulus have their bases over land in summer: 1-2 km; a few hundred metres
in humid sea air, 3 km and more over deserts). A view direction d (world frame, z up) meets
it at the horizontal point d_xy * h / d_z, so clouds crowd together towards the horizon, as a
camera sees them. The layer's optical depth is fractal noise of that point (`cloud_noise`): five
octaves, the largest wavelength CLOUD_WAVELENGTH_M (cumulus humilis and mediocris are 0.5-2 km
across), each octave half the wavelength and half the amplitude of the one before. The cloud edge
is the noise level above which the covered fraction of the sky dome, solid-angle weighted as an
observer counts oktas, is oktas / 8; the optical depth rises from 0 at the edge to
CLOUD_MAX_OPTICAL_DEPTH one noise standard deviation inside it.

**How bright they are.** Seen from below, a cloud of optical depth tau passes the clear sky behind
it attenuated by exp(-tau), and adds the sunlight it scatters through its depth. For a
non-absorbing cloud of scattering asymmetry g, the two-stream approximation gives the diffuse
transmittance t(tau) = 1 / (1 + 3/4 (1 - g) tau) (Bohren, Multiple scattering of light and some of
its observable consequences, Am. J. Phys. 55, 1987); its unscattered part is exp(-tau), and the
scattered rest leaves the cloud's base about evenly in every direction, so the base has the
luminance (t - exp(-tau)) E / pi, with E the sun's illuminance on the layer. Thin edges are
therefore bright and the thick middles grey, as cumulus look from below. The light is neutral
(the D65 white of sRGB). E is DIRECT_NORMAL_ILLUMINANCE_LX times the sine of the sun's
elevation, and the clear sky is Preetham's in the same unit (kcd/m^2), so the clouds and the
sky between them keep the ratio that physics gives; the whole is then scaled by the clear sky's
exposure factor (`avsim.world.sky`), so the clear patches are the daylight sky's own.

**Distance.** Towards the horizon a cloud lies tens of kilometres away and the air in between
lights up like the horizon sky: the cloud's contrast against the clear sky falls as
exp(-3.912 r / V) over the slant range r (Koschmieder's law, V the meteorological visibility,
`scenario.cloud_visibility_km`, 30 km by default for clear air). The same air would also raise the
sky's turbidity; the two are set independently here, and V fades only the clouds.

What is not modelled, each stated in docs/realism.md: the sunlit sides of towering clouds (a flat
layer is seen from below only), the shadows clouds cast (the scene's sun is never behind a cloud,
even where the sky shows one across it), cloud colour at sunset, and the sun's disc (around the sun
the daylight sky already clips to white at this exposure).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import cv2
import numpy as np

CLOUD_WAVELENGTH_M = 1600.0  # the noise's largest wavelength along the layer [m]
CLOUD_OCTAVES = 5
CLOUD_MAX_OPTICAL_DEPTH = 30.0  # vertical optical depth inside a cloud (fair-weather cumulus: about 10-50)
CLOUD_ASYMMETRY_G = 0.85  # scattering asymmetry of cloud droplets at visible wavelengths
DIRECT_NORMAL_ILLUMINANCE_LX = 100_000.0  # clear-sky direct sunlight on a surface facing the sun [lx], high sun
CLOUD_TEXELS = 256  # a face of the cloudy skybox: 0.35 deg a texel, so a cloud's edge spans a few camera pixels
_LATTICE = 64  # random values per octave and axis; the field repeats every 64 wavelengths (over 100 km)
_KOSCHMIEDER = 3.912  # -ln(0.02): the contrast threshold that defines meteorological visibility


@dataclass(frozen=True)
class CloudLayer:
    """One run's clouds: `oktas` (1-6) of the sky covered, in a layer `base_m` [m] above the road, faded
    towards the horizon by air of meteorological visibility `visibility_m` [m], drawn from `rng`."""

    oktas: int
    base_m: float
    visibility_m: float
    rng: np.random.Generator


def cloud_rng(seed: int, layout_seed: int) -> np.random.Generator:
    """The random stream of one run's clouds: a fresh field for every scenario seed, as the weather
    changes from day to day, in each town's scenery."""
    return np.random.default_rng([seed, layout_seed, zlib.crc32(b"clouds")])


def layer_points_m(directions: np.ndarray, base_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each direction ((..., 3) unit, world frame) meets the cloud layer `base_m` [m] up: the (...) horizontal x
    and y [m] relative to the camera, and the slant range r [m]; directions at or below the horizon get
    r = inf (they never meet it) and x = y = 0."""
    above = directions[..., 2] > 0
    met_range_m = base_m / np.where(above, directions[..., 2], 1.0)  # a placeholder range below the horizon
    x_m = np.where(above, directions[..., 0] * met_range_m, 0.0)
    y_m = np.where(above, directions[..., 1] * met_range_m, 0.0)
    return x_m, y_m, np.where(above, met_range_m, np.inf)


def cloud_noise(x_m: np.ndarray, y_m: np.ndarray, rng: np.random.Generator, footprint_m: np.ndarray | None = None) -> np.ndarray:
    """Fractal noise (x_m's shape) at layer points x_m, y_m [m]: CLOUD_OCTAVES octaves of bicubically
    interpolated random lattices (cv2.remap, wrapping at the lattice's edge), amplitudes halving.

    footprint_m: (x_m's shape) how much of the layer one texel spans [m]. An octave finer than the first
    whose wavelength is under four footprints fades out, and is gone at two (the texture's Nyquist limit),
    so that the far clouds near the horizon do not alias into specks. The first octave stays everywhere:
    it decides where the clouds are. It too is under-sampled along the line of sight near the horizon: below about
    6.9 deg for a 1500 m base (12.5 km away, where 30 km visibility leaves 20 % of a cloud's contrast) and 4.2 deg
    for 600 m (8.1 km; 35 %, or 67 % at 80 km). There the texels sample the field coarsely rather than average it
    (docs/realism.md, "When the cloud base and the visibility change")."""
    total = np.zeros(x_m.shape, np.float64)
    # The layer is offset by a random shift so that the camera does not always sit over a lattice node.
    shift_m = rng.uniform(0, _LATTICE * CLOUD_WAVELENGTH_M, size=2)
    for octave in range(CLOUD_OCTAVES):
        lattice = rng.standard_normal((_LATTICE, _LATTICE)).astype(np.float32)
        wavelength_m = CLOUD_WAVELENGTH_M / 2 ** octave
        u = np.mod((x_m + shift_m[0]) / wavelength_m, _LATTICE).astype(np.float32)
        v = np.mod((y_m + shift_m[1]) / wavelength_m, _LATTICE).astype(np.float32)
        # remap refuses maps of 32767 rows or more, so they keep the texture's 2-D shape rather than one column.
        sampled = cv2.remap(lattice, u.reshape(-1, u.shape[-1]), v.reshape(-1, v.shape[-1]), cv2.INTER_CUBIC,
                            borderMode=cv2.BORDER_WRAP)
        weight = 1.0 if footprint_m is None or octave == 0 else np.clip(wavelength_m / (2 * footprint_m) - 1, 0.0, 1.0)
        total += 0.5 ** octave * weight * sampled.reshape(x_m.shape)
    return total


def texel_footprint_m(directions: np.ndarray, solid_angles_sr: np.ndarray, base_m: float) -> np.ndarray:
    """How far along the cloud layer `base_m` [m] up one texel reaches [m], in the direction it is most stretched:
    its angular size sqrt(solid angle) at the slant range h / d_z, foreshortened by the layer's tilt to the
    ray (1 / d_z again). Infinite at and below the horizon."""
    up = np.maximum(directions[..., 2], 1e-9)
    return np.where(directions[..., 2] > 0, np.sqrt(solid_angles_sr) * base_m / up ** 2, np.inf)


def cover_threshold(noise: np.ndarray, weights: np.ndarray, oktas: int) -> float:
    """The noise level above which the sky is cloud: the weighted (1 - oktas / 8) quantile of the
    noise over the texels with positive weight (their solid angle above the horizon)."""
    values, w = noise[weights > 0], weights[weights > 0]
    order = np.argsort(values, kind="stable")
    cumulative = np.cumsum(w[order]) / w.sum()
    return float(values[order][np.searchsorted(cumulative, 1 - oktas / 8)])


def optical_depth(noise: np.ndarray, threshold: float, noise_std: float) -> np.ndarray:
    """Vertical optical depth: 0 below `threshold`, rising to CLOUD_MAX_OPTICAL_DEPTH one `noise_std` above it."""
    return CLOUD_MAX_OPTICAL_DEPTH * np.clip((noise - threshold) / noise_std, 0.0, 1.0)


def base_luminance_kcd(tau: np.ndarray, sun_elevation_rad: float) -> np.ndarray:
    """Luminance [kcd/m^2] of the light a cloud of optical depth `tau` scatters down through its base
    (two-stream diffuse transmittance less the unscattered part, spread evenly, E / pi)."""
    diffuse = 1.0 / (1.0 + 0.75 * (1.0 - CLOUD_ASYMMETRY_G) * tau) - np.exp(-tau)
    illuminance_lx = DIRECT_NORMAL_ILLUMINANCE_LX * max(np.sin(sun_elevation_rad), 0.0)
    return np.maximum(diffuse, 0.0) * illuminance_lx / np.pi / 1000.0


def cloudy_sky_linear(clear_rgb_kcd: np.ndarray, directions: np.ndarray, solid_angles_sr: np.ndarray,
                      sun_elevation_rad: float, layer: CloudLayer) -> np.ndarray:
    """(6 * texels, texels, 3) linear RGB [kcd/m^2 in luminance] of the clear sky `clear_rgb_kcd` (same
    shape, Preetham's luminance unit) with the clouds of `layer` over it, for the skybox texels' `directions`
    ((6 * texels, texels, 3) unit, world frame) and `solid_angles_sr` ((6 * texels, texels))."""
    x_m, y_m, range_m = layer_points_m(directions, layer.base_m)
    noise = cloud_noise(x_m, y_m, layer.rng, texel_footprint_m(directions, solid_angles_sr, layer.base_m))
    weights = solid_angles_sr * (directions[..., 2] > 0)
    threshold = cover_threshold(noise, weights, layer.oktas)
    tau = np.where(directions[..., 2] > 0, optical_depth(noise, threshold, float(noise[weights > 0].std())), 0.0)
    through = np.exp(-tau)[..., None]
    cloudy = clear_rgb_kcd * through + base_luminance_kcd(tau, sun_elevation_rad)[..., None]
    contrast = np.exp(-_KOSCHMIEDER * range_m / layer.visibility_m)[..., None]  # 0 where the layer is never met
    return clear_rgb_kcd + contrast * (cloudy - clear_rgb_kcd)
