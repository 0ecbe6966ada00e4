"""The simulation itself: pybullet (DIRECT), joint PID control, terrain contact and carving.

No ROS here; :mod:`ow_sim_bullet.sim_node` wires it to topics and services. One instance owns one
pybullet client and must only be used from one thread.

Frames: the lander's ``base_link`` is fixed at the world origin, so world and base_link coincide.
Transforms are named ``X_<to>_<from>`` (``X_base_tip`` maps tip coordinates to base_link ones).

Joint control, per joint and physics step (``dt``), the paper's effort PID position controller::

    e = q_set - q;  integral = clip(integral + i e dt, +-i_clamp)   (not while saturated outward)
    effort = clip(p e + integral + d (v_set - v_next), +-effort_limit)
    damping = -c v_next                    (c: the URDF joint damping, a passive torque)

``v_next`` is the joint velocity at the end of the step, predicted from the full joint-space
inertia and bias (gravity + Coriolis) of pinocchio with the effort and damping treated implicitly
(``(M + dt C) v_next = M v + dt (p e + integral + d v_set - bias)``, ``C = diag(d + c)``, solved
by pinocchio's articulated-body algorithm with ``dt C`` as joint armature). This is backward Euler
for the dampers, stable at any step even on the light wrist and scoop links, where the explicit
form needs 1 kHz and the URDF damping applied explicitly by Bullet diverges. At rest ``v_next`` is
0, so the holding effort is exactly the gravity torque. Bullet gets effort + damping as joint
torques; its own joint damping and link damping are set to zero, so the energy the damping
dissipates in a step is exactly ``-damping * v dt`` (published separately).
"""

from __future__ import annotations

import math
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import pybullet as pb

from ow_dem_bridge.api import ToolState, Wrench
from ow_lander.description import (
    ALL_JOINTS,
    GRINDER_LINK,
    GRINDER_TIP_FRAME,
    SCOOP_LINK,
    SCOOP_TIP_FRAME,
    TERRAIN_CONTACT_LINKS,
    URDF_PATH,
)
from ow_lander.terrain import HeightMap
from ow_sim_bullet.bullet_terrain import BulletTerrain
from ow_sim_bullet.config import PidGains, SimConfig
from ow_sim_bullet.errors import CommandError, ConfigError
from ow_sim_bullet.trajectory import ActiveTrajectory, JointTrajectory

FloatArray = npt.NDArray[np.float64]

#: Bullet collision filter bits: only the tools and the terrain ever collide.
_TOOL_GROUP = 1
_TERRAIN_GROUP = 2
_OTHER_GROUP = 4
#: Coulomb friction coefficient of the tools and of the terrain (Bullet multiplies them: 0.5).
_TOOL_FRICTION = 1.0
_TERRAIN_FRICTION = 0.5
#: m, Bullet's contact breaking threshold (default 0.02): how far apart a tool and the terrain
#: still get (speculative) contact points, and how far the tools' bounding boxes are grown for the
#: heightfield triangle query. The tools move at most a few mm per step (joint speed limits
#: 0.2-0.4 rad/s), so 5 mm still catches every approach, with a quarter of the contact points
#: (each costs the multibody solver a Jacobian and 50 iterations) and fewer triangles.
#: Process-wide in Bullet: every BulletSim sets the same value.
_CONTACT_BREAKING_THRESHOLD = 0.005
#: m, how far ahead of a moving tool tip the terrain counts for the tool's depth.
_DEPTH_LOOKAHEAD = 0.05
#: m/s, tip speeds below this count as not moving (depth is taken at the tip only).
_MOVING_SPEED = 1e-3
#: m, distances ahead of a moving tip at which the terrain counts for its depth.
_LOOKAHEAD_STEPS: tuple[float, ...] = tuple(np.linspace(0.0, _DEPTH_LOOKAHEAD, 6).tolist())

#: m, depth below the surface at which a tool that does not press removes material anyway.
_EMBEDDED_DEPTH = 0.01

#: s of sim time a tool tip may be out of the ground in the middle of a dig (the carving ahead
#: of it zeroes its depth now and then) before its dig progress starts again from zero.
DIG_END_GAP_S = 1.0

#: link whose joint (j_dist_pitch) carries the wrist force/torque sensor.
WRIST_FT_LINK = "l_dist"

#: tool name -> (link, tip frame)
TOOLS: dict[str, tuple[str, str]] = {
    "scoop": (SCOOP_LINK, SCOOP_TIP_FRAME),
    "grinder": (GRINDER_LINK, GRINDER_TIP_FRAME),
}


class TerrainForceModel(Protocol):
    """Anything with ``wrench(state) -> Wrench`` (see :mod:`ow_dem_bridge.api`)."""

    def wrench(self, state: ToolState) -> Wrench: ...


@dataclass(frozen=True)
class UrdfJoint:
    """One joint of the URDF.

    Attributes:
        name: joint name.
        kind: revolute, continuous, prismatic or fixed.
        parent: parent link.
        child: child link.
        effort_limit: N m (inf when not given).
        damping: N m s / rad, viscous joint damping.
    """

    name: str
    kind: str
    parent: str
    child: str
    effort_limit: float
    damping: float


def read_urdf_joints(urdf_text: str) -> dict[str, UrdfJoint]:
    """Joints of a URDF document by name, in document order.

    Raises:
        ConfigError: a movable joint has a friction attribute (not simulated here).
    """
    joints = {}
    for element in ET.fromstring(urdf_text).iter("joint"):
        name = element.get("name", "")
        limit = element.find("limit")
        dynamics = element.find("dynamics")
        effort = float(limit.get("effort", "inf")) if limit is not None else math.inf
        damping = float(dynamics.get("damping", "0")) if dynamics is not None else 0.0
        if dynamics is not None and float(dynamics.get("friction", "0")) != 0.0:
            msg = f"URDF joint {name} has friction; joint friction is not simulated"
            raise ConfigError(msg)
        parent = element.find("parent")
        child = element.find("child")
        joints[name] = UrdfJoint(
            name,
            element.get("type", ""),
            parent.get("link", "") if parent is not None else "",
            child.get("link", "") if child is not None else "",
            effort,
            damping,
        )
    return joints


