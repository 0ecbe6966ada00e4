"""The viz node: robot_description, the world frame and markers of the stack (rospy wiring only)."""

from __future__ import annotations

import sys
import threading
import time
from typing import Any

import numpy as np
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker

from ow_description.conversions import height_map_from_msg
from ow_description.description import BASE_FRAME, URDF_PATH
from ow_description.errors import TerrainError
from ow_description.model import LanderModel
from ow_msgs.msg import GuardedMoveResult, HeightMap
from ow_runtime.latched import latched_publisher, static_transform_broadcaster
from ow_runtime.names import (
    GUARDED_MOVE_RESULT,
    JOINT_STATES,
    ROBOT_DESCRIPTION,
    TERRAIN_TOPIC,
    TRAJECTORY_TOPIC,
)
from ow_runtime.node import init_node, quiet_at_shutdown, spin
from ow_viz.config import VizConfig
from ow_viz.conversions import (
    ground_marker,
    path_marker,
    static_transform,
    terrain_marker,
    trajectory_arrays,
)
from ow_viz.errors import ConfigError, SceneError
from ow_viz.scene import terrain_mesh, tool_path


class VizNode:
    """Makes the stack visible to RViz and to bag viewers (Foxglove, Lichtblick).

    ROS API:
        Parameters:
            ``/robot_description`` (str, set): the lander URDF (``ow_lander`` ``urdf/lander.urdf``).
            private, read once (see :class:`~ow_viz.config.VizConfig`): ``~world_frame`` (str,
            default ``world``), ``~base_link_in_world`` ([x, y, z] m, default 0 0 0),
            ``~tool_frame`` (str, default ``l_scoop_tip``), ``~path_sample_period_s`` (float, s,
            default 0.05), ``~terrain_max_side`` (int, default 101), ``~path_width_m`` (float,
            m, default 0.01), ``~ground_diameter_m`` (float, m, default 0.05).
        Subscribes:
            ``/sim/terrain`` (ow_msgs/HeightMap): the terrain, redrawn on every message.
            ``/sim/joint_trajectory`` (trajectory_msgs/JointTrajectory): plans, drawn as the tool
            frame's path.
            ``/guarded_move_result`` (ow_msgs/GuardedMoveResult): the ground found (successes).
            ``/joint_states`` (sensor_msgs/JointState): the joints a plan does not name.
        Publishes (all latched):
            ``/robot_description`` (std_msgs/String): the URDF, once, for bag viewers.
            ``/tf_static`` (tf2_msgs/TFMessage): ``world`` -> ``base_link``.
            ``~terrain`` (visualization_msgs/Marker, TRIANGLE_LIST, frame base_link, m).
            ``~tool_path`` (visualization_msgs/Marker, LINE_STRIP, frame base_link, m).
            ``~ground_point`` (visualization_msgs/Marker, SPHERE, frame base_link, m).
    """

    def __init__(
        self, config: VizConfig, urdf: str, namespace: str = "~", joint_queue_size: int = 1
    ) -> None:
        """Publish the description and the world frame; subscribe to what is drawn.

        Args:
            namespace: of the markers (``~``: the node's; ``/viz/`` when it is one component
                of another node, :mod:`ow_bringup.monitors_node`).
            joint_queue_size: of ``/joint_states`` (only the newest is needed; rospy keeps one
                queue per topic and process, so a component beside one that takes every joint
                state passes ``EVERY_MESSAGE``).
        """
        self.config = config
        self.model = LanderModel()
        self._q_rest = np.zeros(self.model.nq)
        self._lock = threading.Lock()
        rospy.set_param(ROBOT_DESCRIPTION, urdf)
        self._description = latched_publisher(ROBOT_DESCRIPTION, String, queue_size=1)
        self._description.publish(String(data=urdf))
        self._static = static_transform_broadcaster()
        self._static.sendTransform(
            static_transform(
                config.world_frame, BASE_FRAME, config.base_link_in_world, rospy.Time.now()
            )
        )
        self._terrain = latched_publisher(f"{namespace}terrain", Marker, queue_size=1)
        self._path = latched_publisher(f"{namespace}tool_path", Marker, queue_size=1)
        self._ground = latched_publisher(f"{namespace}ground_point", Marker, queue_size=1)
        rospy.Subscriber(JOINT_STATES, JointState, self._on_joints, queue_size=joint_queue_size)
        rospy.Subscriber(TERRAIN_TOPIC, HeightMap, self._on_terrain, queue_size=1)
        rospy.Subscriber(TRAJECTORY_TOPIC, JointTrajectory, self._on_trajectory, queue_size=10)
        rospy.Subscriber(
            GUARDED_MOVE_RESULT, GuardedMoveResult, self._on_guarded_move, queue_size=10
        )

    def _on_joints(self, msg: Any) -> None:
        with self._lock:
            for name, position in zip(msg.name, msg.position, strict=False):
                if name in self.model.joint_names:
                    self._q_rest[self.model.index(name)] = position

    @quiet_at_shutdown
    def _on_terrain(self, msg: Any) -> None:
        start = time.perf_counter()
        try:
            mesh = terrain_mesh(height_map_from_msg(msg), self.config.terrain_max_side)
        except (TerrainError, SceneError) as exc:
            rospy.logerr_throttle(5.0, f"viz: cannot draw /sim/terrain: {exc}")
            return
        marker = terrain_marker(mesh, msg.header.frame_id or BASE_FRAME, msg.header.stamp)
        self._terrain.publish(marker)
        rospy.logdebug(
            f"viz: terrain of {len(mesh.triangles)} triangles in "
            f"{1e3 * (time.perf_counter() - start):.0f} ms"
        )

    @quiet_at_shutdown
    def _on_trajectory(self, msg: Any) -> None:
        with self._lock:
            q_rest = self._q_rest.copy()
        try:
            joints, times, positions, velocities = trajectory_arrays(msg)
            path = tool_path(
                self.model,
                self.config.tool_frame,
                joints,
                times,
                positions,
                velocities,
                self.config.path_sample_period_s,
                q_rest,
            )
        except SceneError as exc:
            rospy.logwarn(f"viz: cannot draw the planned tool path: {exc}")
            return
        stamp = msg.header.stamp if msg.header.stamp.to_nsec() else rospy.Time.now()
        self._path.publish(path_marker(path, BASE_FRAME, stamp, self.config.path_width_m))

    @quiet_at_shutdown
    def _on_guarded_move(self, msg: Any) -> None:
        if not msg.success:
            return
        self._ground.publish(
            ground_marker(
                msg.position,
                msg.frame or BASE_FRAME,
                msg.header.stamp,
                self.config.ground_diameter_m,
            )
        )


def main(argv: list[str] | None = None) -> int:
    """Run the viz node until shutdown; 1 on a configuration error."""
    init_node("viz", argv=argv)
    try:
        config = VizConfig.from_dict(rospy.get_param("~", {}))
    except ConfigError as exc:
        rospy.logfatal(f"viz: {exc}")
        return 1
    VizNode(config, URDF_PATH.read_text())
    rospy.loginfo(
        f"viz: robot_description set, {config.world_frame} -> {BASE_FRAME} published; "
        "drawing /sim/terrain, /sim/joint_trajectory and /guarded_move_result"
    )
    spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
