"""The sky: MuJoCo's two-colour gradient (scenario.sky = "gradient", the default renders) or a clear
daylight sky that follows the scene's sun (scenario.sky = "daylight").

A clear sky is not a vertical gradient. Its luminance and colour depend on the angle to the sun as
much as on the height above the horizon: bright and white around the sun (the aureole), brighter
towards the horizon, and deepest blue about 90 degrees from the sun. "daylight" draws the skybox from
Preetham, Shirley and Smits' analytic model of the clear sky (A Practical Analytic Model for
Daylight, SIGGRAPH 1999): Perez et al.'s five-parameter distribution for the luminance Y and for
the CIE chromaticities x and y, with coefficients linear in the atmosphere's turbidity (their
Table 2), and the zenith values as functions of turbidity and the sun's zenith angle (their
Appendix A.2). The sun's disc itself is not drawn. `scenario.cloud_oktas` lays fair-weather cumulus
over it (`avsim.world.clouds`).

One correction: near the horizon the model's chromaticity y falls below the CIE daylight locus
(by 0.015 at 2 degrees up, turbidity 3), which gives the horizon a magenta cast that real skies do
not have (Zotti, Wilkie and Purgathofer, A Critical Review of the Preetham Skylight Model, 2007,
found its colours unreliable). Clear-sky chromaticities lie close to the daylight locus, which was
fitted to measured daylight (Judd, MacAdam and Wyszecki, 1964). So the sky keeps the model's x and
takes y on the daylight locus, y = -3 x^2 + 2.87 x - 0.275 (CIE 15).

Exposure is not modelled by the classic renderer, whose lights were set for the gradient sky. So
the daylight sky is scaled to the gradient sky's mean luminance over the upper hemisphere
(solid-angle weighted, in linear light): the same overall brightness, distributed and coloured as
a clear sky with this sun. Around the sun it then exceeds the 8-bit range and clips to white, as a
camera exposed for the ground does. `scenario.sky_exposure_ev` moves that level by whole or part stops,
to measure what the choice does; it moves the gradient sky's two colours the same way (MuJoCo then blends
them in display values, so a stop there is a stop at the zenith and at the nadir).

Directions are in the world frame (x along the road, z up). The skybox is a cube map stored as six
square faces one above the other; `cube_directions` gives each texel's direction in MuJoCo's
layout (checked against renders in tests/world/test_sky.py).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from avsim.config import SKIES, ScenarioConfig
from avsim.world.clouds import CLOUD_TEXELS, CloudLayer, cloud_rng, cloudy_sky_linear
from avsim.world.signs import set_texture_data

SKY_TEXTURE_NAME = "sky"
# The default sky: MuJoCo's built-in gradient from a light blue zenith to a near-white nadir, whose
# horizon is the mix of the two.
GRADIENT_ZENITH_RGB = (0.55, 0.7, 0.9)
GRADIENT_NADIR_RGB = (0.9, 0.93, 0.97)
GRADIENT_TEXELS = 256
# The gradient sky's mean luminance over the upper hemisphere, solid-angle weighted, in linear
# light (sRGB decoded, Rec. 709 weights). Computed from MuJoCo's built-in texture; a test recomputes it.
GRADIENT_MEAN_LINEAR_LUMINANCE = 0.5261
DAYLIGHT_TEXELS = 128  # a face; the sky varies over tens of degrees, and MuJoCo filters the cube map
# The sky is never darker than at the Perez function's horizon limit; cos(zenith angle) is floored
# here so that directions at and below the horizon take the horizon's value (the ground hides them).
_MIN_COS_ZENITH = 1e-3

# Preetham et al. 1999, Table 2: the Perez coefficients A..E of Y, x and y as (slope, intercept) in T.
_PEREZ_Y = ((0.1787, -1.4630), (-0.3554, 0.4275), (-0.0227, 5.3251), (0.1206, -2.5771), (-0.0670, 0.3703))
_PEREZ_X = ((-0.0193, -0.2592), (-0.0665, 0.0008), (-0.0004, 0.2125), (-0.0641, -0.8989), (-0.0033, 0.0452))
_PEREZ_YC = ((-0.0167, -0.2608), (-0.0950, 0.0092), (-0.0079, 0.2102), (-0.0441, -1.6537), (-0.0109, 0.0529))
# Appendix A.2: the zenith chromaticity is [T^2, T, 1] M [theta_s^3, theta_s^2, theta_s, 1]^T.
_ZENITH_X = np.array([[0.00166, -0.00375, 0.00209, 0.0],
                      [-0.02903, 0.06377, -0.03202, 0.00394],
                      [0.11693, -0.21196, 0.06052, 0.25886]])
_ZENITH_YC = np.array([[0.00275, -0.00610, 0.00317, 0.0],
                       [-0.04214, 0.08970, -0.04153, 0.00516],
                       [0.15346, -0.26756, 0.06670, 0.26688]])
# CIE XYZ to linear sRGB (IEC 61966-2-1, D65 white).
_XYZ_TO_LINEAR_SRGB = np.array([[3.2406, -1.5372, -0.4986],
                                [-0.9689, 1.8758, 0.0415],
                                [0.0557, -0.2040, 1.0570]])
_LUMINANCE_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])


def add_sky(spec: mujoco.MjSpec, scenario: ScenarioConfig) -> None:
    """Register the skybox texture named SKY_TEXTURE_NAME for `scenario.sky`: the built-in gradient, or
    the daylight sky of the scenario's sun (its elevation and azimuth, as `avsim.world.scene` lights
    the scene) at `scenario.sky_turbidity` (2 very clear, 3 clear, 6 hazy). Either is brightened or
    darkened by `scenario.sky_exposure_ev` stops."""
    if scenario.sky == "gradient":
        zenith, nadir = (exposed_rgb(rgb, scenario.sky_exposure_ev) for rgb in (GRADIENT_ZENITH_RGB, GRADIENT_NADIR_RGB))
        spec.add_texture(name=SKY_TEXTURE_NAME, type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                         rgb1=zenith, rgb2=nadir, width=GRADIENT_TEXELS, height=GRADIENT_TEXELS)
        return
    if scenario.sky != "daylight":
        raise ValueError(f"unknown sky {scenario.sky!r}; one of {', '.join(SKIES)}")
    sun = sun_direction(scenario.sun_elevation_deg, scenario.sun_azimuth_deg)
    texture = spec.add_texture(name=SKY_TEXTURE_NAME, type=mujoco.mjtTexture.mjTEXTURE_SKYBOX)
    clouds = CloudLayer(scenario.cloud_oktas, scenario.cloud_base_m, scenario.cloud_visibility_km * 1000.0,
                        cloud_rng(scenario.seed, scenario.layout_seed)) if scenario.cloud_oktas else None
    set_texture_data(texture, daylight_sky_texture(sun, scenario.sky_turbidity, texels=CLOUD_TEXELS if clouds else DAYLIGHT_TEXELS,
                                                   exposure_ev=scenario.sky_exposure_ev, clouds=clouds))


def exposed_rgb(rgb: tuple[float, float, float], exposure_ev: float) -> list[float]:
    """A display (sRGB) colour in [0, 1] with its linear light scaled by 2 ** `exposure_ev`, clipped to
    white; the colour itself at 0 (exactly, so that the default sky is unchanged)."""
    if exposure_ev == 0:
        return list(rgb)
    return [float(v) for v in srgb_encode(srgb_decode(np.asarray(rgb)) * 2.0 ** exposure_ev)]


def sun_direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """(3,) unit vector from the scene towards the sun, world frame (the scene's light shines along its negative)."""
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


def _face_grid(texels: int) -> tuple[np.ndarray, np.ndarray]:
    """(texels, texels) coordinates s (along a row) and t (down the face) of a cube face's texel centres, in (-1, 1)."""
    centres = (np.arange(texels) + 0.5) / texels * 2 - 1
    s, t = np.meshgrid(centres, centres)
    return s, t


def cube_directions(texels: int) -> np.ndarray:
    """(6 * texels, texels, 3) unit world direction of each texel of a MuJoCo skybox texture, faces stacked
    top to bottom in the order MuJoCo reads them (+x, -x, up, down, -y, +y), row 0 at the top of each face."""
    s, t = _face_grid(texels)
    one = np.ones_like(s)
    # OpenGL's cube-map faces (+X, -X, +Y, -Y, +Z, -Z), in its y-up frame ...
    faces = [(one, -t, -s), (-one, -t, s), (s, one, t), (s, -one, -t), (s, -t, one), (-s, -t, -one)]
    # ... which MuJoCo turns to z up: world (x, y, z) = (x_gl, -z_gl, y_gl).
    world = np.concatenate([np.stack([x, -z, y], axis=-1) for x, y, z in faces], axis=0)
    return world / np.linalg.norm(world, axis=-1, keepdims=True)


def cube_solid_angles(texels: int) -> np.ndarray:
    """(6 * texels, texels) solid angle [sr] of each texel of `cube_directions`; they sum to 4 pi."""
    s, t = _face_grid(texels)
    face = (2 / texels) ** 2 / (1 + s * s + t * t) ** 1.5
    return np.tile(face, (6, 1))


def _perez(cos_zenith: np.ndarray, gamma_rad: np.ndarray, coefficients: tuple, turbidity: float) -> np.ndarray:
    a, b, c, d, e = (slope * turbidity + intercept for slope, intercept in coefficients)
    return (1 + a * np.exp(b / cos_zenith)) * (1 + c * np.exp(d * gamma_rad) + e * np.cos(gamma_rad) ** 2)


def preetham_xyY(directions: np.ndarray, sun: np.ndarray, turbidity: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CIE chromaticities x, y and luminance Y [kcd/m^2] of the clear sky in `directions` ((..., 3) unit,
    world frame) for the sun in direction `sun` ((3,) unit) and `turbidity`. Directions at or below the
    horizon get the horizon's value."""
    theta_s = math.acos(float(np.clip(sun[2], -1.0, 1.0)))
    cos_zenith = np.maximum(directions[..., 2], _MIN_COS_ZENITH)
    gamma = np.arccos(np.clip(directions @ sun, -1.0, 1.0))  # angle to the sun

    chi = (4 / 9 - turbidity / 120) * (math.pi - 2 * theta_s)
    zenith_luminance = (4.0453 * turbidity - 4.9710) * math.tan(chi) - 0.2155 * turbidity + 2.4192
    powers_t = np.array([turbidity ** 2, turbidity, 1.0])
    powers_theta = np.array([theta_s ** 3, theta_s ** 2, theta_s, 1.0])
    zenith = {"x": powers_t @ _ZENITH_X @ powers_theta, "y": powers_t @ _ZENITH_YC @ powers_theta, "Y": zenith_luminance}
    values = {}
    for name, coefficients in (("x", _PEREZ_X), ("y", _PEREZ_YC), ("Y", _PEREZ_Y)):
        at_zenith = _perez(np.float64(1.0), np.float64(theta_s), coefficients, turbidity)
        values[name] = zenith[name] * _perez(cos_zenith, gamma, coefficients, turbidity) / at_zenith
    return values["x"], values["y"], values["Y"]


def on_daylight_locus(x: np.ndarray) -> np.ndarray:
    """The CIE daylight locus: chromaticity y of daylight whose x is `x` (CIE 15, fitted for 4000-25000 K,
    x from about 0.25 to 0.38; a little beyond at a deep blue zenith)."""
    return -3.0 * x * x + 2.87 * x - 0.275


def linear_srgb(x: np.ndarray, y: np.ndarray, luminance: np.ndarray) -> np.ndarray:
    """(..., 3) linear sRGB of chromaticities x, y and luminance Y (any unit; the result has Y's)."""
    xyz = np.stack([x * luminance / y, luminance, (1 - x - y) * luminance / y], axis=-1)
    return xyz @ _XYZ_TO_LINEAR_SRGB.T


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer function: linear light in [0, 1] (clipped) to display values in [0, 1]."""
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """The inverse of `srgb_encode`: display values in [0, 1] to linear light."""
    encoded = np.asarray(encoded, np.float64)
    return np.where(encoded <= 0.04045, encoded / 12.92, ((encoded + 0.055) / 1.055) ** 2.4)


def upper_hemisphere_mean_luminance(rgb_linear: np.ndarray, texels: int, directions: np.ndarray | None = None) -> float:
    """Solid-angle weighted mean luminance over the directions above the horizon of a skybox's
    (6 * texels, texels, 3) linear RGB; directions: its `cube_directions(texels)`, where the caller has them."""
    if directions is None:
        directions = cube_directions(texels)
    weights = cube_solid_angles(texels) * (directions[..., 2] > 0)
    return float((rgb_linear @ _LUMINANCE_WEIGHTS * weights).sum() / weights.sum())


def daylight_sky_texture(sun: np.ndarray, turbidity: float, texels: int = DAYLIGHT_TEXELS, exposure_ev: float = 0.0,
                         clouds: CloudLayer | None = None) -> np.ndarray:
    """(6 * texels, texels, 3) uint8 sRGB skybox of the clear sky for the sun in direction `sun` ((3,)
    unit, world frame), scaled to the gradient sky's mean luminance over the upper hemisphere times
    2 ** `exposure_ev` [stops]. clouds: the cumulus drawn over it
    (`avsim.world.clouds`), lit in the clear sky's unit and scaled by the clear sky's factor, so that
    the clear patches between them are the clear sky's own."""
    directions = cube_directions(texels)
    x, _, luminance = preetham_xyY(directions, sun, turbidity)
    rgb = linear_srgb(x, on_daylight_locus(x), luminance)
    # A saturated blue can fall just outside sRGB's gamut; clip it to the gamut before scaling.
    rgb = np.maximum(rgb, 0.0)
    scale = 2.0 ** exposure_ev * GRADIENT_MEAN_LINEAR_LUMINANCE / upper_hemisphere_mean_luminance(rgb, texels, directions)
    if clouds is not None:
        rgb = cloudy_sky_linear(rgb, directions, cube_solid_angles(texels), math.asin(float(np.clip(sun[2], -1.0, 1.0))), clouds)
    rgb *= scale
    return np.rint(srgb_encode(rgb) * 255).astype(np.uint8)
