"""Configuration of the viz node: a frozen dataclass built by a pure ``from_dict()``.

The node reads its private namespace once (``rospy.get_param("~")``) and passes the dict here;
``config/viz.yaml`` holds the defaults below (:data:`CONFIG_FILE`). A missing key takes its
default; unknown keys, wrong types and values out of range are reported together in one
:class:`~ow_viz.errors.ConfigError` naming each key (``viz/terrain_max_side``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ow_description.description import SCOOP_TIP_FRAME
from ow_runtime.params import Params
from ow_viz.errors import ConfigError

#: The viz node's parameter file (``src/ow_viz/config/viz.yaml``), loaded whole as ``~``.
CONFIG_FILE = Path(__file__).resolve().parents[2] / "config" / "viz.yaml"


@dataclass(frozen=True)
class VizConfig:
    """Parameters of the viz node (private namespace ``~``).

    Attributes:
        world_frame: the fixed frame above ``base_link`` (REP 105), published static.
        base_link_in_world: m, (x, y, z) of ``base_link`` in ``world`` (no rotation: the lander
            stands level, x forward).
        tool_frame: the frame whose path is drawn along every planned trajectory.
        path_sample_period_s: s of trajectory time between two drawn points of the tool path.
        terrain_max_side: vertices per side of the terrain mesh at most; a larger height map is
            drawn with every n-th cell (its last row and column always kept).
        path_width_m: m, width of the tool-path line.
        ground_diameter_m: m, diameter of the ground-point sphere.
    """

    world_frame: str = "world"
    base_link_in_world: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tool_frame: str = SCOOP_TIP_FRAME
    path_sample_period_s: float = 0.05
    terrain_max_side: int = 101
    path_width_m: float = 0.01
    ground_diameter_m: float = 0.05

    @classmethod
    def from_dict(cls, params: Mapping[str, Any]) -> VizConfig:
        """Validate a parameter dict (missing keys take their defaults).

        Args:
            params: the node's private namespace (the content of :data:`CONFIG_FILE`).

        Raises:
            ConfigError: unknown keys, wrong types or values out of range; the message names
                each key.
        """
        p = Params(params, "viz", ConfigError)
        world_frame = p.string("world_frame", cls.world_frame)
        if not world_frame or world_frame == "base_link":
            p.problem(
                f"{p.name('world_frame')} = {world_frame!r} must name a frame other than base_link"
            )
        raw_xyz = p.raw("base_link_in_world", list(cls.base_link_in_world))
        xyz = cls.base_link_in_world
        if not isinstance(raw_xyz, list | tuple) or len(raw_xyz) != 3:
            p.problem(f"{p.name('base_link_in_world')} must be [x, y, z] in m, got {raw_xyz!r}")
        else:
            x, y, z = (
                p.check_number(v, f"{p.name('base_link_in_world')}[{i}]", 0.0, unit="m")
                for i, v in enumerate(raw_xyz)
            )
            xyz = (x, y, z)
        config = cls(
            world_frame=world_frame,
            base_link_in_world=xyz,
            tool_frame=p.string("tool_frame", cls.tool_frame),
            path_sample_period_s=p.positive("path_sample_period_s", cls.path_sample_period_s, "s"),
            terrain_max_side=p.integer("terrain_max_side", cls.terrain_max_side, low=2),
            path_width_m=p.positive("path_width_m", cls.path_width_m, unit="m"),
            ground_diameter_m=p.positive("ground_diameter_m", cls.ground_diameter_m, unit="m"),
        )
        p.finish()
        return config
