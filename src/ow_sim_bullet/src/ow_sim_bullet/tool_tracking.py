"""The tools in the terrain: depth and dig progress, when they dig (the scoop's dig phase, the
grinder grinding), the terrain-force model's wrenches and the tools' contacts as joint torques, the
tools' wrench snapshots and the wrist force/torque sensor.

No pybullet here: the caller hands over the simulator's contact points after each step (the sums
are :class:`~ow_sim_bullet.tool_forces.ToolForces`'). Frames:
``base_link`` is the world (the lander is fixed at the origin); transforms are named
``X_<to>_<from>`` (``X_base_link`` maps tool link coordinates to base_link ones).
"""

from __future__ import annotations

import enum
import math
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ow_dem_bridge.api import TerrainForceModel, ToolState, Wrench
from ow_description.description import GRINDER_LINK, GRINDER_TIP_FRAME, SCOOP_LINK, SCOOP_TIP_FRAME
from ow_sim_bullet.carving import MOVING_SPEED
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.joints import JointSample
from ow_sim_bullet.tool_forces import ToolForces, cross

FloatArray = npt.NDArray[np.float64]

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


#: s of sim time over which a tool tip's velocity is measured for its dig (its displacement
#: over this time): longer than the stick-slip of a tool cutting at each carve update, short
#: against the phases of a dig.
MOTION_WINDOW_S = 0.2


class DigPhase(enum.IntEnum):
    """The scoop's dig phase, OceanWATERS' ``ow_dynamic_terrain/scoop_dig_phase`` (same values)."""

    NOT_DIGGING = 0
    SINKING = 1
    PLOWING = 2
    RETRACTING = 3

    @property
    def digging(self) -> bool:
        """Whether the scoop digs (the terrain gives way to it): any phase but NOT_DIGGING."""
        return self is not DigPhase.NOT_DIGGING


class TipMotion:
    """A tool tip's velocity from its positions over the last :data:`MOTION_WINDOW_S`."""

    def __init__(self) -> None:
        self._samples: deque[tuple[float, FloatArray]] = deque()

    def reset(self) -> None:
        """Forget the positions."""
        self._samples.clear()

    def add(self, now: float, tip: FloatArray) -> FloatArray | None:
        """Record the tip at ``now`` (s; (3,) m, base_link); its velocity (3,) m/s over the
        window (from the newest position at least :data:`MOTION_WINDOW_S` old, else the
        oldest), None before a second position."""
        samples = self._samples
        samples.append((now, tip))
        while len(samples) > 2 and now - samples[1][0] >= MOTION_WINDOW_S - 1e-9:
            samples.popleft()
        if len(samples) < 2:
            return None
        then, old = samples[0]
        return (tip - old) / (now - then)


