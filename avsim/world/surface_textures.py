"""Procedural surface textures at the scale a camera resolves (`scenario.materials = "textured"`).

With the default flat materials every surface is one colour, so a detector sees uniform grass,
uniform asphalt and facades as large checkers. Real surfaces carry texture down to the scale a camera
resolves: at the default f = 896 px a pixel covers 1.1 cm at 10 m and 5.6 cm at 50 m. Each texture
here is drawn from a fixed seed with numpy and OpenCV (no network is involved in choosing anything),
with its texels a few millimetres to centimetres across, and repeated over the surface:

- asphalt: dark binder with fine grain and scattered light aggregate (stones of 0.5-1.5 cm);
- grass and fields: blade-tip speckle, clumps and patches of lighter and darker green or straw;
- leaves: overlapping leaf-sized blobs of several greens on a dark, shadowed interior (the gaps
  between leaves read dark, as in a real crown seen from outside; the crown stays opaque);
- concrete (kerb, sidewalk, plaza): grain with slab joints every 1.5 m;
- facades: one storey by one bay (3.5 m x 2.5 m) of wall with grain, a window with a frame, a
  mullion and a transom, and a sill, repeated over the building.

Mean colours are the flat materials' own (`avsim.world.props`), so a texture changes detail, not
the scene's overall colour. MuJoCo mip-maps the textures, so far surfaces average them as a camera would.

Worn road paint (`scenario.road_paint = "worn"`, with either materials) is drawn here too: unlike the
textures above it does change the mean colour, since a worn marking shows the asphalt through it.
"""

from __future__ import annotations

import cv2
import numpy as np

TEXTURE_SEED = 20251125  # fixed: every scene gets the same textures
TEXELS = 256
# Metres covered by one repeat of each kind of texture.
GROUND_REPEAT_M = 2.0
CONCRETE_REPEAT_M = 3.0
CONCRETE = ("kerb", "sidewalk", "plaza")
FACADE_STOREY_M, FACADE_BAY_M = 3.5, 2.5


def _to_uint8(rgb01: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(rgb01 * 255), 0, 255).astype(np.uint8)


def _blur_tiling(image: np.ndarray, sigma_x: float, sigma_y: float) -> np.ndarray:
    """Gaussian blur of a texture that repeats: padded by wrapping (OpenCV's blur has no wrap border)."""
    pad = int(np.ceil(4 * max(sigma_x, sigma_y)))
    padded = np.pad(image, ((pad, pad), (pad, pad)), mode="wrap")
    return cv2.GaussianBlur(padded, (0, 0), sigmaX=sigma_x, sigmaY=sigma_y)[pad:-pad, pad:-pad]


def _grain(rng: np.random.Generator, sigma_texels: float, size: int = TEXELS) -> np.ndarray:
    """(size, size) zero-mean, unit-std noise, smoothed to features about `sigma_texels` across, tiling."""
    noise = rng.standard_normal((size, size)).astype(np.float32)
    if sigma_texels > 0:
        noise = _blur_tiling(noise, sigma_texels, sigma_texels)
    return (noise - noise.mean()) / max(float(noise.std()), 1e-6)


def _albedo(mean_rgb: tuple[float, float, float], relative: np.ndarray) -> np.ndarray:
    """The flat colour times (1 + relative variation), (H, W) or (H, W, 3), rescaled to keep the flat
    colour as the mean."""
    relative = relative if relative.ndim == 3 else relative[..., None]
    rgb = np.asarray(mean_rgb, np.float32) * (1 + relative)
    return _to_uint8(rgb * (np.asarray(mean_rgb) / np.maximum(rgb.reshape(-1, 3).mean(axis=0), 1e-6)))


def asphalt(rng: np.random.Generator, mean_rgb: tuple[float, float, float]) -> np.ndarray:
    """Binder grain plus light aggregate stones (1-2 texels, 0.8-1.6 cm); 256 texels per 2 m."""
    relative = 0.15 * _grain(rng, 0.7) + 0.08 * _grain(rng, 6.0)
    for _ in range(900):
        x, y = (int(v) for v in rng.integers(0, TEXELS, 2))
        cv2.circle(relative, (x, y), int(rng.integers(1, 3)), float(rng.uniform(0.3, 0.8)), -1, cv2.LINE_AA)
    return _albedo(mean_rgb, relative)


