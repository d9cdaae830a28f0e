"""The parts of a run that never move, as one visualization_msgs/MarkerArray for a bag's `/scene`.

Drawn as the rerun recording draws them (`avsim.recording.static_scene`): the road's edges, the
stop line across the travelled lanes and the stop sign's outline and post in the map frame, and
the car's body boxes in base_link, so a 3D view that follows base_link shows the car on the road.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from avsim.recording.ros_types import BASE_FRAME, MAP_FRAME, header
from avsim.recording.static_scene import CAR_BOX_GEOMS, ROAD_LINE_Z_M
from avsim.world.road import APPROACH_LENGTH_M, ROAD_END_X_M
from avsim.world.scene import CAR_PREFIX, SceneInfo

_CUBE, _LINE_STRIP, _LINE_LIST = 1, 4, 5  # visualization_msgs/Marker types
_RED, _GREY, _WHITE = (0.86, 0.12, 0.12, 1.0), (0.63, 0.63, 0.63, 1.0), (0.94, 0.94, 0.94, 1.0)


def scene_markers(types: dict[str, Any], model: mujoco.MjModel, scene: SceneInfo) -> Any:
    """The MarkerArray of the road, the stop line, the stop sign and the car body."""
    layout = scene.layout
    x_line, y_right = scene.stop_line_x_m, layout.lane_edge_y_m
    x0, x1 = x_line - APPROACH_LENGTH_M, ROAD_END_X_M
    edges = [(x, y, ROAD_LINE_Z_M) for y in (-layout.half_width_m, layout.half_width_m) for x in (x0, x1)]
    stop_line = [(x_line, y_right, ROAD_LINE_Z_M), (x_line, y_right + layout.lanes_per_direction * layout.lane_width_m, ROAD_LINE_Z_M)]
    sign = scene.stop_sign
    outline = [tuple(p) for p in sign.corners_m()]
    base = np.asarray(sign.base_pos_m, dtype=float)
    post = [tuple(base), tuple(base + np.array([0.0, 0.0, sign.bottom_height_m + sign.shape.height_m / 2]))]
    markers = [
        _marker(types, "road", 0, _LINE_LIST, MAP_FRAME, edges, _GREY, 0.08),
        _marker(types, "stop_line", 0, _LINE_LIST, MAP_FRAME, stop_line, _WHITE, 0.15),
        _marker(types, "stop_sign", 0, _LINE_STRIP, MAP_FRAME, [*outline, outline[0]], _RED, 0.03),
        _marker(types, "stop_sign", 1, _LINE_LIST, MAP_FRAME, post, _GREY, 0.035),
    ]
    for index, name in enumerate(CAR_BOX_GEOMS):
        geom = model.geom(CAR_PREFIX + name)
        colour = tuple(float(c) for c in geom.rgba)
        markers.append(_marker(types, "car", index, _CUBE, BASE_FRAME, [], colour, 1.0,
                               centre=np.asarray(geom.pos, dtype=float), size=2 * np.asarray(geom.size, dtype=float)))
    return types["visualization_msgs/msg/MarkerArray"](markers=markers)


def _marker(types: dict[str, Any], ns: str, marker_id: int, kind: int, frame: str, points: list, colour: tuple,
            width_m: float, centre: np.ndarray | None = None, size: np.ndarray | None = None) -> Any:
    t = types
    scale = size if size is not None else np.array([width_m, 0.0, 0.0])  # lines: scale.x is the width
    position = centre if centre is not None else np.zeros(3)
    return t["visualization_msgs/msg/Marker"](
        header=header(0.0, frame), ns=ns, id=marker_id, type=kind, action=0,
        pose=t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](*map(float, position)),
                                         orientation=t["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0)),
        scale=t["geometry_msgs/msg/Vector3"](*map(float, scale)), color=t["std_msgs/msg/ColorRGBA"](*colour),
        lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0), frame_locked=frame == BASE_FRAME,
        points=[t["geometry_msgs/msg/Point"](*map(float, p)) for p in points], colors=[],
        texture_resource="", texture=t["sensor_msgs/msg/CompressedImage"](header=header(0.0, ""), format="", data=np.zeros(0, np.uint8)),
        uv_coordinates=[], text="", mesh_resource="",
        mesh_file=t["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)), mesh_use_embedded_materials=False)
