"""docs/realism_clouds_horizon.jpg: the cloudy skybox's band 0-20 deg above the horizon, one cube face (the
+x face, columns 64-192 of 256) at 3x, for scattered_clouds (1,500 m base, 30 km visibility) and
scattered_clouds_low_clear (600 m, 80 km), rows; columns: each texel drawn from its one direction (as before
7dfa1c2, recovered by spacing the points further apart than any texel spans) and as built (the mean along its
line of sight). Scenario seed 0, the default sun.

    python experiments/probes/cloud_horizon_figure.py docs/realism_clouds_horizon.jpg
"""

import argparse

import cv2
import numpy as np

from avsim.config import ScenarioConfig, SimConfig, with_overrides
from avsim.realism.settings import SETTINGS
from avsim.world import clouds, sky

ROWS = ("scattered_clouds", "scattered_clouds_low_clear")
TOP_DEG = 20.0


def skybox(scenario: ScenarioConfig) -> np.ndarray:
    layer = clouds.CloudLayer(scenario.cloud_oktas, scenario.cloud_base_m, scenario.cloud_visibility_km * 1000.0,
                              clouds.cloud_rng(scenario.seed, scenario.layout_seed))
    sun = sky.sun_direction(scenario.sun_elevation_deg, scenario.sun_azimuth_deg)
    return sky.daylight_sky_texture(sun, scenario.sky_turbidity, clouds.CLOUD_TEXELS, scenario.sky_exposure_ev, clouds=layer)


def band(texture: np.ndarray) -> np.ndarray:
    """The +x face's rows from TOP_DEG down to the horizon, its middle half of columns, at 3x."""
    texels = clouds.CLOUD_TEXELS
    elevation = np.degrees(np.arcsin(sky.cube_directions(texels)[:texels, texels // 2, 2]))
    rows = np.flatnonzero((elevation >= 0) & (elevation <= TOP_DEG))
    crop = texture[rows[0]:rows[-1] + 1, texels // 4:3 * texels // 4]
    return cv2.resize(crop, None, fx=3, fy=3, interpolation=cv2.INTER_NEAREST)


def main(out_path: str) -> None:
    as_built_spacing_m = clouds.SUB_SAMPLE_SPACING_M
    grid = []
    for name in ROWS:
        scenario = with_overrides(SimConfig(), SETTINGS[name].config_overrides()).scenario
        clouds.SUB_SAMPLE_SPACING_M = 1e12  # one point a texel: its own direction
        one_point = band(skybox(scenario))
        clouds.SUB_SAMPLE_SPACING_M = as_built_spacing_m
        mean = band(skybox(scenario))
        gap = np.full((one_point.shape[0], 6, 3), 255, np.uint8)
        grid.append(np.hstack([one_point, gap, mean]))
        grid.append(np.full((6, grid[-1].shape[1], 3), 255, np.uint8))
    cv2.imwrite(out_path, cv2.cvtColor(np.vstack(grid[:-1]), cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 90])


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="the JPEG to write")
    main(parser.parse_args().out)