def vegetation(rng: np.random.Generator, mean_rgb: tuple[float, float, float]) -> np.ndarray:
    """Grass, crop or soil seen from above: blade-tip speckle (about a centimetre), clumps, and drier or
    greener patches; 256 texels per 2 m."""
    luma = 0.25 * _grain(rng, 0.6) + 0.12 * _grain(rng, 10.0)
    tint = 0.08 * _grain(rng, 20.0)  # drier (redder) against greener patches
    return _albedo(mean_rgb, np.stack([luma + tint, luma, luma - 0.5 * tint], axis=2))


def leaves(rng: np.random.Generator, mean_rgb: tuple[float, float, float]) -> np.ndarray:
    """Leaf-sized blobs (4-12 cm) of several greens over a dark, shadowed interior; 256 texels per 2 m."""
    relative = np.full((TEXELS, TEXELS, 3), -0.65, np.float32)
    for _ in range(2600):
        x, y = (int(v) for v in rng.integers(0, TEXELS, 2))
        axes = (int(rng.integers(3, 7)), int(rng.integers(2, 4)))
        shade = float(rng.uniform(-0.3, 0.6))
        hue = float(rng.uniform(-0.1, 0.1))  # yellower or bluer leaves
        cv2.ellipse(relative, (x, y), axes, float(rng.uniform(0, 180)), 0, 360, (shade + hue, shade, shade - hue), -1, cv2.LINE_AA)
    return _albedo(mean_rgb, relative)


