"""Real-time factor of the simulation node with every ROS output on and subscribed.

Starts a private master and ``rosrun ow_sim_bullet sim`` with ``real_time_factor: 0`` and measures
sim seconds per wall second (a) while the arm holds the stowed pose and (b) while the scoop is
lowered onto the terrain and dragged mouth first through it, digging (a dig phase: the terrain
gives way and is carved, the regolith collected). One JSON line per metric.
Bar (issue 4): at least 30x real time on the project's 2-core machine.

    source env.sh && python bench/sim_speed.py
"""

from __future__ import annotations

import json
import os
import threading
import time
from collections.abc import Sequence

import numpy as np
import rospy
from geometry_msgs.msg import WrenchStamped
from rosgraph_msgs.msg import Clock
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ow_bringup.testing import RosStack, private_master
from ow_description.description import DEFAULT_GROUND_Z, SCOOP_ABOVE_GROUND, SCOOP_DIG_SWEEP
from ow_msgs.msg import ToolState

OUTPUTS = [
    "/joint_states",
    "/sim/joint_damping",
    "/tf",
    "/tf_static",
    "/sim/scoop_tip_ground",
    "/sim/grinder_wrench",
    "/sim/grinder_state",
    "/sim/terrain",
]


class ClockWatch:
    """Wall time at which /clock first reached given sim times."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.sim = 0.0
        self.marks: dict[float, float] = {}
        self.targets: list[float] = []

    def on_clock(self, msg: Clock) -> None:
        now = time.perf_counter()
        with self.lock:
            self.sim = msg.clock.to_sec()
            for target in self.targets:
                if target not in self.marks and self.sim >= target:
                    self.marks[target] = now

    def wait(self, target: float, timeout_s: float = 300.0) -> float:
        with self.lock:
            self.targets.append(target)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self.lock:
                if target in self.marks:
                    return self.marks[target]
            time.sleep(0.01)
        msg = f"sim time never reached {target} s (at {self.sim} s)"
        raise RuntimeError(msg)


def line(metric: str, value: float, unit: str, **extra: object) -> None:
    print(
        json.dumps({"metric": metric, "value": round(value, 2), "unit": unit, **extra}), flush=True
    )


def trajectory(points: Sequence[tuple[float, dict[str, float]]]) -> JointTrajectory:
    msg = JointTrajectory()
    msg.joint_names = list(SCOOP_ABOVE_GROUND)
    for t, pose in points:
        point = JointTrajectoryPoint()
        point.positions = [pose[j] for j in msg.joint_names]
        point.time_from_start = rospy.Duration.from_sec(t)
        msg.points.append(point)
    return msg


def main() -> None:
    with private_master() as master:
        os.environ["ROS_MASTER_URI"] = master.uri
        rospy.init_node("sim_speed_bench", disable_signals=True)
        stack = RosStack(master)
        try:
            stack.start_node(
                "ow_sim_bullet",
                "sim",
                params={
                    "real_time_factor": 0.0,
                    "terrain": f"flat:{DEFAULT_GROUND_Z}",
                    "start_paused": True,
                },
                wait_for_services=["/sim/resume"],
            )
            watch = ClockWatch()
            rospy.Subscriber("/clock", Clock, watch.on_clock, queue_size=100)
            # (sim time s, value): the digging window is selected by stamp.
            forces: list[tuple[float, float]] = []
            depths: list[tuple[float, float]] = []
            rospy.Subscriber(
                "/sim/scoop_wrench",
                WrenchStamped,
                lambda m: forces.append(
                    (m.header.stamp.to_sec(), abs(m.wrench.force.z) + abs(m.wrench.force.x))
                ),
                queue_size=1000,
            )
            rospy.Subscriber(
                "/sim/scoop_state",
                ToolState,
                lambda m: depths.append((m.header.stamp.to_sec(), m.depth)),
                queue_size=1000,
            )
            counts = {topic: 0 for topic in OUTPUTS}
            for topic in OUTPUTS:
                rospy.Subscriber(
                    topic,
                    rospy.AnyMsg,
                    lambda _, t=topic: counts.__setitem__(t, counts[t] + 1),
                    queue_size=1000,
                )
            commands = rospy.Publisher("/sim/joint_trajectory", JointTrajectory, queue_size=1)
            deadline = time.monotonic() + 10.0
            while commands.get_num_connections() == 0 and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(1.0)  # let every subscription connect before the clock runs

            # (a) holding the stowed pose.
            rospy.ServiceProxy("/sim/resume", Trigger)()
            wall_a0 = watch.wait(5.0)
            wall_a1 = watch.wait(65.0)
            line("sim_rtf_holding", 60.0 / (wall_a1 - wall_a0), "x real time", window_sim_s=60.0)

            # (b) scoop onto the terrain, then dragged mouth first through fresh terrain for 60 s
            # (SCOOP_DIG_SWEEP: one sweep of the shoulder yaw; passes back and forth through
            # their own trench would leave the scoop out of contact most of the time).
            rospy.ServiceProxy("/sim/pause", Trigger)()
            time.sleep(0.5)
            start = watch.sim
            msg = trajectory(SCOOP_DIG_SWEEP)
            msg.header.stamp = rospy.Time.from_sec(start + 1.0)
            commands.publish(msg)
            time.sleep(0.5)
            rospy.ServiceProxy("/sim/resume", Trigger)()
            wall_b0 = watch.wait(start + 18.0)
            wall_b1 = watch.wait(start + 78.0)
            time.sleep(0.5)  # the last messages of the window

            def window(samples: list[tuple[float, float]]) -> np.ndarray:
                return np.array([v for t, v in samples if start + 18.0 < t <= start + 78.0])

            window_forces = window(forces)
            window_depths = window(depths)
            line(
                "sim_rtf_digging",
                60.0 / (wall_b1 - wall_b0),
                "x real time",
                window_sim_s=60.0,
                scoop_contact_fraction=round(float(np.mean(window_forces > 0.1)), 3),
                scoop_mean_force_n=round(float(window_forces.mean()), 2),
                scoop_below_surface_fraction=round(float(np.mean(window_depths > 0.0)), 3),
            )
            line(
                "sim_messages_received",
                float(sum(counts.values())),
                "messages",
                per_topic=counts,
            )
        finally:
            stack.shutdown()
            rospy.signal_shutdown("bench done")


if __name__ == "__main__":
    main()
