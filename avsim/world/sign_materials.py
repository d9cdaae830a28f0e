"""Sign materials as the standards specify them (`scenario.sign_materials = "sheeting"`).

**Sheeting colours.** A US sign face is retroreflective sheeting whose daytime colour is bounded by
the chromaticity boxes and luminance factors of 23 CFR 655 Subpart F, Appendix, Table 1 (CIE 1931 2°
observer, illuminant D65, 45/0 geometry), the same boxes as ASTM D4956. Each colour here is the mean
of its box's four corners at a stated luminance factor Y, converted to sRGB (IEC 61966-2-1): the
scene's flat colours are sRGB-encoded reflectances too. Red's box reaches beyond the sRGB gamut at
its long-wave corner; its mean lies just outside it (green slightly negative in linear light), and is
clipped to the gamut's edge. The default faces instead use the design colours of
`avsim.world.textures` (red (200, 16, 46), paper white 255).

**Metal.** A sign blank is 0.080 in (2 mm) aluminium sheet, so seen from behind or from the side a
sign is bare mill-finish aluminium; the post is galvanised (zinc-coated) steel. MuJoCo's classic
renderer has no metallic BRDF: each is its albedo plus a specular highlight (`specular`,
`shininess` in MuJoCo's [0, 1] units); the values are stated assumptions for a bright, smooth
aluminium and a duller, weathered zinc, not measured reflectances and not searched for a score.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import mujoco
import numpy as np

from avsim.world.textures import SIGN_TEXTURE_MAKERS, Palette

# Daytime chromaticity boxes (x, y corners), 23 CFR 655 Subpart F Appendix Table 1.
RED_BOX_XY = ((0.648, 0.351), (0.735, 0.265), (0.629, 0.281), (0.565, 0.346))
WHITE_BOX_XY = ((0.303, 0.300), (0.368, 0.366), (0.340, 0.393), (0.274, 0.329))
# Luminance factors Y (fraction of a perfect white diffuser). Red: the middle of Table 1A's 2.5-15 %.
# White: Table 1A (and ASTM D4956) set only a minimum, 27 %; new sheeting measures above it, and
# 40 % is an assumed value for it.
RED_LUMINANCE_FACTOR = 0.0875
WHITE_LUMINANCE_FACTOR = 0.40
# A 2 mm (0.080 in) aluminium sign blank behind the sheeting.
BLANK_THICKNESS_M = 0.002
# Albedo (sRGB, [0, 1]) and MuJoCo specular, shininess: stated assumptions (see the module docstring).
METALS = {
    "sign_aluminium": ((0.75, 0.76, 0.78), 0.8, 0.6),
    "sign_galvanised": ((0.58, 0.59, 0.60), 0.5, 0.3),
}
ALUMINIUM, GALVANISED = METALS


def srgb_from_xyY(x: float, y: float, luminance_factor: float) -> tuple[int, int, int]:
    """The 8-bit sRGB colour (D65 white) of CIE 1931 chromaticity (x, y) at luminance factor Y in [0, 1];
    out-of-gamut colours are clipped to the gamut's edge in linear light."""
    xyz = np.float32([[[x * luminance_factor / y, luminance_factor, (1 - x - y) * luminance_factor / y]]])
    linear = np.clip(cv2.cvtColor(xyz, cv2.COLOR_XYZ2RGB)[0, 0], 0.0, 1.0)  # linear sRGB: Rec. 709 primaries, D65
    encoded = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)
    return tuple(int(v) for v in np.rint(encoded * 255))


def box_mean(box_xy: tuple[tuple[float, float], ...]) -> tuple[float, float]:
    """The mean (x, y) of a chromaticity box's corners."""
    return tuple(float(v) for v in np.mean(np.asarray(box_xy), axis=0))


# The speed-limit sign's black legend stays black: it is ink printed on the sheeting.
SHEETING_PALETTE = Palette(red=srgb_from_xyY(*box_mean(RED_BOX_XY), RED_LUMINANCE_FACTOR),
                           white=srgb_from_xyY(*box_mean(WHITE_BOX_XY), WHITE_LUMINANCE_FACTOR))


@lru_cache(maxsize=None)
def sheeting_face(kind: str) -> np.ndarray:
    """The clean face of sign `kind` drawn in the sheeting colours: RGB uint8 (H, W, 3), read-only
    (shared between scenes)."""
    face = SIGN_TEXTURE_MAKERS[kind](palette=SHEETING_PALETTE)
    face.flags.writeable = False
    return face


def add_metal_materials(spec: mujoco.MjSpec) -> None:
    """Register the blank's aluminium and the post's galvanised steel (`METALS`) in `spec`."""
    for name, (rgb, specular, shininess) in METALS.items():
        spec.add_material(name=name, rgba=[*rgb, 1.0], specular=specular, shininess=shininess)
