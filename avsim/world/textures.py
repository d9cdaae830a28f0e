"""Sign face textures: clean MUTCD-style faces drawn with OpenCV, and safe PNG I/O.

The makers draw a stop sign (R1-1), a yield sign (R1-2) and a speed-limit sign (R2-1)
as RGB uint8 arrays. `load_texture_png` reads a sign face a user supplies (for example
an adversarially patched stop sign) and refuses anything that is not a sane 8/16-bit
PNG with a one-line `TextureError`. `python -m avsim.world.textures` rewrites the
committed clean PNGs in the repo's top-level `textures/` folder.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from avsim.boundary import run_guarded
from avsim.errors import TextureError
from avsim.file_kinds import special_file_kind
from avsim.image_files import c_stderr_silenced
from avsim.outputs import write_bytes_atomic
from avsim.validation import OneLineArgumentParser

TEXTURE_DIR = Path(__file__).resolve().parents[2] / "textures"

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
MIN_SIDE_PX, MAX_SIDE_PX = 32, 4096

RED, WHITE, BLACK = (200, 16, 46), (255, 255, 255), (0, 0, 0)  # MUTCD red
GREY = (128, 128, 128)  # outside the sign outline; the mesh never samples it


@dataclass(frozen=True)
class Palette:
    """The colours a sign face is drawn in, 8-bit RGB each: the design colours by default
    (`avsim.world.sign_materials` has the sheeting's)."""

    red: tuple[int, int, int] = RED
    white: tuple[int, int, int] = WHITE
    black: tuple[int, int, int] = BLACK


DESIGN_PALETTE = Palette()

_FONT = cv2.FONT_HERSHEY_DUPLEX
# fillPoly takes fixed-point vertices; 4 fractional bits keep edges sub-pixel exact.
_SHIFT = 4


def _fill(img: np.ndarray, pts: np.ndarray, color: tuple[int, int, int]) -> None:
    fixed = np.round(np.asarray(pts, np.float64) * (1 << _SHIFT)).astype(np.int32)
    cv2.fillPoly(img, [fixed], color, cv2.LINE_AA, _SHIFT)


def _octagon(cx: float, cy: float, flat_to_flat: float) -> np.ndarray:
    """Regular octagon with horizontal/vertical flats, vertices clockwise from top-left."""
    a = flat_to_flat / 2.0
    b = a * (np.sqrt(2.0) - 1.0)  # half a side length
    offsets = [(-b, -a), (b, -a), (a, -b), (a, b), (b, a), (-b, a), (-a, b), (-a, -b)]
    return np.array([(cx + dx, cy + dy) for dx, dy in offsets])


def _glyph(ch: str, scale: float, thick: int) -> tuple[np.ndarray, int, int, int]:
    """Tight ink mask of one character, its (left, top) offset from the pen, and its advance."""
    (adv, h), base = cv2.getTextSize(ch, _FONT, scale, thick)
    pad = thick + 2
    mask = np.zeros((h + base + 2 * pad, adv + 2 * pad), np.uint8)
    cv2.putText(mask, ch, (pad, pad + h), _FONT, scale, 255, thick, cv2.LINE_AA)
    ys, xs = np.nonzero(mask)
    if xs.size == 0:
        return np.zeros((1, 1), np.uint8), 0, 0, adv
    ink = mask[ys.min():ys.max() + 1, xs.min():xs.max() + 1]
    return ink, xs.min() - pad, ys.min() - pad - h, adv


def _ink(text: str, scale: float, thick: int) -> np.ndarray:
    """Tight ink mask of a line of text, laid out glyph by glyph at the font's advances."""
    placed, pen = [], 0
    for ch in text:
        ink, left, top, adv = _glyph(ch, scale, thick)
        if ch == "0":
            # OpenCV 5's Hershey fonts draw a slashed zero; signs use an open one, so draw
            # the letter O squeezed into the zero's ink box.
            o_ink = _glyph("O", scale, thick)[0]
            ink = cv2.resize(o_ink, ink.shape[::-1], interpolation=cv2.INTER_AREA)
        placed.append((ink, pen + left, top))
        pen += adv
    x0, y0 = min(x for _, x, _ in placed), min(y for _, _, y in placed)
    x1 = max(x + g.shape[1] for g, x, _ in placed)
    out = np.zeros((max(y + g.shape[0] for g, _, y in placed) - y0, x1 - x0), np.uint8)
    for g, x, y in placed:
        view = out[y - y0:y - y0 + g.shape[0], x - x0:x - x0 + g.shape[1]]
        np.maximum(view, g, out=view)
    return out


def _text(img: np.ndarray, text: str, color: tuple[int, int, int], center: tuple[float, float],
          height: float, width: float | None = None, max_width: float | None = None,
          weight: float = 0.14) -> None:
    """Draw `text` with its ink box `height` tall, centred on `center`, anti-aliased.

    `width` fixes the ink width (letters are stretched to it), else the font's own
    proportions are kept; either way it is narrowed to `max_width` if given. The font
    scale comes from cv2.getTextSize so glyphs are drawn near their final size before
    the exact resize. `weight` is the stroke thickness as a fraction of the cap height
    (bold is ~0.14).
    """
    (_, h1), _ = cv2.getTextSize(text, _FONT, 1.0, 1)
    scale = height / h1
    thick = max(1, round(weight * height))
    ink = _ink(text, scale, thick)
    if width is None:
        width = ink.shape[1] * height / ink.shape[0]
    if max_width is not None:
        width = min(width, max_width)
    out_w, out_h = max(1, round(width)), max(1, round(height))
    ink = cv2.resize(ink, (out_w, out_h), interpolation=cv2.INTER_AREA)
    x0, y0 = round(center[0] - out_w / 2), round(center[1] - out_h / 2)
    region = img[y0:y0 + out_h, x0:x0 + out_w]
    alpha = (ink.astype(np.float32) / 255.0)[..., None]
    region[:] = np.round(region * (1.0 - alpha) + np.float32(color) * alpha).astype(np.uint8)


def make_stop_sign(size_px: int = 512, palette: Palette = DESIGN_PALETTE) -> np.ndarray:
    """Stop sign face (MUTCD R1-1) as RGB uint8, shape (size_px, size_px, 3).

    The image is the sign's bounding square: the octagon's four flats touch the four
    image edges, so image width = flat-to-flat width of the sign (0.75 m for a 30 in
    sign), x right and y down as seen from the front. Pixels outside the octagon are
    grey (128) and are never mapped onto the mesh.
    """
    s = float(size_px)
    img = np.full((size_px, size_px, 3), GREY, np.uint8)
    c, rim, band = s / 2.0, 0.015 * s, 0.03 * s  # red rim, then white border band, as on R1-1
    _fill(img, _octagon(c, c, s), palette.red)
    _fill(img, _octagon(c, c, s - 2 * rim), palette.white)
    _fill(img, _octagon(c, c, s - 2 * (rim + band)), palette.red)
    # Real legend letters are a third of the sign height; Hershey glyphs are squatter.
    _text(img, "STOP", palette.white, (c, c), height=0.27 * s, width=0.70 * s, weight=0.16)
    return img


def make_yield_sign(size_px: int = 512, palette: Palette = DESIGN_PALETTE) -> np.ndarray:
    """Yield sign face (MUTCD R1-2) as RGB uint8, shape (size_px, size_px, 3).

    The downward-pointing equilateral triangle has its top edge along the image's top
    edge (full width = sign side, 0.9 m for a 36 in sign) and its apex at the bottom
    centre, y = size_px * sqrt(3)/2. Everything else is grey (128), never mapped.
    """
    s = float(size_px)
    img = np.full((size_px, size_px, 3), GREY, np.uint8)
    tri_h = s * np.sqrt(3.0) / 2.0
    outer = np.array([(0.0, 0.0), (s, 0.0), (s / 2.0, tri_h)])
    _fill(img, outer, palette.red)
    incentre, inradius = np.array([s / 2.0, tri_h / 3.0]), tri_h / 3.0
    band = 0.155 * s  # red band ~5.5 in wide on a 36 in side
    inner = incentre + (outer - incentre) * (inradius - band) / inradius
    _fill(img, inner, palette.white)
    # Put the legend where the white triangle is still wide: its top third.
    top, side, text_h = inner[0, 1], inner[1, 0] - inner[0, 0], 0.085 * s
    inner_h = side * np.sqrt(3.0) / 2.0
    text_cy = top + 0.08 * inner_h + text_h / 2.0
    width_at_bottom = side * (1.0 - (text_cy + text_h / 2.0 - top) / inner_h)
    _text(img, "YIELD", palette.red, (s / 2.0, text_cy), height=text_h, max_width=0.85 * width_at_bottom)
    return img


def _rounded_rect(x0: float, y0: float, x1: float, y1: float, r: float) -> np.ndarray:
    corners = [(x1 - r, y0 + r, -90), (x1 - r, y1 - r, 0), (x0 + r, y1 - r, 90),
               (x0 + r, y0 + r, 180)]
    pts = []
    for cx, cy, start in corners:
        angles = np.deg2rad(np.linspace(start, start + 90, 12))
        pts.extend(zip(cx + r * np.cos(angles), cy + r * np.sin(angles)))
    return np.array(pts)


def make_speed_limit_sign(limit_kmh: int = 50, width_px: int = 400, height_px: int = 500,
                          palette: Palette = DESIGN_PALETTE) -> np.ndarray:
    """Speed-limit sign face (MUTCD R2-1) as RGB uint8, shape (height_px, width_px, 3).

    The whole image is the sign face, 0.61 m wide by 0.76 m tall (aspect 4:5), x right
    and y down as seen from the front: white, a thin black border inset from the edge,
    "SPEED" / "LIMIT" in the top part and `limit_kmh` large below.
    """
    w, h = float(width_px), float(height_px)
    img = np.full((height_px, width_px, 3), palette.white, np.uint8)
    inset, border = 0.02 * w, 0.025 * w
    _fill(img, _rounded_rect(inset, inset, w - inset, h - inset, 0.06 * w), palette.black)
    i = inset + border
    _fill(img, _rounded_rect(i, i, w - i, h - i, 0.06 * w - border), palette.white)
    for word, cy in (("SPEED", 0.17), ("LIMIT", 0.35)):
        _text(img, word, palette.black, (w / 2, cy * h), height=0.12 * h, max_width=0.8 * w)
    _text(img, str(int(limit_kmh)), palette.black, (w / 2, 0.68 * h), height=0.34 * h, max_width=0.8 * w,
          width=0.3 * w * len(str(int(limit_kmh))), weight=0.09)
    return img


def hexagon_outline(width: float) -> np.ndarray:
    """A regular hexagon `width` across its corners, corners left and right, flats on top and bottom:
    (6, 2) points (x right, y down) centred on the origin; its height is width * sqrt(3) / 2."""
    angles = np.deg2rad(np.arange(0, 360, 60))
    return np.column_stack([width / 2 * np.cos(angles), width / 2 * np.sin(angles)])


def make_disc_advert(word: str = "CAFE", size_px: int = 512) -> np.ndarray:
    """A red round roadside advert with a white ring and a white word: red and white like a stop
    sign, of about its size, and no traffic sign at all. RGB uint8, (size_px, size_px, 3), the
    disc touching the image edges; grey (128) outside it."""
    s = float(size_px)
    img = np.full((size_px, size_px, 3), GREY, np.uint8)
    angles = np.deg2rad(np.linspace(0, 360, 96, endpoint=False))
    ring = np.column_stack([np.cos(angles), np.sin(angles)])
    for radius, colour in ((s / 2, RED), (0.46 * s, WHITE), (0.43 * s, RED)):
        _fill(img, s / 2 + radius * ring, colour)
    _text(img, word, WHITE, (s / 2, s / 2), height=0.25 * s, max_width=0.66 * s, weight=0.16)
    return img


def make_hexagon_advert(word: str = "PIZZA", width_px: int = 512) -> np.ndarray:
    """A red hexagonal shop board with a white border and a white word (corners left and right):
    RGB uint8, (round(width_px * sqrt(3) / 2), width_px, 3), the hexagon touching the image edges."""
    w = float(width_px)
    h = round(w * np.sqrt(3.0) / 2.0)
    img = np.full((h, width_px, 3), GREY, np.uint8)
    centre = np.array([w / 2, h / 2])
    for scale, colour in ((1.0, RED), (0.93, WHITE), (0.88, RED)):
        _fill(img, centre + hexagon_outline(w * scale), colour)
    _text(img, word, WHITE, (w / 2, h / 2), height=0.22 * h, max_width=0.62 * w, weight=0.16)
    return img


# Each takes a `palette=` keyword (the design colours by default).
SIGN_TEXTURE_MAKERS: dict[str, Callable[..., np.ndarray]] = {
    "stop_sign": make_stop_sign, "yield": make_yield_sign, "speed_limit": make_speed_limit_sign}
CLEAN_TEXTURE_FILES: dict[str, str] = {
    "stop_sign": "stop_sign.png", "yield": "yield.png", "speed_limit": "speed_limit.png"}

_PNG_HINT = "give a PNG image (colour or grey, with or without alpha, 8 or 16 bits a sample)"


def load_texture_png(path: str | os.PathLike, expected_aspect: float | None = None) -> np.ndarray:
    """Read a PNG sign face; return RGB uint8, shape (H, W, 3).

    Alpha is dropped, grey is expanded to RGB and 16-bit samples are scaled to 8 bit.
    `expected_aspect` is width / height; it must match within 2 %. Raises TextureError
    (one line, naming the path and the fix) for a missing, non-PNG, corrupt, too small
    (< 32 px) or too large (> 4096 px) file, or a wrong aspect ratio.
    """
    p = Path(path)
    if p.is_dir():
        raise TextureError(f"texture {p} is a folder; {_PNG_HINT}, e.g. a file in it")
    if kind := special_file_kind(p):  # a device would be read until memory runs out, a pipe blocks
        raise TextureError(f"texture {p} is {kind}, not a regular file; {_PNG_HINT}")
    if not p.is_file():
        raise TextureError(f"texture {p} does not exist; check the path or run "
                           f"`python -m avsim.world.textures` to regenerate the clean ones")
    data = p.read_bytes()
    if not data.startswith(PNG_SIGNATURE):
        raise TextureError(f"texture {p} is not a PNG file; {_PNG_HINT}")
    # Read the size from IHDR first so a huge image is refused before it is inflated.
    if len(data) < 24 or data[12:16] != b"IHDR":
        raise TextureError(f"texture {p} is a corrupt PNG (no IHDR); re-export it, {_PNG_HINT}")
    w, h = struct.unpack(">II", data[16:24])
    if min(w, h) < MIN_SIDE_PX or max(w, h) > MAX_SIDE_PX:
        raise TextureError(f"texture {p} is {w}x{h} px; give a PNG between {MIN_SIDE_PX} and "
                           f"{MAX_SIDE_PX} px on each side")
    # libpng may hand back a partial image for a truncated file; a complete PNG ends in IEND.
    if b"IEND" not in data[-12:]:
        raise TextureError(f"texture {p} is a truncated PNG; re-export it, {_PNG_HINT}")
    with c_stderr_silenced():  # libpng's own warnings would make a one-line refusal several
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise TextureError(f"texture {p} is a corrupt PNG that cannot be decoded; re-export it, "
                           f"{_PNG_HINT}")
    if img.dtype == np.uint16:
        img = np.rint(img / 257.0).astype(np.uint8)
    elif img.dtype != np.uint8:
        raise TextureError(f"texture {p} has {img.dtype} samples; {_PNG_HINT}")
    img = img.reshape(img.shape[0], img.shape[1], -1)
    if img.shape[2] == 2:  # grey + alpha
        img = img[..., :1]
    codes = {1: cv2.COLOR_GRAY2RGB, 3: cv2.COLOR_BGR2RGB, 4: cv2.COLOR_BGRA2RGB}
    rgb = cv2.cvtColor(img, codes[img.shape[2]])
    if expected_aspect is not None:
        actual = rgb.shape[1] / rgb.shape[0]
        if abs(actual - expected_aspect) > 0.02 * expected_aspect:
            raise TextureError(f"texture {p} has shape {rgb.shape[1]}x{rgb.shape[0]} (width:height "
                               f"{actual:.3f}); give a PNG with width:height {expected_aspect:.3f}")
    return np.ascontiguousarray(rgb)


def save_texture_png(path: str | os.PathLike, rgb: np.ndarray) -> None:
    """Write an RGB uint8 (H, W, 3) array as a PNG, atomically.

    The bytes go to a temporary file in the same folder, which then replaces `path`,
    so a reader never sees a half-written texture.
    """
    p = Path(path)
    fix = "give an RGB uint8 array of shape (H, W, 3)"
    is_rgb = isinstance(rgb, np.ndarray) and rgb.ndim == 3 and rgb.shape[2] == 3
    if not is_rgb or rgb.dtype != np.uint8:
        desc = f"{rgb.dtype} {rgb.shape}" if isinstance(rgb, np.ndarray) else type(rgb).__name__
        raise TextureError(f"cannot save texture {p} from a {desc} array; {fix}")
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise TextureError(f"cannot encode texture {p} as PNG; {fix}")
    write_bytes_atomic(p, buf.tobytes())


def write_clean_textures(out_dir: Path = TEXTURE_DIR) -> list[Path]:
    """Render every maker in SIGN_TEXTURE_MAKERS and write it as out_dir/<kind file>.png."""
    paths = [Path(out_dir) / CLEAN_TEXTURE_FILES[kind] for kind in SIGN_TEXTURE_MAKERS]
    for path, make in zip(paths, SIGN_TEXTURE_MAKERS.values()):
        save_texture_png(path, make())
    return paths


def main(argv: list[str] | None = None) -> int:
    """`python -m avsim.world.textures`: draw the clean sign faces into textures/; returns the exit status.
    It takes no arguments, so a mistyped one is refused before any file is written."""
    prog = "python -m avsim.world.textures"
    OneLineArgumentParser(prog=prog, description=f"Draw the clean sign faces into {TEXTURE_DIR}.").parse_args(argv)
    return run_guarded(lambda: print("\n".join(str(path) for path in write_clean_textures())), prog=prog)


if __name__ == "__main__":
    raise SystemExit(main())
