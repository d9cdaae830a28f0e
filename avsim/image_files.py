"""Image files from users, read defensively: size from the header before any pixel is decoded.

A PNG's header can declare 100,000 x 100,000 pixels in a few hundred bytes (a decompression
bomb); OpenCV would then stop on its own pixel-limit assertion, or try to allocate 30 GB.
`check_image_file` reads the width and height from the PNG or JPEG header (and BMP, GIF,
WebP) and refuses more than `MAX_IMAGE_PIXELS` before decoding, and refuses the formats whose header
it does not read (TIFF, PNM, ...), a file larger than any such image, and a device or a pipe; `decode_image` decodes with
libpng's and libjpeg's warnings kept off the terminal (they print to the C stderr, one
refusal would otherwise be several lines) and turns every failure into one line.
"""

from __future__ import annotations

import contextlib
import os
import struct
import sys
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from avsim.errors import AvsimError
from avsim.file_kinds import special_file_kind

# 50 megapixels (an 8K frame is 33): far above any camera frame avsim or a dataset uses, and
# about 150 MB of RGB, so a decode cannot exhaust memory.
MAX_IMAGE_PIXELS = 50_000_000
# The most bytes an image file may hold: an uncompressed 50-megapixel RGB BMP, with room for its header.
MAX_IMAGE_BYTES = 3 * MAX_IMAGE_PIXELS + 1_000_000


class ImageError(AvsimError):
    """An image file that does not exist, is a folder, is too large, or cannot be decoded."""


def header_size_px(data: bytes) -> tuple[int, int] | None:
    """(width, height) from the first bytes of a PNG, JPEG, GIF, BMP or WebP file; None when
    the format is not one of these or its header is cut short."""
    if data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) >= 24 and data[12:16] == b"IHDR":
        return struct.unpack(">II", data[16:24])
    if data[:6] in (b"GIF87a", b"GIF89a") and len(data) >= 10:
        return struct.unpack("<HH", data[6:10])
    if data.startswith(b"BM") and len(data) >= 26:
        width, height = struct.unpack("<ii", data[18:26])
        return abs(width), abs(height)
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP" and len(data) >= 30:
        chunk = data[12:16]
        if chunk == b"VP8 ":
            width, height = struct.unpack("<HH", data[26:30])
            return width & 0x3FFF, height & 0x3FFF
        if chunk == b"VP8L":
            bits = int.from_bytes(data[21:25], "little")
            return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
        if chunk == b"VP8X":
            return int.from_bytes(data[24:27], "little") + 1, int.from_bytes(data[27:30], "little") + 1
    if data.startswith(b"\xff\xd8"):
        return _jpeg_size(data)
    return None


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    """The frame size in a JPEG's first start-of-frame marker."""
    i = 2
    while i + 9 < len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:  # no length field
            i += 2
            continue
        length = struct.unpack(">H", data[i + 2:i + 4])[0]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            height, width = struct.unpack(">HH", data[i + 5:i + 9])
            return width, height
        i += 2 + length
    return None


def check_image_file(path: Path, what: str = "image") -> bytes:
    """The bytes of image file `path`, after refusing (one line, ImageError) a missing path, a
    folder, an unreadable file, or a header that declares more than MAX_IMAGE_PIXELS."""
    if path.is_dir():
        raise ImageError(f"{what} {path} is a folder; pass image files (PNG, JPEG, BMP, GIF or WebP), e.g. {path}/*.png")
    if not path.exists():
        raise ImageError(f"{what} {path} does not exist; pass image files (PNG, JPEG, BMP, GIF or WebP)")
    if kind := special_file_kind(path):  # a device would be read until memory runs out, a pipe with no writer blocks
        raise ImageError(f"{what} {path} is {kind}, not a regular file; pass image files (PNG, JPEG, BMP, GIF or WebP)")
    try:
        with path.open("rb") as file:
            head = file.read(65536)
            # Only the header is read before the size is known (a sparse 2 GB file would be read whole).
            size_bytes = os.fstat(file.fileno()).st_size
            if size_bytes > MAX_IMAGE_BYTES:
                raise ImageError(f"{what} {path} is {size_bytes / 1e6:.0f} MB, more than the "
                                 f"{MAX_IMAGE_BYTES // 1_000_000} MB of any image avsim reads; pass a smaller image")
            data = head + file.read()
    except OSError as exc:
        raise ImageError(f"cannot read {what} {path} ({exc.strerror})") from None
    size = header_size_px(head)
    if size is None:
        # Other formats OpenCV decodes (TIFF, PNM, ...) declare their size where this reader does not look, so a
        # small file could still decode to tens of gigabytes.
        raise ImageError(f"{what} {path} is not PNG, JPEG, BMP, GIF or WebP (or its header is cut short), the formats "
                         "whose size avsim checks before decoding; convert it to PNG")
    if size[0] * size[1] > MAX_IMAGE_PIXELS:
        raise ImageError(f"{what} {path} declares {size[0]}x{size[1]} px, more than {MAX_IMAGE_PIXELS // 1_000_000} "
                         f"megapixels; pass a smaller image")
    return data


def decode_image(data: bytes, path: Path, flags: int = cv2.IMREAD_COLOR, what: str = "image") -> np.ndarray:
    """`cv2.imdecode` of `data`, with the C libraries' warnings silenced; ImageError when it fails."""
    try:
        with c_stderr_silenced():
            image = cv2.imdecode(np.frombuffer(data, np.uint8), flags)
    except cv2.error as exc:
        raise ImageError(f"{what} {path} cannot be decoded ({str(exc).strip().splitlines()[-1]})") from None
    if image is None:
        raise ImageError(f"{what} {path} cannot be decoded as an image (corrupt, truncated or not an image); "
                         "pass a PNG, JPEG, BMP, GIF or WebP file")
    return image


@contextlib.contextmanager
def c_stderr_silenced() -> Iterator[None]:
    """File descriptor 2 pointed at /dev/null for the block (libpng's "Read Error" and the like)."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no fd 2 (a service without a terminal): nothing to silence
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
