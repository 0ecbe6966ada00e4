"""The simulation itself: the lander in pybullet (DIRECT), stepped with its parts.

No ROS here; :mod:`ow_sim_bullet.sim_node` wires it to topics and services. One instance owns one
pybullet client and must only be used from one thread. :class:`BulletSim` loads the robot and the
terrain into pybullet and, every physics step, hands the measured joints to its parts and their
torques to pybullet:

* :class:`~ow_sim_bullet.joint_control.JointController`: the PID controllers, trajectories,
  gravity feed-forward and the implicit damped step (the equations are in its module);
* :class:`~ow_sim_bullet.tool_forces.ToolForces`: the forces on the tools, summed between
  snapshots;
* :class:`~ow_sim_bullet.tool_tracking.ToolTracker`: the tools' depth and dig progress, when they
  dig (the scoop's dig phase, the grinder grinding), the terrain-force model's wrenches and the
  contacts as joint torques, the tools' snapshots and the wrist F/T sensor;
* :class:`~ow_sim_bullet.carving.TerrainCarver`: the height map and the carving under the tools
  (only those that dig: elsewhere the terrain is solid);
* :class:`~ow_sim_bullet.regolith.SimRegolith`: the regolith the tools cut, the scoop holds,
  spills and pours (deposits raise the height map), the dock, and their budget.

Frames: the lander's ``base_link`` is fixed at the world origin, so world and base_link coincide.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pybullet as pb

from ow_dem_bridge.api import LockstepModel, TerrainForceModel
from ow_dem_bridge.errors import DemRunError
from ow_dem_bridge.models import make_model
from ow_description.description import ARM_JOINTS, TERRAIN_CONTACT_LINKS, URDF_PATH
from ow_description.terrain import HeightMap
from ow_faults.injection import FaultSet
from ow_regolith.errors import RegolithError
from ow_sim_bullet.bullet_terrain import BulletTerrain
from ow_sim_bullet.carving import TerrainCarver, collision_surface_points
from ow_sim_bullet.config import PidGains, SimConfig
from ow_sim_bullet.dem_terrain import LiveDemDigEnds
from ow_sim_bullet.errors import CommandError, ConfigError
from ow_sim_bullet.faults import LOCK_DAMPER, JointLocks, WristFaults
from ow_sim_bullet.joint_control import FloatArray, JointController
from ow_sim_bullet.joints import ClippedSetpoint, JointSample
from ow_sim_bullet.regolith import SimRegolith
from ow_sim_bullet.tool_forces import ToolForces
from ow_sim_bullet.tool_tracking import TOOLS, DigPhase, ToolSnapshot, ToolTracker
from ow_sim_bullet.trajectory import JointTrajectory
from ow_sim_bullet.urdf import physical_inertias, read_urdf_joints

#: Bullet collision filter bits: only the tools and the terrain ever collide.
_TOOL_GROUP = 1
_TERRAIN_GROUP = 2
_OTHER_GROUP = 4
#: Coulomb friction coefficient of the tools. Bullet multiplies the two bodies' coefficients, so
#: the tool-terrain pair's is the terrain's, ``terrain_friction``.
_TOOL_FRICTION = 1.0
#: m, Bullet's contact breaking threshold (default 0.02): how far apart a tool and the terrain
#: still get (speculative) contact points, and how far the tools' bounding boxes are grown for the
#: heightfield triangle query. The tools move at most a few mm per step (joint speed limits
#: 0.2-0.4 rad/s), so 5 mm still catches every approach, with a quarter of the contact points
#: (each costs the multibody solver a Jacobian and 50 iterations) and fewer triangles.
#: Process-wide in Bullet: every BulletSim sets the same value.
_CONTACT_BREAKING_THRESHOLD = 0.005
#: Carving points per terrain cell along a tool's surface (their spacing is the cell over this).
_POINTS_PER_CELL = 4.0

#: Builds a terrain-force model that is not made in process (the node's topic-backed one).
RemoteFactory = Callable[[Mapping[str, Any]], TerrainForceModel]


def make_force_model(
    name: str,
    params: Mapping[str, Any],
    remote: tuple[str, RemoteFactory] | None = None,
) -> TerrainForceModel | None:
    """The terrain-force model called ``name``, or None for "none".

    Args:
        name: a name of ``ow_dem_bridge.models.make_model`` or ``remote``'s.
        params: the model's parameters.
        remote: (name, factory) of the model made outside this package's pure core (the
            simulation node passes the ROS-backed ``ow_dem_bridge.remote_node`` factory).

    Raises:
        ConfigError: the factory rejects the name or parameters, or made no model.
    """
    if name == "none":
        return None
    try:
        if remote is not None and name == remote[0]:
            model = remote[1](dict(params))
        else:
            model = make_model(name, dict(params))
    except Exception as error:
        msg = f"terrain_forces {name!r}: ow_dem_bridge could not make the model: {error}"
        raise ConfigError(msg) from error
    if not callable(getattr(model, "wrench", None)):
        msg = f"terrain_forces {name!r}: the model has no wrench(state) method"
        raise ConfigError(msg)
    return model


def load_robot(
    client: int, urdf_text: str, names: Sequence[str], tool_contact: bool
) -> tuple[int, dict[str, int], list[int]]:
    """Load the URDF into pybullet client ``client`` under torque control: only the tools
    collide (with the terrain, if ``tool_contact``), no Bullet damping.

    Returns:
        The body id, link name -> link index, and the joint indices of ``names``.
    """
    with tempfile.TemporaryDirectory(prefix="ow_sim_bullet_") as directory:
        urdf_path = Path(directory) / "lander.urdf"
        urdf_path.write_text(urdf_text)
        robot = pb.loadURDF(
            str(urdf_path),
            useFixedBase=True,
            flags=pb.URDF_USE_INERTIA_FROM_FILE,
            physicsClientId=client,
        )
    link_index: dict[str, int] = {}
    joint_index: dict[str, int] = {}
    for index in range(pb.getNumJoints(robot, physicsClientId=client)):
        info = pb.getJointInfo(robot, index, physicsClientId=client)
        joint_index[info[1].decode()] = index
        link_index[info[12].decode()] = index
    bullet_index = [joint_index[j] for j in names]
    tools = [link_index[name] for name in TERRAIN_CONTACT_LINKS]
    for link in (-1, *link_index.values()):
        pb.changeDynamics(
            robot,
            link,
            linearDamping=0.0,
            angularDamping=0.0,
            jointDamping=0.0,
            physicsClientId=client,
        )
        is_tool = link >= 0 and link in tools
        pb.setCollisionFilterGroupMask(
            robot,
            link,
            _TOOL_GROUP if is_tool else _OTHER_GROUP,
            _TERRAIN_GROUP if is_tool and tool_contact else 0,
            physicsClientId=client,
        )
        if is_tool:
            pb.changeDynamics(robot, link, lateralFriction=_TOOL_FRICTION, physicsClientId=client)
    # Torque control needs the default velocity motors off.
    pb.setJointMotorControlArray(
        robot,
        bullet_index,
        pb.VELOCITY_CONTROL,
        forces=[0.0] * len(names),
        physicsClientId=client,
    )
    return robot, link_index, bullet_index


class BulletSim:
    """The lander on Europa in pybullet, with PID-controlled joints and a carvable terrain.

    Args:
        config: validated parameters.
        heightmap: the initial terrain.
        force_model: terrain-force model for tools below the surface, or None.

    Raises:
        ConfigError: the URDF does not suit the simulation (joint friction, tool shapes, the
            regolith's scoop or dock).
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
        # frame poses.
        model = pin.buildModelFromXML(urdf_text)
        model.gravity.linear = np.array([0.0, 0.0, -config.gravity])
        self.controller = JointController(
            model, self.urdf_joints, config.gains, self.dt, config.gravity_feedforward
        )
        #: joint names in the order of every joint array of this class.
        self.names: tuple[str, ...] = self.controller.names

        self.client = pb.connect(pb.DIRECT)
        pb.setGravity(0.0, 0.0, -config.gravity, physicsClientId=self.client)
        pb.setPhysicsEngineParameter(
            fixedTimeStep=self.dt,
            numSubSteps=0,
            deterministicOverlappingPairs=1,
            contactBreakingThreshold=_CONTACT_BREAKING_THRESHOLD,
            physicsClientId=self.client,
        )
        self.robot, self.link_index, self._bullet_index = load_robot(
            self.client, urdf_text, self.names, config.tool_contact
        )
        spacing = heightmap.resolution / _POINTS_PER_CELL
        cutters = {
            tool: np.ascontiguousarray(collision_surface_points(urdf_text, link, spacing).T)
            for tool, (link, _) in TOOLS.items()
        }
        tool_links = {tool: self.link_index[link] for tool, (link, _) in TOOLS.items()}
        com = {
            tool: np.array(
                pb.getDynamicsInfo(self.robot, index, physicsClientId=self.client)[3],
                dtype=np.float64,
            )
            for tool, index in tool_links.items()
        }
        self.carver = TerrainCarver(heightmap, config, cutters, self._make_surface)
        self.regolith, self._regolith_scoop = self._make_regolith(heightmap)
        material_top = None
        #: the live terrain-force model (the DEM), None for the others.
        self._live = force_model if isinstance(force_model, LockstepModel) else None
        #: every dig of it that ended or failed, (sim time s of the carve update that learnt it,
        #: the dig's summary), oldest first: a few per mission (the outputs publish each once).
        self.finished_dem_digs: list[tuple[float, dict[str, Any]]] = []
        #: what the simulation does with the live DEM's digs when they end (None without it).
        self._dem_digs: LiveDemDigEnds | None = None
        if self._live is not None:  # this terrain, its loose regolith, the physics step
            self._live.attach(self.carver, self.dt, self._loose_top)
            material_top = self._live.material_top
            self._dem_digs = LiveDemDigEnds(self._live, self.regolith, self.carver, self._scoop_box)
        self.forces = ToolForces(tool_links)
        self.tracker = ToolTracker(
            model,
            self.forces,
            com,
            self.carver,
            config,
            frames=(*self.link_index, "base_link"),
            material_top=material_top,
        )
        self._tool_links = tool_links
        joint_index = dict(zip(self.names, self._bullet_index, strict=True))
        self.locks = JointLocks(self.client, self.robot, joint_index)
        self.wrist_faults = WristFaults(config.noise_seed)
        self.time = 0.0
        self.steps = 0
        self._next_carve = 0.0
        self.sample: JointSample
        self.reset()

    def _make_regolith(self, heightmap: HeightMap) -> tuple[SimRegolith, int]:
        """The regolith of the initial terrain and the Bullet link index of its scoop link."""
        config = self.config.regolith
        if config.scoop.link not in self.link_index:
            msg = f"regolith/scoop/link {config.scoop.link!r} is not a link of the URDF"
            raise ConfigError(msg)
        try:
            regolith = SimRegolith(config, heightmap, self.config.terrain)
        except RegolithError as error:
            msg = f"regolith: {error}"
            raise ConfigError(msg) from error
        return regolith, self.link_index[config.scoop.link]

    def _loose_top(self, x: float, y: float) -> float:
        """m, base_link z of the top of the loose regolith in the terrain cell nearest (x, y) m
        (its solid top where there is none; ``-inf`` beyond the terrain): the regolith ledger's
        (``CarvingLedger.loose_top``), for the live DEM's beds."""
        ledger = self.regolith.tracker.ledger
        cell = ledger.cell_at(x, y)
        return -math.inf if cell is None else ledger.loose_top(cell)

    def _scoop_box(self) -> tuple[FloatArray, FloatArray]:
        """(low, high) (3,) m, the scoop link's bounding box in base_link now."""
        low, high = pb.getAABB(self.robot, self._tool_links["scoop"], physicsClientId=self.client)
        return np.asarray(low), np.asarray(high)

    def _make_surface(self, heightmap: HeightMap) -> BulletTerrain:
        """The terrain as Bullet heightfields, colliding with the tools if ``tool_contact``."""
        # Both sides' masks exclude the pair when the tools do not touch the terrain (Bullet's
        # filter may be "either side accepts").
        mask = _TOOL_GROUP if self.config.tool_contact else 0
        terrain = BulletTerrain(self.client, heightmap, _TERRAIN_GROUP, mask)
        for body in terrain.body_ids:
            pb.changeDynamics(
                body,
                -1,
                lateralFriction=self.config.terrain_friction,
                physicsClientId=self.client,
            )
        return terrain

    # ------------------------------------------------------------------ commands
    def reset(self) -> None:
        """Put the joints at the initial positions, at rest, holding them; clear trajectories
        and the tools' forces and digs (see :meth:`JointController.reset`). The carve updates
        start again with the next step, as on a new simulation: what follows a reset does not
        depend on how many steps came before it."""
        q0 = np.array([self.config.initial_positions[j] for j in self.names])
        for index, position in zip(self._bullet_index, q0, strict=True):
            pb.resetJointState(self.robot, index, position, 0.0, physicsClientId=self.client)
        self.controller.reset(q0)
        zeros = np.zeros(len(self.names))
        self.sample = JointSample(
            self.time,
            self.names,
            q0,
            zeros,
            self.controller.gravity_torque(q0),
            zeros,
            self.controller.setpoint,
        )
        self.tracker.reset()
        self._next_carve = self.time

    def position(self, joint: str) -> float:
        """rad, where ``joint`` is now (after the last step).

        Raises:
            CommandError: unknown joint.
        """
        if joint not in self.names:
            msg = f"unknown joint {joint!r}"
            raise CommandError(msg)
        state = pb.getJointState(
            self.robot, self._bullet_index[self.names.index(joint)], physicsClientId=self.client
        )
        return float(state[0])

    def set_setpoint(self, joint: str, position: float) -> ClippedSetpoint | None:
        """Command one joint's position set-point (rad); cancels its trajectory. A set-point
        beyond the joint's URDF limits is clipped onto the limit.

        Returns:
            What was clipped, or None.

        Raises:
            CommandError: unknown joint or non-finite position (the command is ignored).
        """
        return self.controller.set_setpoint(joint, position)

    def set_trajectory(self, trajectory: JointTrajectory) -> list[ClippedSetpoint]:
        """Follow ``trajectory`` on its joints (replacing any trajectory they were following);
        points beyond a joint's URDF limits are followed on the limit.

        Returns:
            The joints with points beyond their limits (empty: none).

        Raises:
            CommandError: the trajectory names an unknown joint.
        """
        return self.controller.set_trajectory(trajectory, self.time)

    def set_gains(self, joint: str, gains: PidGains) -> None:
        """Change one joint's PID gains now; the integral is kept, within the new clamp.

        Raises:
            CommandError: unknown joint.
        """
        self.controller.set_gains(joint, gains)

    def gains(self, joint: str) -> PidGains:
        """The gains one joint uses now (i_clamp resolved to N m).

        Raises:
            CommandError: unknown joint.
        """
        return self.controller.gains(joint)

    def apply_faults(self, faults: FaultSet) -> tuple[frozenset[str], frozenset[str]]:
        """Lock the joints ``faults`` lock (releasing the others, each held where it is) and
        fault the wrist sensor as it says (:mod:`ow_sim_bullet.faults`). A newly locked arm
        joint with ``arm_motion_continues_in_fault`` false stops the other arm joints where they
        are (their trajectories cancelled) in this step.

        Returns:
            The joints newly locked and the joints released.
        """
        locked, released = self.locks.set(faults.locked_joints)
        self.controller.set_locked(faults.locked_joints, LOCK_DAMPER)
        for joint in released:
            self.controller.release(joint, float(self.sample.position[self.names.index(joint)]))
        if locked & set(ARM_JOINTS) and not faults.arm_motion_continues_in_fault:
            # OceanWATERS stops the arm on an arm execution error: here in the step the lock
            # engages, whatever the detector's and the arm services' topics take to arrive.
            for joint in set(ARM_JOINTS) - faults.locked_joints:
                position = float(self.sample.position[self.names.index(joint)])
                self.controller.set_setpoint(joint, position)
        self.wrist_faults.set(faults)
        return locked, released

    def set_terrain(self, heightmap: HeightMap, terrain: str = "") -> None:
        """Replace the terrain (the old one, with its trenches and loose regolith, is
        discarded); ``terrain``, its specification, selects its regolith layer column (the
        default column for "" or a kind without its own)."""
        self.carver.replace(heightmap)
        self.regolith.set_terrain(heightmap, terrain)
        if self._dem_digs is not None:
            self._dem_digs.terrain_replaced()

    # ------------------------------------------------------------------ stepping
    def step(self) -> None:
        """Advance the simulation by one physics step of ``dt`` seconds."""
        states = pb.getJointStates(self.robot, self._bullet_index, physicsClientId=self.client)
        q = np.array([s[0] for s in states])
        v = np.array([s[1] for s in states])
        v_set = self.controller.follow(self.time)
        # Forces besides motors and dampers, for the implicit step's prediction: the tools'
        # contacts of the last step (Bullet applies this step's itself) and the terrain-force
        # model's wrenches (applied below as joint torques).
        external = self.tracker.contact_torque(q)
        model_torque = None
        if self.force_model is not None:
            # The sample made below holds these very arrays: its snapshots reuse the frames.
            self.tracker.place(q, v)
            try:
                model_torque = self.tracker.apply_model(q, self.time, self.force_model)
            except DemRunError:  # the live DEM failed mid-dig and logged why: this step has no
                model_torque = None  # model wrench, the rest of the dig the model's fallback
            if model_torque is not None:
                external = model_torque if external is None else external + model_torque
        effort, damping = self.controller.control(q, v, v_set, external)
        self.sample = JointSample(
            self.time, self.names, q, v, effort, damping, self.controller.setpoint
        )
        applied = effort + damping
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
        # One query for the whole robot: only the tools touch anything.
        self.forces.add_contacts(pb.getContactPoints(bodyA=self.robot, physicsClientId=self.client))
        if self.time >= self._next_carve - 1e-9:
            self._next_carve = self.time + self.config.carve_period
            was_digging = self.tracker.dig.phase.digging
            self.tracker.update_digging(q, self.time)
            digging = self.tracker.dig.phase.digging
            if digging and not was_digging:
                self.regolith.start_dig()
                if self._dem_digs is not None:
                    self._dem_digs.dig_started()
            if self._dem_digs is not None:
                self.finished_dem_digs += (
                    (self.time, dig) for dig in self._dem_digs.update(was_digging and not digging)
                )
            self._carve()

    def _carve(self) -> None:
        """One carve update: the regolith follows the scoop (it collects in a dig, spills and
        pours outside one; poured on the terrain it raises it), then the terrain is lowered under
        the tools that reach it (:meth:`TerrainCarver.cut`), as far as it gives way to each
        (:meth:`ToolTracker.digs`), each cut told to the regolith."""
        carver, tracker, regolith = self.carver, self.tracker, self.regolith
        digging = tracker.dig.phase.digging
        if regolith.scoop_active(digging):  # else nothing to collect or spill: skip the pose
            state = pb.getLinkState(self.robot, self._regolith_scoop, physicsClientId=self.client)
            X_base_scoop = np.eye(4)
            X_base_scoop[:3, :3] = np.asarray(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3)
            X_base_scoop[:3, 3] = state[4]
            deposit = regolith.scoop_moved(X_base_scoop, digging)
            if deposit:
                carver.raise_cells(deposit.rows, deposit.cols, deposit.raise_m)
        for tool, link in self._tool_links.items():
            low, high = pb.getAABB(self.robot, link, physicsClientId=self.client)
            if not carver.reaches(low, high):
                continue
            state = pb.getLinkState(self.robot, link, physicsClientId=self.client)
            rotation = np.asarray(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3)
            normal_force = self.forces.normal_force(tool)
            cut = carver.cut(tool, rotation, np.asarray(state[4]), normal_force, tracker.digs(tool))
            if cut is not None:
                regolith.terrain_cut(tool, cut, digging)
        carver.commit()

    # ------------------------------------------------------------------ outputs
    @property
    def dig_phase(self) -> DigPhase:
        """The scoop's dig phase (decided at each carve update)."""
        return self.tracker.dig.phase

    @property
    def terrain_version(self) -> int:
        """Incremented whenever the terrain changes (carving or replacement)."""
        return self.carver.version

    @property
    def heightmap(self) -> HeightMap:
        """A copy of the current (carved) terrain."""
        return self.carver.heightmap

    def terrain_height(self, x: float, y: float) -> float:
        """m, current terrain height at (x, y) in base_link (bilinear in the height map)."""
        return self.carver.height_at(x, y)

    def link_poses(self, q: FloatArray | None = None) -> dict[str, FloatArray]:
        """(4, 4) pose in base_link of every link, at joint positions q (default: the sample's)."""
        return self.tracker.link_poses(self.sample.position if q is None else q)

    def tool_snapshot(self, tool: str) -> ToolSnapshot:
        """The tool now; the mean force and torque since the previous snapshot of this tool."""
        return self.tracker.snapshot(tool, self.sample, self.time, self.force_model is None)

    def wrist_wrench(self) -> tuple[FloatArray, FloatArray]:
        """The wrist force/torque sensor at ``j_dist_pitch``, compensated for the weight and
        inertia of the links beyond it (the external wrench on them): force N and torque N m
        about the joint, in ``l_dist`` (:meth:`ToolTracker.wrist_wrench`), with the injected
        sensor faults (:class:`~ow_sim_bullet.faults.WristFaults`)."""
        force, torque = self.tracker.wrist_wrench(self.sample)
        return self.wrist_faults.apply(force, torque, self.steps)

    def gravity_torque(self, q: FloatArray) -> FloatArray:
        """N m, gravity torques (our joint order) at positions q (rad), from pinocchio."""
        return self.controller.gravity_torque(q)

    def close(self) -> None:
        """Disconnect from pybullet."""
        if pb.isConnected(physicsClientId=self.client):
            pb.disconnect(physicsClientId=self.client)
