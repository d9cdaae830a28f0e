"""The default rerun layout of a run: camera views and the 3D world on the left,
time series on the right, so a recording opens ready to read."""

from __future__ import annotations

from collections.abc import Sequence

import rerun.blueprint as rrb

from avsim.recording import paths

# Time-series panels: (title, metric fields plotted together). Fields sharing a panel
# share a unit, so one y axis serves them.
SERIES_PANELS = (
    ("speed [m/s]", ("speed_mps",)),
    ("throttle and brake [0-1]", ("throttle", "brake")),
    ("bumper to stop line [m]: true and estimated", ("stop_line_dist_m", "est_stop_line_dist_m")),
    ("top stop-sign confidence", ("top_stop_conf",)),
    ("required deceleration [m/s^2]", ("required_decel_mps2",)),
    ("body pitch [rad] and wheel slip while braking", ("pitch_rad", "max_brake_slip")),
)


def default_blueprint(cameras: Sequence[str]) -> rrb.Blueprint:
    """Layout for a recording whose images come from `cameras` (e.g. ("front", "side"))."""
    camera_views = [
        rrb.Spatial2DView(name=f"{name} camera", origin=paths.camera_image(name)) for name in cameras
    ]
    world_view = rrb.Spatial3DView(
        name="world",
        origin=paths.WORLD,
        # Follow the car: the road is 380 m long and the car a few metres.
        eye_controls=rrb.EyeControls3D(tracking_entity=paths.CAR),
    )
    series_views = [
        rrb.TimeSeriesView(name=title, origin="/", contents=[paths.metric(field) for field in fields])
        for title, fields in SERIES_PANELS
    ]
    left = rrb.Vertical(rrb.Horizontal(*camera_views), world_view, row_shares=[1, 1])
    right = rrb.Vertical(*series_views)
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[3, 2]),
        rrb.TimePanel(state="expanded", timeline=paths.SIM_TIME_TIMELINE),
        collapse_panels=False,
    )
