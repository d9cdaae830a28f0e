"""docs/realism_sky_paint.jpg: the front camera 30-35 m before the sign in the first scene draw of Town07,
Town03 and Town10 (rows) of `avsim realism`'s frame set, under baseline, daylight_sky, hazy_sky,
worn_paint and full_scene_no_shadows (columns), at half size; other settings as columns with --columns.

    MUJOCO_GL=egl python experiments/probes/sky_paint_figure.py docs/realism_sky_paint.jpg
    MUJOCO_GL=egl python experiments/probes/sky_paint_figure.py docs/realism_clouds.jpg --columns daylight_sky,scattered_clouds,broken_clouds
"""

import argparse

import cv2
import numpy as np

from avsim.realism.frame_set import render_scene, scene_draws
from avsim.realism.settings import SETTINGS

COLUMNS = ("baseline", "daylight_sky", "hazy_sky", "worn_paint", "full_scene_no_shadows")
BIN_M = (30.0, 35.0)


def front_frame(scene, setting_name: str) -> np.ndarray:
    for frame, *_ in render_scene(scene, SETTINGS[setting_name]):
        if frame.camera == "front" and frame.dist_m is not None and BIN_M[0] <= frame.dist_m < BIN_M[1]:
            return frame.image
    raise RuntimeError(f"no front frame in {BIN_M} m")


def main(out_path: str, columns: tuple[str, ...]) -> None:
    scenes = [s for s in scene_draws(("town07", "town03", "town10"), 1, 0)]
    grid = np.vstack([np.hstack([front_frame(scene, name) for name in columns]) for scene in scenes])
    half = cv2.resize(grid, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    cv2.imwrite(out_path, cv2.cvtColor(half, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 90])


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="the JPEG to write")
    parser.add_argument("--columns", default=",".join(COLUMNS), help="comma-separated settings, one column each")
    args = parser.parse_args()
    main(args.out, tuple(args.columns.split(",")))
