"""Fair-weather cumulus in the daylight sky (scenario.cloud_oktas > 0 with scenario.sky = "daylight").

A sign on a rural road is often seen against a sky with clouds in it, not against a clear one. This
module lays a seeded field of clouds over the clear daylight sky of `avsim.world.sky`, at a cover
stated in oktas (eighths of the sky, as weather observers report it), lit from the physics of a
cloud seen from below rather than coloured by hand.

**Where the clouds are.** One flat layer at `scenario.cloud_base_m` above the ground (1500 m by
default, where fair-weather cumulus have their bases over land in summer: 1-2 km; a few hundred metres
in humid sea air, 3 km and more over deserts). A view direction d (world frame, z up) meets
it at the horizontal point d_xy * h / d_z, so clouds crowd together towards the horizon, as a
camera sees them. The layer's optical depth is fractal noise of that point (`CloudField`): five
octaves, the largest wavelength CLOUD_WAVELENGTH_M (cumulus humilis and mediocris are 0.5-2 km
across), each octave half the wavelength and half the amplitude of the one before. The cloud edge
is the noise level above which the covered fraction of the sky dome, solid-angle weighted as an
observer counts oktas, is oktas / 8; the optical depth rises from 0 at the edge to
CLOUD_MAX_OPTICAL_DEPTH one noise standard deviation inside it. Near the horizon one texel spans
kilometres of the layer along the line of sight, so there it shows the mean of points spread along
it rather than one point (`sample_layer`), as a camera's pixel averages the light it gathers.

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

What is not modelled, each stated in docs/realism_sky.md: the sunlit sides of towering clouds (a flat
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
SUB_SAMPLE_SPACING_M = CLOUD_WAVELENGTH_M / 8  # at most this far apart along a texel's line of sight: the first
# two octaves, which place the clouds and shape them, at four points or more a wavelength
MAX_SUB_SAMPLES = 256  # points a texel at most; only the rows within a degree of the horizon reach it
CONTRAST_FLOOR = 1e-3  # the share of a cloud's contrast below which a texel is not sub-sampled: under an 8-bit level
_REMAP_COLUMNS = 4096  # points per row of cv2.remap's maps, which refuses 32767 rows or columns or more
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


@dataclass(frozen=True)
class CloudField:
    """The layer's fractal noise, drawn once: a random shift of the layer [m] ((2,)) and one (_LATTICE, _LATTICE)
    lattice of standard normal values per octave, the first of wavelength CLOUD_WAVELENGTH_M."""

    shift_m: np.ndarray
    lattices: tuple[np.ndarray, ...]

    @classmethod
    def draw(cls, rng: np.random.Generator) -> CloudField:
        # The layer is offset by a random shift so that the camera does not always sit over a lattice node.
        shift_m = rng.uniform(0, _LATTICE * CLOUD_WAVELENGTH_M, size=2)
        lattices = tuple(rng.standard_normal((_LATTICE, _LATTICE)).astype(np.float32) for _ in range(CLOUD_OCTAVES))
        return cls(shift_m, lattices)

    def noise(self, x_m: np.ndarray, y_m: np.ndarray, spacing_m: np.ndarray | None = None) -> np.ndarray:
        """Fractal noise (x_m's shape) at layer points x_m, y_m [m]: the octaves' bicubically interpolated
        lattices (cv2.remap, wrapping at the lattice's edge), amplitudes halving.

        spacing_m: (x_m's shape) how far apart the points sample the layer [m]. An octave finer than the first
        whose wavelength is under four spacings fades out, and is gone at two (the sampling's Nyquist limit), so
        that the far clouds near the horizon do not alias into specks. The first octave stays everywhere: it
        decides where the clouds are, and `sample_layer` spaces the points so that it is sampled."""
        flat_x, flat_y = np.ravel(x_m), np.ravel(y_m)
        flat_spacing = None if spacing_m is None else np.ravel(np.broadcast_to(spacing_m, np.shape(x_m)))
        total = np.zeros(flat_x.size, np.float64)
        for octave, lattice in enumerate(self.lattices):
            wavelength_m = CLOUD_WAVELENGTH_M / 2 ** octave
            weight = np.ones(flat_x.size) if flat_spacing is None or octave == 0 else \
                np.clip(wavelength_m / (2 * flat_spacing) - 1, 0.0, 1.0)
            kept = np.flatnonzero(weight > 0)  # an octave that has faded out costs nothing
            total[kept] += 0.5 ** octave * weight[kept] * _bicubic(lattice, (flat_x[kept] + self.shift_m[0]) / wavelength_m,
                                                                     (flat_y[kept] + self.shift_m[1]) / wavelength_m)
        return total.reshape(np.shape(x_m))


def _bicubic(lattice: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(n,) values of `lattice` at (n,) lattice coordinates u (column) and v (row), bicubically interpolated and
    wrapping at its edge (cv2.remap), the points passed as rows of _REMAP_COLUMNS."""
    if u.size == 0:
        return np.zeros(0, np.float32)
    rows = -(-u.size // _REMAP_COLUMNS)
    maps = np.zeros((2, rows * _REMAP_COLUMNS), np.float32)
    maps[0, :u.size] = np.mod(u, _LATTICE)
    maps[1, :v.size] = np.mod(v, _LATTICE)
    sampled = cv2.remap(lattice, maps[0].reshape(rows, _REMAP_COLUMNS), maps[1].reshape(rows, _REMAP_COLUMNS),
                        cv2.INTER_CUBIC, borderMode=cv2.BORDER_WRAP)
    return sampled.reshape(-1)[:u.size]


def texel_footprint_m(directions: np.ndarray, solid_angles_sr: np.ndarray, base_m: float) -> np.ndarray:
    """How far along the cloud layer `base_m` [m] up one texel reaches [m], in the direction it is most stretched
    (along the line of sight): its angular size sqrt(solid angle) at the slant range h / d_z, foreshortened by
    the layer's tilt to the ray (1 / d_z again). Across the line of sight it reaches d_z times less. Infinite at
    and below the horizon."""
    up = np.maximum(directions[..., 2], 1e-9)
    return np.where(directions[..., 2] > 0, np.sqrt(solid_angles_sr) * base_m / up ** 2, np.inf)


def sub_sample_counts(footprint_m: np.ndarray) -> np.ndarray:
    """(footprint_m's shape) int: how many points `sample_layer` takes along the line of sight of a texel above the
    horizon, so that they lie at most SUB_SAMPLE_SPACING_M apart on the layer, from 1 up to MAX_SUB_SAMPLES."""
    wanted = np.ceil(np.minimum(footprint_m, MAX_SUB_SAMPLES * SUB_SAMPLE_SPACING_M) / SUB_SAMPLE_SPACING_M)
    return np.maximum(wanted, 1).astype(np.int64)


@dataclass(frozen=True)
class LayerSamples:
    """Where the skybox's texels see the cloud layer.

    `texel_noise` ((texels,), flat) is the field at each texel's own direction, its finer octaves faded at the
    texel's footprint: where the clouds are, and what their cover is counted on. The other arrays are (n,),
    one entry per point a texel shows the mean of: one point, the texel's own direction, for most texels;
    `sub_sample_counts` points spread evenly over its height in elevation near the horizon."""

    texel_noise: np.ndarray
    texel: np.ndarray  # int: flat index of the texel the point belongs to
    share: np.ndarray  # the point's share of its texel: 1 / the texel's count
    noise: np.ndarray  # the field's noise there
    range_m: np.ndarray  # the slant range [m] to the layer, inf at and below the horizon


def sample_layer(directions: np.ndarray, solid_angles_sr: np.ndarray, layer: CloudLayer, field: CloudField) -> LayerSamples:
    """Sample the cloud `layer`'s noise `field` under the texels of `directions` ((..., 3) unit, world frame) with
    `solid_angles_sr` ((...)).

    Towards the horizon one texel spans kilometres of the layer along the line of sight (`texel_footprint_m`): for a
    1500 m base more than SUB_SAMPLE_SPACING_M below about 13 deg, and more than a wavelength of the first octave
    below about 5 deg. A texel shows the mean of what its solid angle sees, so a single point there would show one
    cloud or one gap where the eye sees the average of many: bands of cloud and sky in a coarse, seeded order. Such a texel is therefore sampled at up to
    MAX_SUB_SAMPLES points spread over its height in elevation (its angular size sqrt(solid angle), within 19 %
    of its true height on a cube face), which keeps the first octave sampled at least twice a wavelength down to
    about 0.4 deg for a 1500 m base and 0.25 deg for 600 m, 100 km and more away. A texel keeps its one point
    where that suffices, and where the haze leaves under CONTRAST_FLOOR of a cloud's contrast even at the texel's
    nearest point (within 1.7 deg of the horizon for a 1500 m base in 30 km air): no cloud there changes the
    texel by an 8-bit level, however it is sampled."""
    flat_directions = directions.reshape(-1, 3)
    flat_solid_angles = solid_angles_sr.reshape(-1)
    along_m = texel_footprint_m(flat_directions, flat_solid_angles, layer.base_m)
    x_m, y_m, range_m = layer_points_m(flat_directions, layer.base_m)
    texel_noise = field.noise(x_m, y_m, along_m)

    elevation_rad = np.arcsin(np.clip(flat_directions[:, 2], -1.0, 1.0))
    height_rad = np.sqrt(flat_solid_angles)
    nearest_range_m = layer.base_m / np.sin(np.clip(elevation_rad + height_rad / 2, 1e-9, np.pi / 2))
    hazed_out = np.exp(-_KOSCHMIEDER * nearest_range_m / layer.visibility_m) < CONTRAST_FLOOR
    counts = np.where((flat_directions[:, 2] > 0) & ~hazed_out, sub_sample_counts(along_m), 1)
    spread = np.flatnonzero(counts > 1)

    # The spread texels' points: rays tilted in elevation about the texel's own, its horizontal direction kept.
    texel = np.repeat(spread, counts[spread])
    count = counts[texel]
    index_in_texel = np.arange(len(texel)) - np.repeat(np.cumsum(counts[spread]) - counts[spread], counts[spread])
    tilted_rad = elevation_rad[texel] + ((index_in_texel + 0.5) / count - 0.5) * height_rad[texel]
    horizontal = flat_directions[texel, :2] / np.linalg.norm(flat_directions[texel, :2], axis=-1, keepdims=True)
    rays = np.concatenate([horizontal * np.cos(tilted_rad)[:, None], np.sin(tilted_rad)[:, None]], axis=-1)
    point_x_m, point_y_m, point_range_m = layer_points_m(rays, layer.base_m)
    spacing_m = np.maximum(along_m[texel] / count, along_m[texel] * flat_directions[texel, 2])  # along, across the ray
    point_noise = field.noise(point_x_m, point_y_m, spacing_m)

    alone = np.flatnonzero(counts == 1)
    return LayerSamples(texel_noise=texel_noise,
                        texel=np.concatenate([alone, texel]),
                        share=np.concatenate([np.ones(len(alone)), 1.0 / count]),
                        noise=np.concatenate([texel_noise[alone], point_noise]),
                        range_m=np.concatenate([range_m[alone], point_range_m]))


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
    samples = sample_layer(directions, solid_angles_sr, layer, CloudField.draw(layer.rng))
    weights = solid_angles_sr.reshape(-1) * (directions.reshape(-1, 3)[:, 2] > 0)
    threshold = cover_threshold(samples.texel_noise, weights, layer.oktas)
    noise_std = float(samples.texel_noise[weights > 0].std())
    tau = np.where(np.isfinite(samples.range_m), optical_depth(samples.noise, threshold, noise_std), 0.0)
    clear = clear_rgb_kcd.reshape(-1, 3)
    behind = clear[samples.texel]
    cloudy = behind * np.exp(-tau)[:, None] + base_luminance_kcd(tau, sun_elevation_rad)[:, None]
    contrast = np.exp(-_KOSCHMIEDER * samples.range_m / layer.visibility_m)  # 0 where the layer is never met
    # Each texel shows the mean over its points of what the clouds change there (none where a point sees clear sky).
    change = (contrast * samples.share)[:, None] * (cloudy - behind)
    summed = np.stack([np.bincount(samples.texel, weights=change[:, channel], minlength=len(clear)) for channel in range(3)], axis=-1)
    return (clear + summed).reshape(clear_rgb_kcd.shape)