class ScoopDigDetector:
    """The scoop's dig phase from its tip's pose and motion (OceanWATERS' DigStateMachine,
    spec 14.2, with thresholds for this arm's digs; the terrain gives way to the scoop only in
    a dig).

    With ``forward`` the scoop's forward axis (+x of l_scoop_tip, out of its mouth), ``b`` the
    cosine of the angle between its bottom normal (+z) and straight down, and the tip's
    velocity ``v`` over :data:`MOTION_WINDOW_S`, the scoop moves *mouth first* when ``|v|`` >
    :data:`~ow_sim_bullet.carving.MOVING_SPEED` and the angle between ``v`` and ``forward`` is
    at most ``dig_forward_angle``. Transitions, at each :meth:`update`:

    * NOT_DIGGING -> SINKING: mouth first, ``forward`` pointing down, ``b`` >
      cos(``dig_sink_angle``), the tip in the terrain or less than ``dig_exit_clearance``
      above it (at and ahead of it: a dig starts at the ground, not in the air);
    * SINKING -> PLOWING: mouth first, the tip's path descending less steeply than
      ``dig_slope``;
    * SINKING or PLOWING -> RETRACTING: the tip rising more steeply than ``dig_slope``;
    * RETRACTING -> NOT_DIGGING: the tip ``dig_exit_clearance`` above the terrain at and
      ahead of it, and no longer mouth first;
    * any dig phase -> NOT_DIGGING: ``dig_timeout`` s with the tip standing still or out of
      the terrain (OceanWATERS times each phase from its start: 12, 10 and 5 s, shorter than
      this arm's slower digs).

    Args:
        config: the ``dig_*`` thresholds.
    """

    def __init__(self, config: SimConfig) -> None:
        self._cos_forward = math.cos(config.dig_forward_angle)
        self._cos_sink = math.cos(config.dig_sink_angle)
        self._sin_slope = math.sin(config.dig_slope)
        self._exit_clearance = config.dig_exit_clearance
        self._timeout = config.dig_timeout
        self._motion = TipMotion()
        self.phase = DigPhase.NOT_DIGGING
        #: s of sim time the scoop last moved in the terrain while digging.
        self._active_at = 0.0

    def reset(self) -> None:
        """NOT_DIGGING, the tip's motion forgotten."""
        self._motion.reset()
        self.phase = DigPhase.NOT_DIGGING

    def update(
        self, now: float, rotation: FloatArray, tip: FloatArray, terrain: TerrainDepth
    ) -> DigPhase:
        """The phase after the scoop tip's pose at ``now`` (s of sim time).

        Args:
            now: s of sim time.
            rotation: (3, 3), orientation of l_scoop_tip in base_link.
            tip: (3,) m, l_scoop_tip in base_link.
            terrain: the terrain the tip digs.
        """
        velocity = self._motion.add(now, tip)
        if velocity is None:
            return self.phase
        vx, vy, vz = velocity.tolist()
        speed = math.sqrt(vx * vx + vy * vy + vz * vz)
        moving = speed > MOVING_SPEED
        rising = moving and vz > self._sin_slope * speed
        forward = rotation[:, 0]
        mouth_first = moving and float(forward @ velocity) > self._cos_forward * speed
        _, surface = terrain.surface_ahead(tip, velocity)
        clear = float(tip[2]) - surface > self._exit_clearance
        phase = self.phase
        if phase is DigPhase.NOT_DIGGING:
            bottom_down = -float(rotation[2, 2])
            if mouth_first and not clear and forward[2] < 0.0 and bottom_down > self._cos_sink:
                phase = DigPhase.SINKING
        elif phase is DigPhase.RETRACTING:
            if clear and not mouth_first:
                phase = DigPhase.NOT_DIGGING
        elif rising:
            phase = DigPhase.RETRACTING
        elif phase is DigPhase.SINKING and mouth_first and vz >= -self._sin_slope * speed:
            phase = DigPhase.PLOWING
        if phase.digging:
            if not self.phase.digging or (moving and not clear):
                self._active_at = now
            elif now - self._active_at >= self._timeout - 1e-9:
                phase = DigPhase.NOT_DIGGING
        self.phase = phase
        return phase


class TerrainDepth(Protocol):
    """The terrain as the tools' depth reads it (:class:`ow_sim_bullet.carving.TerrainCarver`)."""

    def depth(self, point: FloatArray, velocity: FloatArray) -> tuple[float, float]:
        """(terrain z under ``point``, depth of ``point`` below the terrain at and ahead of it
        along ``velocity``), m."""
        ...

    def surface_ahead(self, point: FloatArray, velocity: FloatArray) -> tuple[float, float]:
        """(terrain z under ``point``, highest terrain z at and ahead of it along
        ``velocity``), m: the terrain :meth:`depth` measures against."""
        ...

    def above(self, point: FloatArray) -> bool:
        """Whether ``point`` (m) is above every part of the terrain (its depth is 0)."""
        ...


@dataclass
class _Dig:
    """Per-tool dig bookkeeping (mutable, sim thread only)."""

    #: (3,) m, the link's centre of mass in the link frame (where model wrenches act).
    com: FloatArray
    progress: float = 0.0
    last_tip: FloatArray | None = None
    state: ToolState | None = None
    model_wrench: Wrench | None = None
    out_since: float | None = None


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