def physical_inertias(urdf_text: str, margin: float = 1e-3) -> tuple[str, list[str]]:
    """Make every inertia tensor satisfy the triangle inequality with a relative ``margin``.

    Bullet zeroes the inertia of a link whose principal moments (l1 <= l2 <= l3) break, or only
    just meet, l1 + l2 >= l3, which leaves the link without rotational inertia. Adding the
    smallest ``a`` times the identity (every principal moment grows by ``a``) restores it.

    Args:
        urdf_text: the URDF document.
        margin: required (l1 + l2 - l3) / l3.

    Returns:
        The (possibly) corrected URDF text and the names of the links that were corrected.
    """
    root = ET.fromstring(urdf_text)
    corrected = []
    for link in root.iter("link"):
        inertia = link.find("inertial/inertia")
        if inertia is None:
            continue
        names = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        ixx, ixy, ixz, iyy, iyz, izz = (float(inertia.get(k, "0")) for k in names)
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        low, mid, high = np.linalg.eigvalsh(tensor)
        shortfall = margin * high - (low + mid - high)
        if shortfall > 0:
            for key, value in (("ixx", ixx), ("iyy", iyy), ("izz", izz)):
                inertia.set(key, f"{value + shortfall:.9g}")
            corrected.append(link.get("name", ""))
    if not corrected:
        return urdf_text, []
    return ET.tostring(root, encoding="unicode"), corrected


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """a x b of two (3,) vectors: ``np.cross``'s arithmetic (bit-identical), ten times cheaper."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))


def collision_surface_points(urdf_text: str, link_name: str, spacing: float) -> FloatArray:
    """Points on the surface of a link's box and cylinder collision shapes, in the link frame.

    Args:
        urdf_text: the URDF document.
        link_name: the link.
        spacing: m, largest distance between neighbouring points.

    Returns:
        (n, 3) m.

    Raises:
        ConfigError: the link is missing or has a collision shape other than a box or cylinder.
    """
    link = next(
        (e for e in ET.fromstring(urdf_text).iter("link") if e.get("name") == link_name), None
    )
    if link is None:
        msg = f"link {link_name} is not in the URDF"
        raise ConfigError(msg)
    clouds = []
    for collision in link.iter("collision"):
        origin = collision.find("origin")
        xyz = [
            float(v)
            for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()
        ]
        rpy = [
            float(v)
            for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()
        ]
        box = collision.find("geometry/box")
        cylinder = collision.find("geometry/cylinder")
        if box is not None:
            size = [float(v) for v in box.get("size", "0 0 0").split()]
            axes = [np.linspace(-s / 2, s / 2, max(2, math.ceil(s / spacing) + 1)) for s in size]
            grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
            on_face = np.any(np.isclose(np.abs(grid), np.array(size) / 2), axis=1)
            local = grid[on_face]
        elif cylinder is not None:
            radius, length = float(cylinder.get("radius", "0")), float(cylinder.get("length", "0"))
            angles = np.linspace(
                0, 2 * math.pi, max(8, math.ceil(2 * math.pi * radius / spacing)), endpoint=False
            )
            heights = np.linspace(-length / 2, length / 2, max(2, math.ceil(length / spacing) + 1))
            a, h = np.meshgrid(angles, heights)
            side = np.stack((radius * np.cos(a), radius * np.sin(a), h), axis=-1).reshape(-1, 3)
            radii = np.linspace(0, radius, max(2, math.ceil(radius / spacing) + 1))
            rr, aa = np.meshgrid(radii, angles)
            disc = np.stack((rr * np.cos(aa), rr * np.sin(aa)), axis=-1).reshape(-1, 2)
            caps = [
                np.column_stack((disc, np.full(len(disc), z))) for z in (-length / 2, length / 2)
            ]
            local = np.vstack((side, *caps))
        else:
            msg = f"collision of {link_name} must be boxes or cylinders to be carved with"
            raise ConfigError(msg)
        clouds.append(local @ np.asarray(pin.rpy.rpyToMatrix(*rpy)).T + np.asarray(xyz))
    return np.vstack(clouds)


@dataclass(frozen=True)
class JointSample:
    """The joints at one instant, with the torques applied over the following step.

    Attributes:
        time: s of sim time.
        names: joint names (ALL_JOINTS order).
        position: (9,) rad.
        velocity: (9,) rad/s.
        effort: (9,) N m, the controller's (motor) torque.
        damping_effort: (9,) N m, the passive joint-damping torque; its power -damping * v is
            dissipated.
        setpoint: (9,) rad, the controllers' set-points.
    """

    time: float
    names: tuple[str, ...]
    position: FloatArray
    velocity: FloatArray
    effort: FloatArray
    damping_effort: FloatArray
    setpoint: FloatArray


@dataclass
class _ToolTrack:
    """Per-tool contact and dig bookkeeping (mutable, sim thread only)."""

    link_index: int
    #: (3, n) m, points on the link's collision surface in the link frame (one per column).
    surface_points: FloatArray
    last_normal_force: float = 0.0
    force_sum: FloatArray = field(default_factory=lambda: np.zeros(3))
    moment_sum: FloatArray = field(default_factory=lambda: np.zeros(3))
    samples: int = 0
    #: a force was added to the sums since they were last cleared.
    loaded: bool = False
    #: (3,) N and N m, base_link: the mean force and its moment about the origin in the last
    #: snapshot, None when the tool had no force then.
    mean_force: FloatArray | None = None
    mean_moment: FloatArray | None = None
    progress: float = 0.0
    last_tip: FloatArray | None = None
    state: ToolState | None = None
    model_wrench: Wrench | None = None
    out_since: float | None = None
    #: (3,) m, the link's centre of mass in the link frame (where model wrenches act).
    com: FloatArray = field(default_factory=lambda: np.zeros(3))
    #: (6,) the last step's contact force (N) and moment about the world origin (N m), world
    #: frame, or None without contact.
    last_contact: list[float] | None = None


@dataclass(frozen=True)
class ToolSnapshot:
    """A tool's pose, velocity and terrain interaction, for publishing.

    Attributes:
        tool: "scoop" or "grinder".
        link: the tool link.
        time: s of sim time.
        X_base_link: (4, 4) pose of the tool link in base_link.
        linear_velocity: (3,) m/s, tool link origin velocity in base_link.
        angular_velocity: (3,) rad/s, tool link angular velocity in base_link.
        tip: (3,) m, tool tip position in base_link.
        terrain_z: m, terrain height at the tip's x, y.
        depth: m, penetration of the tip below the terrain ahead of it (>= 0).
        progress: m, tip path length below the surface in this dig.
        material: terrain material id.
        force: (3,) N, mean contact + terrain-model force on the tool since the last snapshot,
            in the tool link frame.
        torque: (3,) N m, the matching torque about the tool link origin, in the tool link frame.
        model_wrench: the terrain-force model's wrench applied in the step of this sample (tool
            link frame, about the link COM), for ``model_depth`` and ``progress``; None when no
            model ran for the tool (no model, or the tool above the surface).
        model_depth: m, the depth the model was given in that step. ``depth`` is measured after
            the step and can differ from it when the step carved the terrain ahead of the tip.
    """

    tool: str
    link: str
    time: float
    X_base_link: FloatArray
    linear_velocity: FloatArray
    angular_velocity: FloatArray
    tip: FloatArray
    terrain_z: float
    depth: float
    progress: float
    material: int
    force: FloatArray
    torque: FloatArray
    model_wrench: Wrench | None = None
    model_depth: float = 0.0


def make_force_model(name: str, params: Mapping[str, Any]) -> TerrainForceModel | None:
    """The terrain-force model called ``name`` from ``ow_dem_bridge.models``, or None for "none".

    Raises:
        ConfigError: the factory is missing or rejects the name or parameters.
    """
    if name == "none":
        return None
    try:
        from ow_dem_bridge.models import make_model
    except ImportError as error:
        msg = f"terrain_forces {name!r} needs ow_dem_bridge.models.make_model: {error}"
        raise ConfigError(msg) from error
    try:
        model = make_model(name, dict(params))
    except Exception as error:
        msg = f"terrain_forces {name!r}: ow_dem_bridge could not make the model: {error}"
        raise ConfigError(msg) from error
    if not callable(getattr(model, "wrench", None)):
        msg = f"terrain_forces {name!r}: the model has no wrench(state) method"
        raise ConfigError(msg)
    return model


class BulletSim:
    """The lander on Europa in pybullet, with PID-controlled joints and a carvable terrain.

    Args:
        config: validated parameters.
        heightmap: the initial terrain.
        force_model: terrain-force model for tools below the surface, or None.
    """

    def __init__(
        self,
        config: SimConfig,
        heightmap: HeightMap,
        force_model: TerrainForceModel | None = None,
    ) -> None:
        self.config = config
        self.dt = config.dt
        self.force_model = force_model
        urdf_text, self.corrected_inertias = physical_inertias(URDF_PATH.read_text())
        self.urdf_joints = read_urdf_joints(urdf_text)
        # pinocchio, on the same URDF, gives the inertia and bias the implicit dampers use and the
        # frame poses. Our joint arrays use pinocchio's coordinate order, so no permutation.
        self._pin_model = pin.buildModelFromXML(urdf_text)
        self._pin_model.gravity.linear = np.array([0.0, 0.0, -config.gravity])
        self._pin_data = self._pin_model.createData()
        # The implicit step's linear solve (M + dt C) x = r is pinocchio's articulated-body
        # algorithm on a copy of the model without gravity, at rest, with dt C as the joints'
        # armature: then ABA returns exactly (M + dt C)^-1 r, in O(n) and for less than numpy's
        # dense solve (plus the mass matrix) costs.
        self._solve_model = pin.Model(self._pin_model)
        self._solve_model.gravity.linear = np.zeros(3)
        self._solve_data = self._solve_model.createData()
        order = sorted(
            ALL_JOINTS, key=lambda j: self._pin_model.joints[self._pin_model.getJointId(j)].idx_q
        )
        if self._pin_model.nq != len(ALL_JOINTS) or self._pin_model.nv != len(ALL_JOINTS):
            msg = (
                f"expected {len(ALL_JOINTS)} one-dof joints, pinocchio has nq {self._pin_model.nq}"
            )
            raise ConfigError(msg)
        #: joint names in the order of every joint array of this class.
        self.names: tuple[str, ...] = tuple(order)
        n = len(self.names)
        self._zeros = np.zeros(n)

        self._effort_limit = np.array([self.urdf_joints[j].effort_limit for j in self.names])
        self._negative_effort_limit = -self._effort_limit
        self._damping = np.array([self.urdf_joints[j].damping for j in self.names])
        self._negative_damping = -self._damping
        self._kp = np.zeros(n)
        self._ki = np.zeros(n)
        self._kd = np.zeros(n)
        self._i_clamp = np.zeros(n)
        for joint in self.names:
            self._set_gains_array(joint, config.gains[joint])

        self.client = pb.connect(pb.DIRECT)
        pb.setGravity(0.0, 0.0, -config.gravity, physicsClientId=self.client)
        pb.setPhysicsEngineParameter(
            fixedTimeStep=self.dt,
            numSubSteps=0,
            deterministicOverlappingPairs=1,
            contactBreakingThreshold=_CONTACT_BREAKING_THRESHOLD,
            physicsClientId=self.client,
        )
        with tempfile.TemporaryDirectory(prefix="ow_sim_bullet_") as directory:
            urdf_path = Path(directory) / "lander.urdf"
            urdf_path.write_text(urdf_text)
            self.robot = pb.loadURDF(
                str(urdf_path),
                useFixedBase=True,
                flags=pb.URDF_USE_INERTIA_FROM_FILE,
                physicsClientId=self.client,
            )
        self.link_index: dict[str, int] = {}
        joint_index: dict[str, int] = {}
        for index in range(pb.getNumJoints(self.robot, physicsClientId=self.client)):
            info = pb.getJointInfo(self.robot, index, physicsClientId=self.client)
            joint_index[info[1].decode()] = index
            self.link_index[info[12].decode()] = index
        self._bullet_index = [joint_index[j] for j in self.names]
        for link in (-1, *self.link_index.values()):
            pb.changeDynamics(
                self.robot,
                link,
                linearDamping=0.0,
                angularDamping=0.0,
                jointDamping=0.0,
                physicsClientId=self.client,
            )
            is_tool = link >= 0 and link in [
                self.link_index[name] for name in TERRAIN_CONTACT_LINKS
            ]
            pb.setCollisionFilterGroupMask(
                self.robot,
                link,
                _TOOL_GROUP if is_tool else _OTHER_GROUP,
                _TERRAIN_GROUP if is_tool and config.tool_contact else 0,
                physicsClientId=self.client,
            )
            if is_tool:
                pb.changeDynamics(
                    self.robot, link, lateralFriction=_TOOL_FRICTION, physicsClientId=self.client
                )
        # Torque control needs the default velocity motors off.
        pb.setJointMotorControlArray(
            self.robot,
            self._bullet_index,
            pb.VELOCITY_CONTROL,
            forces=[0.0] * n,
            physicsClientId=self.client,
        )
        spacing = heightmap.resolution / 4.0
        self._tools = {
            tool: _ToolTrack(
                self.link_index[link],
                np.ascontiguousarray(collision_surface_points(urdf_text, link, spacing).T),
            )
            for tool, (link, _) in TOOLS.items()
        }
        self._tool_by_link = {track.link_index: track for track in self._tools.values()}
        for track in self._tools.values():
            info = pb.getDynamicsInfo(self.robot, track.link_index, physicsClientId=self.client)
            track.com = np.array(info[3], dtype=np.float64)
        self._frame_id = {
            name: self._pin_model.getFrameId(name)
            for name in (*self.link_index, "base_link")
            if self._pin_model.existFrame(name)
        }

        # C order: carving indexes it through its flat view.
        self._heights = np.array(heightmap.heights, dtype=np.float64, order="C")
        self._heightmap = HeightMap(
            self._heights, heightmap.resolution, heightmap.origin_x, heightmap.origin_y
        )
        self._terrain = self._make_terrain()
        self._height_bound = self._highest()
        #: incremented whenever the terrain changes (carving or replacement).
        self.terrain_version = 0

        self.time = 0.0
        self.steps = 0
        self._next_carve = 0.0
        #: joint -> the trajectory it follows.
        self._trajectories: dict[str, ActiveTrajectory] = {}
        #: each followed trajectory with the indices of its joints that still follow it, in the
        #: trajectory's and in our joint order (derived from ``_trajectories``).
        self._followed: list[tuple[ActiveTrajectory, npt.NDArray[np.intp], npt.NDArray[np.intp]]]
        self._followed = []
        self._setpoint = np.zeros(n)
        self._integral = np.zeros(n)
        self.sample: JointSample
        #: the sample whose frames pinocchio's data holds, if any.
        self._frames_sample: JointSample | None = None
        self.reset()

    # ------------------------------------------------------------------ commands
    def reset(self) -> None:
        """Put the joints at the initial positions, at rest, holding them; clear trajectories.

        Without gravity feed-forward the integral terms start at the gravity torque of the
        initial pose (for joints with an integral gain), as if the controllers had been holding
        it: the arm does not sag at start. With it they start at zero.
        """
        q0 = np.array([self.config.initial_positions[j] for j in self.names])
        for index, position in zip(self._bullet_index, q0, strict=True):
            pb.resetJointState(self.robot, index, position, 0.0, physicsClientId=self.client)
        self._setpoint = q0.copy()
        self._trajectories.clear()
        self._update_followed()
        gravity = self._bias(q0, np.zeros_like(q0))
        preload = (self._ki > 0) & (not self.config.gravity_feedforward)
        self._integral = np.where(preload, np.clip(gravity, -self._i_clamp, self._i_clamp), 0.0)
        zeros = np.zeros(len(self.names))
        self.sample = JointSample(
            self.time, self.names, q0, zeros, gravity, zeros, self._setpoint.copy()
        )
        for track in self._tools.values():
            track.force_sum[:] = 0.0
            track.moment_sum[:] = 0.0
            track.samples = 0
            track.loaded = False
            track.mean_force = track.mean_moment = None
            track.progress = 0.0
            track.last_tip = None
            track.state = None
            track.model_wrench = None
            track.last_contact = None

    def set_setpoint(self, joint: str, position: float) -> None:
        """Command one joint's position set-point (rad); cancels its trajectory.

        Raises:
            CommandError: unknown joint or non-finite position.
        """
        k = self._joint(joint)
        if not math.isfinite(position):
            msg = f"set-point {position} for {joint} is not finite; command ignored"
            raise CommandError(msg)
        if self._trajectories.pop(joint, None) is not None:
            self._update_followed()
        self._setpoint[k] = position

    def set_trajectory(self, trajectory: JointTrajectory) -> None:
        """Follow ``trajectory`` on its joints (replacing any trajectory they were following)."""
        start = np.array([self._setpoint[self._joint(j)] for j in trajectory.joints])
        active = ActiveTrajectory(trajectory, start, self.time)
        for joint in trajectory.joints:
            self._trajectories[joint] = active
        self._update_followed()

    def _update_followed(self) -> None:
        followed = []
        for active in dict.fromkeys(self._trajectories.values()):
            pairs = [
                (i, self.names.index(joint))
                for i, joint in enumerate(active.trajectory.joints)
                if self._trajectories.get(joint) is active
            ]
            src, dst = np.array(pairs, dtype=np.intp).T
            followed.append((active, src, dst))
        self._followed = followed

    def set_gains(self, joint: str, gains: PidGains) -> None:
        """Change one joint's PID gains now; the integral is kept, within the new clamp.

        Raises:
            CommandError: unknown joint.
        """
        self._joint(joint)
        self._set_gains_array(joint, gains)
        self._integral = np.clip(self._integral, -self._i_clamp, self._i_clamp)

    def gains(self, joint: str) -> PidGains:
        """The gains one joint uses now (i_clamp resolved to N m)."""
        k = self._joint(joint)
        return PidGains(
            float(self._kp[k]), float(self._ki[k]), float(self._kd[k]), float(self._i_clamp[k])
        )

    def set_terrain(self, heightmap: HeightMap) -> None:
        """Replace the terrain (the old one, with its trenches, is discarded)."""
        self._terrain.remove()
        # C order: carving indexes it through its flat view.
        self._heights = np.array(heightmap.heights, dtype=np.float64, order="C")
        self._heightmap = HeightMap(
            self._heights, heightmap.resolution, heightmap.origin_x, heightmap.origin_y
        )
        self._terrain = self._make_terrain()
        self._height_bound = self._highest()
        self.terrain_version += 1

    def _set_gains_array(self, joint: str, gains: PidGains) -> None:
        k = self.names.index(joint)
        self._kp[k], self._ki[k], self._kd[k] = gains.p, gains.i, gains.d
        self._i_clamp[k] = self._effort_limit[k] if gains.i_clamp is None else gains.i_clamp
        self._negative_i_clamp = -self._i_clamp
        #: N m s/rad, d + c: the dampers treated implicitly (diagonal of C).
        self._dampers = self._kd + self._damping
        self._solve_model.armature = self.dt * self._dampers

    def _joint(self, joint: str) -> int:
        try:
            return self.names.index(joint)
        except ValueError:
            msg = f"unknown joint {joint!r}; joints: {list(self.names)}"
            raise CommandError(msg) from None

    def _make_terrain(self) -> BulletTerrain:
        # Both sides' masks exclude the pair when the tools do not touch the terrain (Bullet's
        # filter may be "either side accepts").
        mask = _TOOL_GROUP if self.config.tool_contact else 0
        terrain = BulletTerrain(self.client, self._heightmap, _TERRAIN_GROUP, mask)
        for body in terrain.body_ids:
            pb.changeDynamics(
                body, -1, lateralFriction=_TERRAIN_FRICTION, physicsClientId=self.client
            )
        return terrain

    # ------------------------------------------------------------------ stepping
    def _gravity(self, q: FloatArray) -> FloatArray:
        """N m, the joint torques that hold ``q`` against gravity (our order)."""
        return np.array(pin.computeGeneralizedGravity(self._pin_model, self._pin_data, q))

    def _bias(self, q: FloatArray, v: FloatArray) -> FloatArray:
        """N m, gravity + Coriolis joint torques (our order)."""
        return np.array(pin.rnea(self._pin_model, self._pin_data, q, v, self._zeros))

    def _implicit_solve(self, q: FloatArray, dampers: FloatArray, rhs: FloatArray) -> FloatArray:
        """x with (M(q) + dt diag(dampers)) x = rhs (our order).

        ``dampers`` other than the current :attr:`_dampers` are set for this solve only.
        """
        model = self._solve_model
        if dampers is not self._dampers:
            model.armature = self.dt * dampers
        x = np.array(pin.aba(model, self._solve_data, q, self._zeros, rhs))
        if dampers is not self._dampers:
            model.armature = self.dt * self._dampers
        return x

    def step(self) -> None:
        """Advance the simulation by one physics step of ``dt`` seconds."""
        states = pb.getJointStates(self.robot, self._bullet_index, physicsClientId=self.client)
        q = np.array([s[0] for s in states])
        v = np.array([s[1] for s in states])

        v_set = np.zeros(len(q))
        if self._followed:
            for active, src, dst in self._followed:
                positions, velocities = active.sample(self.time)
                self._setpoint[dst] = positions[src]
                v_set[dst] = velocities[src]
            if any(active.finished(self.time) for active, _, _ in self._followed):
                for joint in [j for j, a in self._trajectories.items() if a.finished(self.time)]:
                    del self._trajectories[joint]
                self._update_followed()

        # Forces besides motors and dampers, for the implicit step's prediction: the tools'
        # contacts of the last step (Bullet applies this step's itself) and the terrain-force
        # model's wrenches (applied below as joint torques).
        external = self._contact_torque(q)
        model_torque = None
        if self.force_model is not None:
            self._frames(q, v)
            model_torque = self._apply_terrain_forces(q)
            if model_torque is not None:
                external = model_torque if external is None else external + model_torque
        effort, damping = self._control(q, v, v_set, external)
        self.sample = JointSample(
            self.time, self.names, q, v, effort, damping, self._setpoint.copy()
        )
        applied = effort + damping
        if self.force_model is not None:
            self._frames_sample = self.sample  # the frames computed above, at q and v
            if model_torque is not None:
                applied = applied + model_torque
        pb.setJointMotorControlArray(
            self.robot,
            self._bullet_index,
            pb.TORQUE_CONTROL,
            forces=applied.tolist(),
            physicsClientId=self.client,
        )
        pb.stepSimulation(physicsClientId=self.client)
        self.steps += 1
        self.time = self.steps * self.dt
        self._accumulate_contacts()
        if self.time >= self._next_carve - 1e-9:
            self._next_carve = self.time + self.config.carve_period
            self._carve()

    def _control(
        self, q: FloatArray, v: FloatArray, v_set: FloatArray, external: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Motor effort and damping torque (N m) for this step; updates the integrals.

        ``external`` (N m), joint torques of the forces applied this step besides the motors
        and dampers (the terrain-force model's): the implicit step must know them, or on a
        light link (the scoop) one step's acceleration would make the dampers' torque jump.
        """
        # (M + dt C) v_next = M v + dt (tau - bias) written for the acceleration a, v_next =
        # v + dt a: (M + dt C) a = tau - bias - C v.
        dt = self.dt
        error = self._setpoint - q
        tau_pi = self._kp * error + self._integral
        if self.config.gravity_feedforward:
            tau_pi = tau_pi + self._gravity(q)
        drive = tau_pi + self._kd * v_set
        bias = self._bias(q, v)
        if external is not None:
            bias = bias - external
        dampers = self._dampers
        v_next = v + dt * self._implicit_solve(q, dampers, drive - bias - dampers * v)
        effort = tau_pi + self._kd * (v_set - v_next)
        integral = self._integral + self._ki * error * dt
        limit, negative_limit = self._effort_limit, self._negative_effort_limit
        saturated = np.abs(effort) > limit
        if np.count_nonzero(saturated):  # (ndarray.any costs ten times more on 9 values)
            # A saturated joint's effort is its limit, no longer a damper.
            limited = np.minimum(np.maximum(effort, negative_limit), limit)
            dampers = np.where(saturated, 0.0, self._kd) + self._damping
            tau = np.where(saturated, limited, drive)
            v_next = v + dt * self._implicit_solve(q, dampers, tau - bias - dampers * v)
            effort = np.where(saturated, limited, tau_pi + self._kd * (v_set - v_next))
            effort = np.minimum(np.maximum(effort, negative_limit), limit)
            # Anti-windup: no integration while the effort is saturated in the error's direction.
            winding = saturated & (np.sign(error) == np.sign(effort))
            integral = np.where(winding, self._integral, integral)
        self._integral = np.minimum(np.maximum(integral, self._negative_i_clamp), self._i_clamp)
        return effort, self._negative_damping * v_next

    # ------------------------------------------------------------------ tools and terrain
    def _accumulate_contacts(self) -> None:
        """Add the last step's contact forces on each tool to its sums (world frame, about the
        world origin) and record its total normal force.

        One ``getContactPoints`` for the whole robot (only the tools touch anything), summed in
        plain Python: a step has a handful of contacts, too few for numpy to pay off.
        """
        by_link = self._tool_by_link
        totals: dict[int, list[float]] = {}
        for c in pb.getContactPoints(bodyA=self.robot, physicsClientId=self.client):
            # c[3] link on the robot, c[5] point on it, c[7] normal (towards the robot), c[9]
            # normal force, c[10]/c[11] and c[12]/c[13] the two friction forces and directions.
            link = c[3]
            if link not in by_link:
                continue
            (px, py, pz), (nx, ny, nz), fn = c[5], c[7], c[9]
            f1, (ax, ay, az), f2, (bx, by, bz) = c[10], c[11], c[12], c[13]
            fx = nx * fn + ax * f1 + bx * f2
            fy = ny * fn + ay * f1 + by * f2
            fz = nz * fn + az * f1 + bz * f2
            sums = totals.get(link)
            if sums is None:
                sums = totals[link] = [0.0] * 7
            sums[0] += fx
            sums[1] += fy
            sums[2] += fz
            sums[3] += py * fz - pz * fy
            sums[4] += pz * fx - px * fz
            sums[5] += px * fy - py * fx
            sums[6] += fn
        for link, track in by_link.items():
            track.samples += 1
            sums = totals.get(link)
            if sums is None:
                track.last_normal_force = 0.0
                track.last_contact = None
                continue
            track.last_normal_force = sums[6]
            track.last_contact = sums[0:6]
            track.force_sum += sums[0:3]
            track.moment_sum += sums[3:6]
            track.loaded = True

    def _carve(self) -> None:
        """Lower the terrain wherever a tool is below it, and under a tool that presses on it with
        more than the yield force by up to ``carve_step`` (in proportion to the force above the
        yield force, full at ``carve_full_force``: a viscoplastic terrain). The grinder, a
        powered cutter, removes what it touches by ``carve_step`` at any force."""
        hm = self._heightmap
        rows, cols = self._heights.shape
        heights = self._heights.reshape(-1)  # a view: cell (r, c) is r * cols + c
        #: flat offsets of the four corners of a cell from its lower-left corner.
        corner_offsets = np.array((0, 1, cols, cols + 1))
        changed_rows: list[int] = []
        changed_cols: list[int] = []
        floor = self._terrain.floor + 1e-3
        for tool, track in self._tools.items():
            low, high = pb.getAABB(self.robot, track.link_index, physicsClientId=self.client)
            c0 = max(int((low[0] - hm.origin_x) / hm.resolution), 0)
            c1 = min(int((high[0] - hm.origin_x) / hm.resolution) + 2, cols)
            r0 = max(int((low[1] - hm.origin_y) / hm.resolution), 0)
            r1 = min(int((high[1] - hm.origin_y) / hm.resolution) + 2, rows)
            if r0 >= r1 or c0 >= c1 or low[2] > self._heights[r0:r1, c0:c1].max() + hm.resolution:
                continue
            state = pb.getLinkState(self.robot, track.link_index, physicsClientId=self.client)
            rotation = np.asarray(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3)
            x, y, z = rotation @ track.surface_points + np.asarray(state[4])[:, None]
            col = np.floor((x - hm.origin_x) / hm.resolution).astype(np.intp)
            row = np.floor((y - hm.origin_y) / hm.resolution).astype(np.intp)
            # Usually every point is over the grid: a slice then spares the fancy indexing.
            inside: slice | npt.NDArray[np.intp] = slice(None)
            if not (row.min() >= 0 and row.max() < rows - 1) or not (
                col.min() >= 0 and col.max() < cols - 1
            ):
                inside = np.flatnonzero(
                    (row >= 0) & (row < rows - 1) & (col >= 0) & (col < cols - 1)
                )
            excess = track.last_normal_force - self.config.terrain_yield_force
            if tool == "grinder" and track.last_normal_force > 0.0:
                # The grinder is a powered cutter: it removes what it touches at the full rate
                # (OceanWATERS lowers the terrain under it whatever the force).
                target, slack = z - self.config.carve_step, 0.0
            elif excess > 0.0:
                # Viscoplastic: the harder the tool presses, the faster the terrain yields (a
                # tool resting just above the yield force does not sink at full speed).
                full = self.config.carve_full_force - self.config.terrain_yield_force
                step = self.config.carve_step * min(excess / full, 1.0)
                target, slack = z - step, 0.0
            else:
                # Not pressing: only material a tool is well inside (e.g. after a terrain change)
                # is removed; Bullet's own contact penetration must not make the tool creep down.
                target, slack = z, _EMBEDDED_DEPTH
            cell = row[inside] * cols + col[inside]
            target = target[inside]
            near = np.flatnonzero(target + slack < heights[cell] + hm.resolution)
            if not len(near):
                continue
            # Each point lowers the four corners of its grid cell (the vertices of the Bullet
            # triangles under it).
            cell = cell[near]
            target = np.maximum(target[near], floor)
            highest = np.maximum(
                np.maximum(heights[cell], heights[cell + 1]),
                np.maximum(heights[cell + cols], heights[cell + cols + 1]),
            )
            if not np.count_nonzero(highest > target + slack):
                continue  # the usual case: nothing above the tool, nothing to cut
            corners = (cell[:, None] + corner_offsets).ravel()
            target = np.repeat(target, len(corner_offsets))
            cut = heights[corners] > target + slack
            if np.count_nonzero(cut):
                corners = corners[cut]
                np.minimum.at(heights, corners, target[cut])
                corner_rows, corner_cols = np.divmod(corners, cols)
                changed_rows += [int(corner_rows.min()), int(corner_rows.max())]
                changed_cols += [int(corner_cols.min()), int(corner_cols.max())]
        if changed_rows:
            self._terrain.refresh(
                self._heights,
                (min(changed_rows), max(changed_rows)),
                (min(changed_cols), max(changed_cols)),
            )
            self.terrain_version += 1

    def _frames(self, q: FloatArray, v: FloatArray | None = None) -> None:
        self._frames_sample = None
        if v is None:
            pin.framesForwardKinematics(self._pin_model, self._pin_data, q)
        else:
            pin.forwardKinematics(self._pin_model, self._pin_data, q, v)
            pin.updateFramePlacements(self._pin_model, self._pin_data)

    def _sample_frames(self) -> None:
        """Frame placements and velocities at the current sample (once per sample)."""
        if self._frames_sample is not self.sample:
            self._frames(self.sample.position, self.sample.velocity)
            self._frames_sample = self.sample

    def _tool_kinematics(
        self, tool: str
    ) -> tuple[pin.SE3, FloatArray, FloatArray, FloatArray, FloatArray]:
        """Link pose, tip position and velocity, link linear and angular velocity (base_link).

        From the frames last computed by :meth:`_frames`.
        """
        link, tip = TOOLS[tool]
        link_id, tip_id = self._frame_id[link], self._frame_id[tip]
        world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        link_velocity = pin.getFrameVelocity(self._pin_model, self._pin_data, link_id, world)
        tip_velocity = pin.getFrameVelocity(self._pin_model, self._pin_data, tip_id, world)
        return (
            self._pin_data.oMf[link_id],
            np.array(self._pin_data.oMf[tip_id].translation),
            np.array(tip_velocity.linear),
            np.array(link_velocity.linear),
            np.array(link_velocity.angular),
        )

    def _heights_along(
        self, x: float, y: float, dx: float, dy: float, distances: tuple[float, ...]
    ) -> list[float]:
        """m, terrain heights at (x + a dx, y + a dy) for each a in ``distances``.

        ``HeightMap.height_at``'s arithmetic for scalars: the same operations in the same order
        on the same doubles, so bit-identical, at a twentieth of the cost of numpy on one point.
        """
        hm = self._heightmap
        origin_x, origin_y, resolution = hm.origin_x, hm.origin_y, hm.resolution
        rows, cols = self._heights.shape
        h = self._heights.item
        heights = []
        for a in distances:
            fc = min(max((x + a * dx - origin_x) / resolution, 0.0), cols - 1.0)
            fr = min(max((y + a * dy - origin_y) / resolution, 0.0), rows - 1.0)
            c0 = min(math.floor(fc), cols - 2)
            r0 = min(math.floor(fr), rows - 2)
            tc = fc - c0
            tr = fr - r0
            heights.append(
                (1 - tr) * ((1 - tc) * h(r0, c0) + tc * h(r0, c0 + 1))
                + tr * ((1 - tc) * h(r0 + 1, c0) + tc * h(r0 + 1, c0 + 1))
            )
        return heights

    def _highest(self) -> float:
        """m, a bound above every interpolated terrain height (carving only lowers it)."""
        return float(self._heights.max()) + 1e-9

    def _depth(self, tip: FloatArray, tip_velocity: FloatArray) -> tuple[float, float]:
        """(terrain z at the tip, depth of the tip below the terrain at and ahead of it), m."""
        x, y, z = tip.tolist()
        vx, vy, _ = tip_velocity.tolist()
        # Above all terrain the depth is 0 whatever lies ahead: look at the tip only, as at rest.
        horizontal = 0.0 if z > self._height_bound else float(np.hypot(vx, vy))
        if horizontal < _MOVING_SPEED:
            terrain_z = surface = self._heights_along(x, y, 0.0, 0.0, (0.0,))[0]
        else:
            # The first distance is 0: the tip itself.
            ahead = self._heights_along(x, y, vx / horizontal, vy / horizontal, _LOOKAHEAD_STEPS)
            terrain_z, surface = ahead[0], max(ahead)
        return terrain_z, max(0.0, surface - z)

    def _update_tool(self, tool: str) -> ToolState | None:
        """Track depth and progress of one tool (frames at the sample); its ToolState if dug in."""
        X_base_link, tip, tip_velocity, _, angular = self._tool_kinematics(tool)
        _, depth = self._depth(tip, tip_velocity)
        return self._track_dig(tool, X_base_link, tip, tip_velocity, angular, depth)

    def _track_dig(
        self,
        tool: str,
        X_base_link: pin.SE3,
        tip: FloatArray,
        tip_velocity: FloatArray,
        angular: FloatArray,
        depth: float,
    ) -> ToolState | None:
        """Update a tool's dig progress from its kinematics and depth; its ToolState if dug in."""
        track = self._tools[tool]
        if depth > 0.0:
            track.out_since = None
        elif track.out_since is None:
            track.out_since = self.time
        out_for = 0.0 if track.out_since is None else self.time - track.out_since
        if depth <= 0.0 and (track.last_tip is None or out_for > DIG_END_GAP_S):
            # Out of the ground for good: the next dig starts from zero progress.
            track.progress = 0.0
            track.last_tip = None
            track.state = None
            return None
        # In the ground, or out of it only for a moment (the carving ahead of the tip can zero
        # its depth for a step or two in the middle of a cut): the cut goes on.
        if track.last_tip is not None:
            step = tip - track.last_tip
            track.progress += math.sqrt(step.dot(step))  # np.linalg.norm's arithmetic
        track.last_tip = tip
        if depth <= 0.0:
            track.state = None
            return None
        rotation_t = np.asarray(X_base_link.rotation).T
        track.state = ToolState(
            tool=tool,
            material=self.config.terrain_material,
            depth=depth,
            progress=track.progress,
            velocity=rotation_t @ tip_velocity,
            angular_velocity=rotation_t @ angular,
        )
        return track.state

    def _contact_torque(self, q: FloatArray) -> FloatArray | None:
        """N m, joint torques of the tools' contact forces of the last step, at ``q``; None
        without contact.

        The implicit dampers apply ``-c v_next`` with ``v_next`` predicted by the step; a
        prediction that ignored the terrain would have a joint the terrain blocks moving fast,
        and its dampers would cancel the motor (a tool pushed into the ground felt a fraction of
        the effort the controller reported). The last step's contact torque is the estimate.
        """
        total = None
        for tool, track in self._tools.items():
            wrench = track.last_contact
            if wrench is None:
                continue
            fid = self._frame_id[TOOLS[tool][0]]
            jacobian = pin.computeFrameJacobian(
                self._pin_model, self._pin_data, q, fid, pin.LOCAL_WORLD_ALIGNED
            )
            # The moment about the link origin, m - origin x f, in scalars: _cross's arithmetic
            # (bit-identical) without the four small arrays it took (~2 us a step in contact).
            px, py, pz = self._pin_data.oMf[fid].translation.tolist()
            fx, fy, fz, mx, my, mz = wrench
            about_origin = (
                fx,
                fy,
                fz,
                mx - (py * fz - pz * fy),
                my - (pz * fx - px * fz),
                mz - (px * fy - py * fx),
            )
            torque = jacobian.T @ np.array(about_origin)
            total = torque if total is None else total + torque
        return total

    def _apply_terrain_forces(self, q: FloatArray) -> FloatArray | None:
        """Query the terrain-force model for each tool in the ground; return the joint torques
        (N m) of its wrenches, None when no tool is in the ground. The frames must be those at
        ``q`` and the current joint velocities (:meth:`_frames`).

        A wrench on a link of a fixed-base arm acts on the joints exactly as ``J^T w`` (``J``
        the link's Jacobian), so it is applied as joint torques computed with pinocchio rather
        than with pybullet's applyExternalForce/Torque, whose frames are unreliable on the links
        of a multibody (bullet3 issues 1949, 3950: measured here, a 1 N m torque on the scoop
        saturated its 30 N m joint).
        """
        assert self.force_model is not None
        total = None
        for tool in TOOLS:
            track = self._tools[tool]
            state = self._update_tool(tool)
            track.model_wrench = None
            if state is None:
                continue
            wrench = self.force_model.wrench(state)
            track.model_wrench = wrench
            fid = self._frame_id[TOOLS[tool][0]]
            X = self._pin_data.oMf[fid]
            rotation = np.asarray(X.rotation)
            force = np.asarray(wrench.force, dtype=np.float64)
            force_world = rotation @ force
            # About the link origin: the wrench is given about the link's centre of mass.
            moment_world = rotation @ (
                np.asarray(wrench.torque, dtype=np.float64) + _cross(track.com, force)
            )
            jacobian = pin.computeFrameJacobian(
                self._pin_model, self._pin_data, q, fid, pin.LOCAL_WORLD_ALIGNED
            )
            torque = jacobian.T @ np.concatenate((force_world, moment_world))
            total = torque if total is None else total + torque
            origin = np.asarray(X.translation)
            track.force_sum += force_world
            track.moment_sum += _cross(origin, force_world) + moment_world
            track.loaded = True
        return total

    # ------------------------------------------------------------------ outputs
    @property
    def heightmap(self) -> HeightMap:
        """A copy of the current (carved) terrain."""
        hm = self._heightmap
        return HeightMap(self._heights.copy(), hm.resolution, hm.origin_x, hm.origin_y)

    def terrain_height(self, x: float, y: float) -> float:
        """m, current terrain height at (x, y) in base_link (bilinear in the height map)."""
        return float(self._heightmap.height_at(x, y))

    def link_poses(self, q: FloatArray | None = None) -> dict[str, FloatArray]:
        """(4, 4) pose in base_link of every link, at joint positions q (default: the sample's)."""
        self._frames(self.sample.position if q is None else q)
        return {
            name: np.asarray(self._pin_data.oMf[frame].homogeneous)
            for name, frame in self._frame_id.items()
        }

    def tool_snapshot(self, tool: str) -> ToolSnapshot:
        """The tool now; the mean force and torque since the previous snapshot of this tool."""
        track = self._tools[tool]
        link, _ = TOOLS[tool]
        self._sample_frames()
        X_base_link, tip, tip_velocity, linear, angular = self._tool_kinematics(tool)
        terrain_z, depth = self._depth(tip, tip_velocity)
        if self.force_model is None:
            # Without a force model nothing tracks the dig every step: track it here.
            state = self._track_dig(tool, X_base_link, tip, tip_velocity, angular, depth)
            progress = state.progress if state is not None else 0.0
        else:
            progress = track.state.progress if track.state is not None else 0.0
        if track.loaded:
            count = max(track.samples, 1)
            origin = np.asarray(X_base_link.translation)
            force_world = track.force_sum / count
            track.mean_force, track.mean_moment = force_world, track.moment_sum / count
            moment_world = track.mean_moment - _cross(origin, force_world)
            rotation_t = np.asarray(X_base_link.rotation).T
            force, torque = rotation_t @ force_world, rotation_t @ moment_world
            track.force_sum[:] = 0.0
            track.moment_sum[:] = 0.0
            track.loaded = False
        else:
            force, torque = np.zeros(3), np.zeros(3)
            track.mean_force = track.mean_moment = None
        track.samples = 0
        return ToolSnapshot(
            tool=tool,
            link=link,
            time=self.sample.time,
            X_base_link=np.asarray(X_base_link.homogeneous),
            linear_velocity=linear,
            angular_velocity=angular,
            tip=tip,
            terrain_z=terrain_z,
            depth=depth,
            progress=progress,
            material=self.config.terrain_material,
            force=force,
            torque=torque,
            model_wrench=track.model_wrench,
            model_depth=track.state.depth
            if track.model_wrench is not None and track.state is not None
            else 0.0,
        )

    def wrist_wrench(self) -> tuple[FloatArray, FloatArray]:
        """The force/torque sensor at ``j_dist_pitch`` (later OceanWATERS), tared: the external
        wrench on everything beyond the joint (the tools' last snapshots), force N and torque
        N m about the joint's origin, in the ``l_dist`` frame. Gravity and inertia of the distal
        links are not in it (as a sensor zeroed at rest)."""
        force = moment = None
        for track in self._tools.values():
            if track.mean_force is not None and track.mean_moment is not None:
                force = track.mean_force if force is None else force + track.mean_force
                moment = track.mean_moment if moment is None else moment + track.mean_moment
        if force is None or moment is None:
            return np.zeros(3), np.zeros(3)
        self._sample_frames()  # already placed by the tool snapshots of this sample
        X_dist = self._pin_data.oMf[self._frame_id[WRIST_FT_LINK]]
        torque = moment - _cross(np.asarray(X_dist.translation), force)
        R_dist_t = np.asarray(X_dist.rotation).T
        return R_dist_t @ force, R_dist_t @ torque

    def gravity_torque(self, q: FloatArray) -> FloatArray:
        """N m, gravity torques (our joint order) at positions q (rad), from pinocchio."""
        return self._bias(q, np.zeros_like(q))

    def close(self) -> None:
        """Disconnect from pybullet."""
        if pb.isConnected(physicsClientId=self.client):
            pb.disconnect(physicsClientId=self.client)
