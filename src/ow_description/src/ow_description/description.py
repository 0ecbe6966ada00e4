"""Where the robot description lives, and the names every package shares.

Joints are always looked up by name; the tuples below only fix the order of our own arrays
(planner states, trajectory files), never the order of a message.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import numpy.typing as npt

#: The lander URDF: the one source of truth for kinematics, dynamics and collision shapes.
URDF_PATH: Path = Path(__file__).resolve().parents[2] / "urdf" / "lander.urdf"

#: The six arm joints, base to tool (the planner's state order).
ARM_JOINTS: tuple[str, ...] = (
    "j_shou_yaw",
    "j_shou_pitch",
    "j_prox_pitch",
    "j_dist_pitch",
    "j_hand_yaw",
    "j_scoop_yaw",
)
#: The grinder spindle joint.
GRINDER_JOINT = "j_grinder"
#: The antenna pan and tilt joints.
ANTENNA_JOINTS: tuple[str, ...] = ("j_ant_pan", "j_ant_tilt")
#: All nine movable joints, in URDF document order.
ALL_JOINTS: tuple[str, ...] = (*ARM_JOINTS, GRINDER_JOINT, *ANTENNA_JOINTS)
#: The arm joints that turn without end, as OceanWATERS' URDF ``continuous`` joints: any angle
#: is a valid goal (the same as that angle less whole turns), paths go the shorter way round and
#: no joint limit applies. The URDF writes them ``revolute`` with :data:`CONTINUOUS_TRAVEL` of
#: travel, because pinocchio gives a ``continuous`` joint two coordinates (cos, sin): every array
#: of joint angles here stays one number per joint.
CONTINUOUS_JOINTS: tuple[str, ...] = ("j_prox_pitch", "j_dist_pitch", "j_hand_yaw", "j_scoop_yaw")
#: rad, the travel the URDF gives each continuous joint either side of 0 (two turns): the
#: simulated joint never reaches it, as every motion takes the shorter way round from where the
#: joint is, so no measured angle ever falls outside the model's range.
CONTINUOUS_TRAVEL = 4 * math.pi

#: m/s^2, magnitude of Europa's surface gravity, along -z of base_link (the lander stands level).
EUROPA_GRAVITY = 1.315

#: m, height of the flat ground in base_link that OceanWATERS' default world puts under the
#: workspace: default terrain of the simulation, default ``ground_position`` of the services, the
#: mission's expected ground.
DEFAULT_GROUND_Z = -0.155

#: m, deepest trench the grinder can make: its 0.16 m length less clearance for the hand (the
#: grind service's limit, and the mission's).
MAX_GRIND_DEPTH = 0.14
#: m, deepest cut or sweep of the scoop: its mouth is ~0.08 m deep; deeper buries the hand (the
#: dig services' limit, and the mission's).
MAX_SCOOP_DEPTH = 0.1
#: m, longest trench or cut the services accept.
MAX_LENGTH = 1.0

#: Frames the services and tests use.
BASE_FRAME = "base_link"
SCOOP_LINK = "l_scoop"
SCOOP_TIP_FRAME = "l_scoop_tip"
GRINDER_LINK = "l_grinder"
GRINDER_TIP_FRAME = "l_grinder_tip"
DOCK_FRAME = "lander_sample_dock0"

#: Only these links touch the terrain, as in OceanWATERS (the hand and the body do not).
TERRAIN_CONTACT_LINKS: tuple[str, ...] = (SCOOP_LINK, GRINDER_LINK)

#: rad, the stowed configuration of the arm joints (OceanWATERS spawn pose), by joint name.
STOWED: dict[str, float] = {
    "j_shou_yaw": -1.5,
    "j_shou_pitch": 1.5708,
    "j_prox_pitch": -2.75,
    "j_dist_pitch": 2.9,
    "j_hand_yaw": 0.0,
    "j_scoop_yaw": 0.0,
}
#: rad, arm joints holding the scoop level with its tip 5 cm above flat ground at the default
#: height z = -0.155 m (tip at x 1.70, y 0 in base_link); used by simulation tests and benches.
SCOOP_ABOVE_GROUND: dict[str, float] = {
    "j_shou_yaw": -0.0308,
    "j_shou_pitch": 1.3162,
    "j_prox_pitch": -2.3062,
    "j_dist_pitch": 0.99,
    "j_hand_yaw": 0.0,
    "j_scoop_yaw": 1.6016,
}
#: rad, the same with the scoop tip 5 cm below that ground.
SCOOP_BELOW_GROUND: dict[str, float] = {
    **SCOOP_ABOVE_GROUND,
    "j_shou_pitch": 1.0905,
    "j_prox_pitch": -2.2945,
    "j_dist_pitch": 1.204,
}
#: (s from the start, rad by arm joint): the benches' dig (bench/sim_speed.py, bench/sim_core.py):
#: the scoop lowered onto the ground at shoulder yaw -0.3, then dragged for 65 s to yaw 0.35
#: (1.7 cm/s) with its mouth turned along the sweep (scoop yaw + pi/2) and pointing 0.1 rad down
#: (hand yaw - 0.1): mouth first, a dig phase (the terrain gives way); broadside it would only
#: press on solid ground.
SCOOP_DIG_SWEEP: tuple[tuple[float, dict[str, float]], ...] = tuple(
    (
        t,
        {
            **pose,
            "j_shou_yaw": yaw,
            "j_scoop_yaw": pose["j_scoop_yaw"] + math.pi / 2,
            "j_hand_yaw": pose["j_hand_yaw"] - 0.1,
        },
    )
    for t, pose, yaw in (
        (10.0, SCOOP_ABOVE_GROUND, -0.3),
        (15.0, SCOOP_BELOW_GROUND, -0.3),
        (80.0, SCOOP_BELOW_GROUND, 0.35),
    )
)
#: rad, the unstowed ("safe") configuration of the arm joints (later OceanWATERS arm_unstowed).
UNSTOWED: dict[str, float] = {
    "j_shou_yaw": 0.0,
    "j_shou_pitch": 1.5707,
    "j_prox_pitch": -1.5707,
    "j_dist_pitch": 0.0,
    "j_hand_yaw": 1.5707,
    "j_scoop_yaw": 0.0,
}


def nearest_turn(angle: npt.ArrayLike, reference: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """``angle`` (rad) moved by whole turns to the value nearest ``reference`` (rad), elementwise:
    the same orientation of a continuous joint, reached from ``reference`` the shorter way round.
    An angle already within half a turn of ``reference`` is returned unchanged (exactly)."""
    angle = np.asarray(angle, dtype=np.float64)
    turns = np.round((np.asarray(reference, dtype=np.float64) - angle) / (2 * math.pi))
    return angle + (2 * math.pi) * turns


def wrap_angle(angle: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """``angle`` (rad) wrapped into [-pi, pi), elementwise (as OceanWATERS' ``normalize_radians``
    and ros_control's shortest angular distance)."""
    return np.mod(np.asarray(angle, dtype=np.float64) + math.pi, 2 * math.pi) - math.pi