class ToolTracker:
    """The scoop and the grinder: what the terrain does to them and how far they dug.

    Frame placements come from pinocchio, computed once per joint sample (:meth:`place`).

    Args:
        model: pinocchio model of the lander (joint arrays in its coordinate order).
        forces: the forces on the tools (the caller adds each step's contacts).
        com: tool -> (3,) m, its link's centre of mass in the link frame.
        terrain: the terrain, for the tools' depth.
        config: the terrain material id given to the terrain-force model
            (``terrain_material``) and when the tools dig (``dig_*``, ``grind_down_angle``).
        frames: the frames :meth:`link_poses` reports (those the model has); must include the
            tools' links and tips and :data:`WRIST_FT_LINK`.
        material_top: (x, y) m -> m, base_link z of the top of the material a live
            terrain-force model digs (``LockstepModel.material_top``: its bed, loose regolith
            included), or None (the other models: only the height map counts). With it, the
            scoop in a dig phase is in the ground, for the model, wherever its tip is below that
            top, also where its depth below the height map is 0 (the grinder's cuttings on the
            floor of its trench), and its depth is the larger of the two.

    Attributes:
        dig: the scoop's dig phase (decided at each :meth:`update_digging`).
        grinding: whether the grinder grinds: its axis within ``grind_down_angle`` of straight
            down and its tip moving (OceanWATERS lowers the terrain under the grinder then).
    """

    def __init__(
        self,
        model: pin.Model,
        forces: ToolForces,
        com: Mapping[str, FloatArray],
        terrain: TerrainDepth,
        config: SimConfig,
        frames: Iterable[str],
        material_top: Callable[[float, float], float] | None = None,
    ) -> None:
        self._model = model
        self._material_top = material_top
        self._data = model.createData()
        self._terrain = terrain
        self.material = config.terrain_material
        self.dig = ScoopDigDetector(config)
        self.grinding = False
        self._grinder_motion = TipMotion()
        self._cos_grind_down = math.cos(config.grind_down_angle)
        self._tools = {tool: _Dig(com[tool]) for tool in TOOLS}
        self.forces = forces
        self._frame_id = {name: model.getFrameId(name) for name in frames if model.existFrame(name)}
        #: the joint positions and velocities (the arrays themselves) of the frames in _data.
        self._placed: tuple[FloatArray | None, FloatArray | None] = (None, None)

    def reset(self) -> None:
        """Forget the forces, contacts and digs (NOT_DIGGING, the grinder not grinding)."""
        self.forces.reset()
        for track in self._tools.values():
            track.progress = 0.0
            track.last_tip = None
            track.state = None
            track.model_wrench = None
        self.dig.reset()
        self._grinder_motion.reset()
        self.grinding = False

    # ------------------------------------------------------------------ kinematics
    def place(self, q: FloatArray, v: FloatArray | None = None) -> None:
        """Frame placements (and velocities, with ``v``) at joint positions ``q`` (rad, rad/s);
        nothing to do when the frames are already those of these very arrays."""
        placed_q, placed_v = self._placed
        if placed_q is q and placed_v is v:
            return
        if v is None:
            pin.framesForwardKinematics(self._model, self._data, q)
        else:
            pin.forwardKinematics(self._model, self._data, q, v)
            pin.updateFramePlacements(self._model, self._data)
        self._placed = (q, v)

    def link_poses(self, q: FloatArray) -> dict[str, FloatArray]:
        """(4, 4) pose in base_link of every frame, at joint positions ``q`` (rad)."""
        self.place(q)
        return {
            name: np.asarray(self._data.oMf[frame].homogeneous)
            for name, frame in self._frame_id.items()
        }

    def _tool_kinematics(
        self, tool: str
    ) -> tuple[pin.SE3, FloatArray, FloatArray, FloatArray, FloatArray]:
        """Link pose, tip position and velocity, link linear and angular velocity (base_link),
        from the frames placed last."""
        link, tip = TOOLS[tool]
        link_id, tip_id = self._frame_id[link], self._frame_id[tip]
        world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        link_velocity = pin.getFrameVelocity(self._model, self._data, link_id, world)
        tip_velocity = pin.getFrameVelocity(self._model, self._data, tip_id, world)
        return (
            self._data.oMf[link_id],
            np.array(self._data.oMf[tip_id].translation),
            np.array(tip_velocity.linear),
            np.array(link_velocity.linear),
            np.array(link_velocity.angular),
        )

    # ------------------------------------------------------------------ digging
    def update_digging(self, q: FloatArray, now: float) -> None:
        """Decide the scoop's dig phase (:attr:`dig`) and whether the grinder grinds
        (:attr:`grinding`) with the joints at ``q`` (rad) at ``now`` (s of sim time)."""
        self.place(q)
        scoop = self._data.oMf[self._frame_id[SCOOP_TIP_FRAME]]
        self.dig.update(now, np.asarray(scoop.rotation), np.array(scoop.translation), self._terrain)
        grinder = self._data.oMf[self._frame_id[GRINDER_TIP_FRAME]]
        velocity = self._grinder_motion.add(now, np.array(grinder.translation))
        # The grinder's axis is +x of its tip frame: it points down when -z . x is near 1.
        self.grinding = (
            velocity is not None
            and math.sqrt(float(velocity @ velocity)) > MOVING_SPEED
            and -float(grinder.rotation[2, 0]) > self._cos_grind_down
        )

    def digs(self, tool: str) -> bool:
        """Whether ``tool`` digs now: the terrain gives way to it (the scoop in a dig phase,
        the grinder grinding); elsewhere the terrain is solid."""
        return self.dig.phase.digging if tool == "scoop" else self.grinding

    def track_dig(
        self,
        tool: str,
        now: float,
        X_base_link: pin.SE3,
        tip: FloatArray,
        tip_velocity: FloatArray,
        angular: FloatArray,
        depth: float,
    ) -> ToolState | None:
        """Update a tool's dig progress from its kinematics and depth.

        Args:
            tool: "scoop" or "grinder".
            now: s of sim time.
            X_base_link: pose of the tool link in base_link.
            tip: (3,) m, tip position in base_link.
            tip_velocity: (3,) m/s, tip velocity in base_link.
            angular: (3,) rad/s, link angular velocity in base_link.
            depth: m, the tip's depth below the terrain (0 when out of it).

        Returns:
            The tool's state for a terrain-force model when it is dug in, else None.
        """
        if not self._track_progress(tool, now, tip, depth):
            return None
        track = self._tools[tool]
        rotation_t = np.asarray(X_base_link.rotation).T
        track.state = ToolState(
            tool=tool,
            material=self.material,
            depth=depth,
            progress=track.progress,
            velocity=rotation_t @ tip_velocity,
            angular_velocity=rotation_t @ angular,
            time=now,
            pose=np.asarray(X_base_link.homogeneous),
            digging=self.digs(tool),
        )
        return track.state

    def _track_progress(self, tool: str, now: float, tip: FloatArray, depth: float) -> bool:
        """The dig progress of :meth:`track_dig` from the tip (m, base_link) and its depth (m);
        whether the tool is in the ground (when it is not, its state is cleared)."""
        track = self._tools[tool]
        if depth > 0.0:
            track.out_since = None
        elif track.out_since is None:
            track.out_since = now
        out_for = 0.0 if track.out_since is None else now - track.out_since
        if depth <= 0.0 and (track.last_tip is None or out_for > DIG_END_GAP_S):
            # Out of the ground for good: the next dig starts from zero progress.
            track.progress = 0.0
            track.last_tip = None
            track.state = None
            return False
        # In the ground, or out of it only for a moment (the carving ahead of the tip can zero
        # its depth for a step or two in the middle of a cut): the cut goes on.
        if track.last_tip is not None:
            step = tip - track.last_tip
            track.progress += math.sqrt(step.dot(step))  # np.linalg.norm's arithmetic
        track.last_tip = tip
        if depth <= 0.0:
            track.state = None
            return False
        return True

    # ------------------------------------------------------------------ forces
    def contact_torque(self, q: FloatArray) -> FloatArray | None:
        """N m, joint torques of the tools' contact forces of the last step, at ``q`` (rad);
        None without contact.

        The implicit dampers apply ``-c v_next`` with ``v_next`` predicted by the step; a
        prediction that ignored the terrain would have a joint the terrain blocks moving fast,
        and its dampers would cancel the motor (a tool pushed into the ground felt a fraction of
        the effort the controller reported). The last step's contact torque is the estimate.
        """
        total = None
        for tool, wrench in self.forces.last_contacts:
            fid = self._frame_id[TOOLS[tool][0]]
            jacobian = pin.computeFrameJacobian(
                self._model, self._data, q, fid, pin.LOCAL_WORLD_ALIGNED
            )
            # The moment about the link origin, m - origin x f, in scalars: cross's arithmetic
            # (bit-identical) without the four small arrays it took (~2 us a step in contact).
            px, py, pz = self._data.oMf[fid].translation.tolist()
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

    def apply_model(self, q: FloatArray, now: float, model: TerrainForceModel) -> FloatArray | None:
        """Query the terrain-force model for each tool in the ground; the joint torques (N m) of
        its wrenches, None when no tool is in the ground. The frames must have been placed at
        ``q`` and the joint velocities (:meth:`place`); ``now`` is the sim time (s).

        A wrench on a link of a fixed-base arm acts on the joints exactly as ``J^T w`` (``J``
        the link's Jacobian), so the caller applies it as joint torques rather than with
        pybullet's applyExternalForce/Torque, whose frames are unreliable on the links of a
        multibody (bullet3 issues 1949, 3950: measured here, a 1 N m torque on the scoop
        saturated its 30 N m joint).
        """
        total = None
        for tool in TOOLS:
            track = self._tools[tool]
            tip = np.array(self._data.oMf[self._frame_id[TOOLS[tool][1]]].translation)
            material_depth = self.material_depth(tool, tip)
            if material_depth <= 0.0 and self._terrain.above(tip):
                # Above every part of the terrain its depth is 0 whatever its velocity: the
                # velocities (most of the kinematics) are not needed (the grinder, most steps).
                self._track_progress(tool, now, tip, 0.0)
                track.model_wrench = None
                continue
            X_base_link, tip, tip_velocity, _, angular = self._tool_kinematics(tool)
            _, depth = self._terrain.depth(tip, tip_velocity)
            depth = max(depth, material_depth)
            state = self.track_dig(tool, now, X_base_link, tip, tip_velocity, angular, depth)
            track.model_wrench = None
            if state is None:
                continue
            wrench = model.wrench(state)
            track.model_wrench = wrench
            fid = self._frame_id[TOOLS[tool][0]]
            X = self._data.oMf[fid]
            rotation = np.asarray(X.rotation)
            force = np.asarray(wrench.force, dtype=np.float64)
            force_world = rotation @ force
            # About the link origin: the wrench is given about the link's centre of mass.
            moment_world = rotation @ (
                np.asarray(wrench.torque, dtype=np.float64) + cross(track.com, force)
            )
            jacobian = pin.computeFrameJacobian(
                self._model, self._data, q, fid, pin.LOCAL_WORLD_ALIGNED
            )
            torque = jacobian.T @ np.concatenate((force_world, moment_world))
            total = torque if total is None else total + torque
            origin = np.asarray(X.translation)
            self.forces.add(tool, force_world, cross(origin, force_world) + moment_world)
        return total

    def material_depth(self, tool: str, tip: FloatArray) -> float:
        """m, the depth of ``tool``'s tip (3,) m in base_link below the top of the live model's
        material (``material_top``): for the scoop in a dig phase with a live model only, else 0.
        """
        if self._material_top is None or tool != "scoop" or not self.dig.phase.digging:
            return 0.0
        x, y, z = tip.tolist()
        return max(0.0, self._material_top(x, y) - z)

    # ------------------------------------------------------------------ outputs
    def snapshot(self, tool: str, sample: JointSample, now: float, track: bool) -> ToolSnapshot:
        """The tool at ``sample``; the mean force and torque since its previous snapshot.

        Args:
            tool: "scoop" or "grinder".
            sample: the joints now.
            now: s of sim time.
            track: track the dig here (nothing else does when no terrain-force model runs).
        """
        tracked = self._tools[tool]
        link, _ = TOOLS[tool]
        self.place(sample.position, sample.velocity)
        X_base_link, tip, tip_velocity, linear, angular = self._tool_kinematics(tool)
        terrain_z, depth = self._terrain.depth(tip, tip_velocity)
        if track:
            state = self.track_dig(tool, now, X_base_link, tip, tip_velocity, angular, depth)
            progress = state.progress if state is not None else 0.0
        else:
            progress = tracked.state.progress if tracked.state is not None else 0.0
        mean = self.forces.take_mean(tool)
        if mean is not None:
            force_world, moment_about_origin = mean
            origin = np.asarray(X_base_link.translation)
            moment_world = moment_about_origin - cross(origin, force_world)
            rotation_t = np.asarray(X_base_link.rotation).T
            force, torque = rotation_t @ force_world, rotation_t @ moment_world
        else:
            force, torque = np.zeros(3), np.zeros(3)
        return ToolSnapshot(
            tool=tool,
            link=link,
            time=sample.time,
            X_base_link=np.asarray(X_base_link.homogeneous),
            linear_velocity=linear,
            angular_velocity=angular,
            tip=tip,
            terrain_z=terrain_z,
            depth=depth,
            progress=progress,
            material=self.material,
            force=force,
            torque=torque,
            model_wrench=tracked.model_wrench,
            model_depth=tracked.state.depth
            if tracked.model_wrench is not None and tracked.state is not None
            else 0.0,
        )

    def wrist_wrench(self, sample: JointSample) -> tuple[FloatArray, FloatArray]:
        """The force/torque sensor at ``j_dist_pitch`` (later OceanWATERS), compensated for the
        weight and inertia of the links beyond the joint: the external wrench on them (the
        tools' means at their last snapshots: contacts and terrain-force model), force N and
        torque N m about the joint's origin, in the ``l_dist`` frame, at ``sample``. It is the
        joint's reaction wrench less the distal links' weight and ``m a`` (Newton-Euler; checked
        in ``test_wrist_sensor.py``): zero in the air, whatever the pose and motion."""
        total = self.forces.total_mean()
        if total is None:
            return np.zeros(3), np.zeros(3)
        force, moment = total
        self.place(sample.position, sample.velocity)  # already placed by the tool snapshots
        X_dist = self._data.oMf[self._frame_id[WRIST_FT_LINK]]
        torque = moment - cross(np.asarray(X_dist.translation), force)
        R_dist_t = np.asarray(X_dist.rotation).T
        return R_dist_t @ force, R_dist_t @ torque
