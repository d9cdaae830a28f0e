"""Region-of-interest detection: the network runs on a crop, exact inside the region.

The detector is fully convolutional, so a cell's output depends only on the pixels in its
receptive field. Cropping the input changes a cell's output only if the crop's edge, with
its zero padding, comes within reach of that field. Two conditions keep the crop exact:

- the crop starts on the coarsest stride (`ALIGN_PX`), so every cell grid lines up with
  the whole frame's;
- it reaches `CONTEXT_PX` beyond the region on every side that is not an image border.

Then every cell whose centre lies in the region gets the whole-frame score and box, bit
for bit. `tests/perception/detector/test_roi.py` measures that on the shipped weights.
The crop is also a multiple of `ALIGN_PX` in size, which the network's FPN needs.
Coordinates are continuous image pixels, (x0, y0, x1, y1) end-exclusive.
"""

from __future__ import annotations

import math

# The coarsest stride in the network (its stride-32 stage feeds the FPN).
ALIGN_PX = 32
# Context beyond the region: more than the network's measured reach. Cells 104-112 px
# from a crop edge already match the whole frame; this adds a safety margin and keeps
# the crop aligned.
CONTEXT_PX = 128

Box = tuple[int, int, int, int]


def clip_region(region_px: Box, width_px: int, height_px: int) -> Box:
    """The region clipped to a W x H image; ValueError if nothing of it is left."""
    x0, y0, x1, y1 = region_px
    clipped = (max(x0, 0), max(y0, 0), min(x1, width_px), min(y1, height_px))
    if clipped[0] >= clipped[2] or clipped[1] >= clipped[3]:
        raise ValueError(f"region of interest {list(region_px)} lies outside the {width_px}x{height_px} image; "
                         "set perception.front_roi_px / side_roi_px inside it")
    return clipped


def crop_for(region_px: Box, width_px: int, height_px: int) -> Box | None:
    """The crop (x0, y0, x1, y1) [px] whose network output is exact inside `region_px`.

    The region grown by CONTEXT_PX, snapped outwards to ALIGN_PX and clipped to the image.
    None when that is not possible, i.e. when an image side that the crop must reach is
    not itself a multiple of ALIGN_PX (then the caller runs the whole frame).
    """
    x0, y0, x1, y1 = clip_region(region_px, width_px, height_px)
    cx0 = max(0, (x0 - CONTEXT_PX) // ALIGN_PX * ALIGN_PX)
    cy0 = max(0, (y0 - CONTEXT_PX) // ALIGN_PX * ALIGN_PX)
    cx1 = min(width_px, math.ceil((x1 + CONTEXT_PX) / ALIGN_PX) * ALIGN_PX)
    cy1 = min(height_px, math.ceil((y1 + CONTEXT_PX) / ALIGN_PX) * ALIGN_PX)
    if (cx1 - cx0) % ALIGN_PX or (cy1 - cy0) % ALIGN_PX:
        return None
    return cx0, cy0, cx1, cy1