def concrete(rng: np.random.Generator, mean_rgb: tuple[float, float, float]) -> np.ndarray:
    """Cement grain with a slab joint every 1.5 m (the texture covers 3 m: two slabs each way)."""
    relative = 0.05 * _grain(rng, 0.8) + 0.04 * _grain(rng, 12.0)
    for k in (0, TEXELS // 2):
        relative[:, k:k + 2] -= 0.25
        relative[k:k + 2, :] -= 0.25
    return _albedo(mean_rgb, relative)


# A facade's window in its bay and storey [m]: its left and right edges from the bay's left edge, its head and
# sill below the storey's top; its frame, its mullion and transom (bars), and how far the transom's centre lies
# below the head. The texture draws it (`facade`), and `avsim.world.facade_windows` builds it as geometry.
WINDOW_LEFT_M, WINDOW_RIGHT_M = 0.55, 1.95
WINDOW_HEAD_M, WINDOW_SILL_M = 0.90, 2.50
WINDOW_FRAME_M, WINDOW_BAR_M, WINDOW_TRANSOM_BELOW_HEAD_M = 0.06, 0.04, 0.45
# The glass brightens from this factor of its colour at the sill to that at the head: the sky reflected in
# the upper panes.
GLASS_GAIN_SILL, GLASS_GAIN_HEAD = 0.8, 1.15
_TEXELS_PER_M = 100


def window_frame_rgb(wall_rgb: tuple[float, float, float]) -> np.ndarray:
    """A window frame's colour on a wall of `wall_rgb` ([0, 1]): the wall's, lightened towards light grey."""
    return 0.55 * np.asarray(wall_rgb, np.float32) + 0.45 * np.asarray((0.85, 0.85, 0.83), np.float32)


def facade(rng: np.random.Generator, wall_rgb: tuple[float, float, float], glass_rgb: tuple[float, float, float],
           window: bool = True) -> np.ndarray:
    """One bay (2.5 m wide) by one storey (3.5 m tall): wall, window 1.4 x 1.6 m with a 6 cm frame,
    a mullion and a transom, a sill. Rows run top to bottom; 10 texels per 10 cm. `window` False: the wall
    alone, with the same grain (the rng is drawn the same either way)."""
    height, width = 350, 250  # 1 cm per texel
    wall = np.asarray(wall_rgb, np.float32)
    grain = 0.03 * _grain(rng, 0.8, size=max(height, width))[:height, :width]
    image = wall[None, None] * (1 + grain[..., None])
    if not window:
        return _to_uint8(image)
    frame = window_frame_rgb(wall_rgb).tolist()
    x0, x1 = round(WINDOW_LEFT_M * _TEXELS_PER_M), round(WINDOW_RIGHT_M * _TEXELS_PER_M)  # window [texels]
    y0, y1 = round(WINDOW_HEAD_M * _TEXELS_PER_M), round(WINDOW_SILL_M * _TEXELS_PER_M)
    glass = np.asarray(glass_rgb, np.float32)
    vertical = np.linspace(GLASS_GAIN_HEAD, GLASS_GAIN_SILL, y1 - y0, dtype=np.float32)[:, None, None]
    image[y0:y1, x0:x1] = glass[None, None] * vertical
    cv2.rectangle(image, (x0, y0), (x1 - 1, y1 - 1), frame, round(WINDOW_FRAME_M * _TEXELS_PER_M))
    bar = round(WINDOW_BAR_M * _TEXELS_PER_M)
    cv2.line(image, ((x0 + x1) // 2, y0), ((x0 + x1) // 2, y1 - 1), frame, bar)  # mullion
    transom = y0 + round(WINDOW_TRANSOM_BELOW_HEAD_M * _TEXELS_PER_M)
    cv2.line(image, (x0, transom), (x1 - 1, transom), frame, bar)
    cv2.rectangle(image, (x0 - 8, y1), (x1 + 7, y1 + 6), (0.8 * wall).tolist(), -1)  # sill
    return _to_uint8(image)


# Worn road paint: the share of a marking's area still covered by paint, an assumed figure for a
# marking some years old and still legible (not measured here, and not fitted to any detector).
PAINT_RETAINED_FRACTION = 0.75


def worn_paint(rng: np.random.Generator, paint_rgb: tuple[float, float, float], asphalt_rgb: np.ndarray) -> np.ndarray:
    """(TEXELS, TEXELS, 3) uint8 paint worn off in flakes of 1-5 cm and off the aggregate's tips, over
    `asphalt_rgb` ((TEXELS, TEXELS, 3) uint8, the surface it shows through); 256 texels per 2 m.

    Traffic abrades a marking first where the aggregate stands proud and then flakes it off in patches;
    PAINT_RETAINED_FRACTION of the texels keep their paint. The paint itself carries a faint grain."""
    wear = 0.75 * _grain(rng, 2.5) + 0.25 * _grain(rng, 0.6)
    painted = (wear < np.quantile(wear, PAINT_RETAINED_FRACTION)).astype(np.float32)
    # The edge of a flake covers part of a texel: soften it by a texel, keeping the retained share.
    coverage = _blur_tiling(painted, 0.5, 0.5)[..., None]
    paint = np.asarray(paint_rgb, np.float32) * (1 + 0.04 * _grain(rng, 0.8))[..., None]
    return _to_uint8(coverage * paint + (1 - coverage) * asphalt_rgb.astype(np.float32) / 255)


def ground_textures(flat_colours: dict[str, tuple[float, float, float]]) -> dict[str, np.ndarray]:
    """Texture of each ground-like flat material that has one (the rest stay flat), from TEXTURE_SEED."""
    rng = np.random.default_rng(TEXTURE_SEED)
    makers = {"asphalt": asphalt, "grass": vegetation, "field_wheat": vegetation, "field_green": vegetation,
              "soil": vegetation, "leaves": leaves, **{name: concrete for name in CONCRETE}}
    return {name: maker(rng, flat_colours[name]) for name, maker in makers.items()}


def facade_textures(facades: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]],
                    windows: bool = True) -> dict[str, np.ndarray]:
    """Facade material name -> its (350, 250, 3) uint8 texture (one bay by one storey, `facade`), from (wall RGB, glass
    RGB) in [0, 1] each, seeded from TEXTURE_SEED so every build draws the same facades; `windows` False: the
    walls alone, with the grain the windowed textures have."""
    rng = np.random.default_rng((TEXTURE_SEED, 1))
    return {name: facade(rng, wall, glass, windows) for name, (wall, glass) in facades.items()}
