"""ROS wiring of the simulation: parameters, topics, services and the simulation thread."""

from __future__ import annotations

import threading
import warnings
from typing import Any

import rospy
import rospy.impl.simtime
from std_srvs.srv import Trigger, TriggerResponse

from ow_dem_bridge.api import REMOTE_MODEL_NAME, LockstepModel
from ow_dem_bridge.remote_node import make_remote_model
from ow_description.description import SCOOP_TIP_FRAME, URDF_PATH
from ow_description.terrain import HeightMap
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_msgs.msg import ScoopDigPhase
from ow_msgs.srv import SetTerrain, SetTerrainResponse, StepSimulation, StepSimulationResponse
from ow_runtime.latched import latched_publisher, static_transform_broadcaster
from ow_runtime.node import init_node, spin
from ow_sim_bullet import conversions, outputs, wire
from ow_sim_bullet.commands_node import SimCommands
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.errors import SimError
from ow_sim_bullet.lockstep_node import LockstepServer
from ow_sim_bullet.reconfigure_node import SimReconfigure
from ow_sim_bullet.regolith_node import (
    DemDigsServer,
    RegolithServer,
    budget_publisher,
    dem_digs_publisher,
)
from ow_sim_bullet.runner import SimRunner
from ow_sim_bullet.sim_core import BulletSim, make_force_model
from ow_sim_bullet.terrains import parse_terrain_spec
from ow_sim_bullet.tool_tracking import DigPhase


class SimNode:
    """The ``sim`` node: the lander arm in pybullet, driven like OceanWATERS' Gazebo.

    Publications:
        /clock (rosgraph_msgs/Clock): sim time, at ``~clock_rate_hz``.
        /joint_states (sensor_msgs/JointState): the 9 joints at ``~joint_state_rate_hz``:
            position rad, velocity rad/s, effort N m = the controller torque applied.
        /sim/joint_damping (sensor_msgs/JointState): same stamps; effort N m = the passive
            joint-damping torque applied (its power, effort * velocity, is dissipated).
        /tf (tf2_msgs/TFMessage): every movable joint's link, at ``~tf_rate_hz``.
        /tf_static (tf2_msgs/TFMessage): fixed frames (l_scoop_tip, l_grinder_tip, sample dock).
        /sim/scoop_wrench, /sim/grinder_wrench (geometry_msgs/WrenchStamped): mean contact and
            terrain-model force N and torque N m on the tool since the previous message, in the
            tool link frame about its origin, at ``~wrench_rate_hz``.
        /arm_end_effector_force_torque (owl_msgs/ArmEndEffectorForceTorque): the wrist force/torque
            sensor of later OceanWATERS at j_dist_pitch, tared (gravity of the distal links not
            included): the tools' external wrench, N and N m about the joint, in l_dist, at
            ``~wrench_rate_hz``.
        /sim/scoop_tip_ground (geometry_msgs/PointStamped): base_link x, y of l_scoop_tip and
            z = true terrain height there (m), at ``~wrench_rate_hz``.
        /sim/scoop_state, /sim/grinder_state (ow_msgs/ToolState): at ``~tool_state_rate_hz``.
        /sim/scoop_model_state, /sim/grinder_model_state (ow_msgs/ToolState): same stamp, the
            state the terrain-force model was given in that step (depth 0: no model ran).
        /sim/scoop_model_wrench, /sim/grinder_model_wrench (geometry_msgs/WrenchStamped): same
            stamp, the model's wrench of that step, N and N m in the tool link frame about its
            COM (zero when no model ran).
        /sim/terrain (ow_msgs/HeightMap, latched): the terrain; republished after carving at
            most every ``~terrain_publish_period`` s of simulation time.
        /ow_dynamic_terrain/scoop_dig_phase (ow_msgs/ScoopDigPhase, latched): the scoop's dig
            phase (OceanWATERS' topic and fields), NOT_DIGGING at start, then at each change;
            the terrain gives way to the scoop only while it digs.
        /flags/joint_states (ow_msgs/JointStatesFlag): locked joints, with /joint_states.
        /sim/dem_digs (ow_msgs/DemDig): with the live DEM (``terrain_forces: yade``), one
            message per dig when it ends or fails, stamped at the carve update that learnt it:
            its bed's spheres, exchanges, the sample (spheres in the scoop, m^3, kg) or the
            error.
    The regolith (/regolith/budget, /ground_truth/material_ingested, /sim/ingest_sample): see
    :class:`~ow_sim_bullet.regolith_node.RegolithServer`.
    Faults (``/faults/parameter_updates``) and PID gains (dynamic_reconfigure): see
    :class:`~ow_sim_bullet.reconfigure_node.SimReconfigure`.

    Commands (joint set-points, ``~joint_trajectory``) and their receipts: see
    :class:`~ow_sim_bullet.commands_node.SimCommands`.

    Subscriptions:
        /dem/scoop_wrench, /dem/grinder_wrench (geometry_msgs/WrenchStamped): with
            ``~terrain_forces: bridge`` only, the co-simulation's wrenches (ow_dem_bridge).

    Services (std_srvs/Trigger unless given):
        ~reset: joints back to ``~initial_positions`` (stowed), at rest, trajectories cleared.
        ~pause, ~resume: stop and restart the clock (~pause answers once all is out up to it).
        ~step (ow_msgs/StepSimulation): advance a paused simulation by N physics steps.
        ~set_pid_gains (ow_msgs/SetPidGains): change one joint's gains now (partial requests
            keep what they leave out; see SimReconfigure).
        ~set_terrain (ow_msgs/SetTerrain): replace the terrain (spec as ``~terrain``).
        /sim/dem_digs_between (ow_msgs/DemDigs): with the live DEM only, the /sim/dem_digs
            messages stamped within a window (the arm services ask after each execution).
    Lockstep: :class:`~ow_sim_bullet.lockstep_node.LockstepServer`, docs/determinism.md.

    Parameters: see :class:`ow_sim_bullet.config.SimConfig` and docs/simulation.md.
    """

    def __init__(self, config: SimConfig) -> None:
        self.config = config
        remote = (REMOTE_MODEL_NAME, make_remote_model)
        force_model = make_force_model(config.terrain_forces, config.terrain_force_params, remote)
        self.sim = BulletSim(config, self._parse_terrain(config.terrain), force_model)
        if self.sim.corrected_inertias:
            rospy.logwarn(
                "inertia tensors of %s break the triangle inequality (Bullet would zero them); "
                "added the smallest isotropic inertia that makes them physical",
                ", ".join(self.sim.corrected_inertias),
            )
        # Outputs publish synchronously (queue_size None): rospy's writer thread costs ~110 us a
        # message at tens of times real time. A subscriber that cannot keep up slows the
        # simulation down instead of losing messages.
        publishers = {topic: _batch_publisher(topic, cls) for topic, cls in outputs.WIRE_TOPICS}
        terrain = latched_publisher("~terrain", HeightMapMsg, queue_size=1)
        self._dig_phase = latched_publisher(outputs.DIG_PHASE_TOPIC, ScoopDigPhase, queue_size=1)
        # With /use_sim_time rospy subscribes every node to /clock, this one too. The sim sets its
        # rospy time itself instead: a thread receiving /clock would take the GIL at every tick.
        own_clock = getattr(rospy.impl.simtime, "_clock_sub", None)
        if own_clock is not None:
            own_clock.unregister()
        frames = conversions.joint_frames(URDF_PATH.read_text())
        self._static_tf = static_transform_broadcaster()
        self._static_tf.sendTransform(
            [conversions.transform_msg(f, 0.0, 0.0) for f in frames if f.axis is None]
        )
        on_clock = _set_rostime if own_clock is not None else None
        self.outputs = outputs.SimOutputs(
            self.sim,
            config,
            publishers,
            terrain,
            frames,
            on_clock,
            self._publish_dig_phase,
            budget_publisher(),
            dem_digs_publisher(),
        )
        self.outputs.publish_terrain()
        self.outputs.publish_dig_phase()
        self.outputs.publish_budget()
        rtf, paused = config.real_time_factor, config.start_paused
        self.runner = SimRunner(
            self.sim, self.outputs, rtf, paused, rospy.is_shutdown, rospy.logerr
        )
        self.commands = SimCommands(self.runner)  # set-points, trajectories, their receipts
        rospy.Service("~reset", Trigger, self._on_reset)
        rospy.Service("~pause", Trigger, self._on_pause)
        rospy.Service("~resume", Trigger, self._on_resume)
        rospy.Service("~step", StepSimulation, self._on_step)
        rospy.Service("~set_terrain", SetTerrain, self._on_set_terrain)
        self.reconfigure = SimReconfigure(self.runner)  # faults, PID gains, ~set_pid_gains
        self.lockstep = LockstepServer(self.runner, config.lockstep_clients)
        self.regolith = RegolithServer(self.runner, self.outputs)  # /sim/ingest_sample
        if isinstance(force_model, LockstepModel):  # /sim/dem_digs_between
            self.dem_digs = DemDigsServer(self.runner)
        self._thread = threading.Thread(target=self._run, name="sim", daemon=True)

    def _parse_terrain(self, spec: str) -> HeightMap:
        c = self.config
        return parse_terrain_spec(
            spec, c.terrain_file_resolution, c.terrain_file_center, c.terrain_png_height_range
        )

    def _publish_dig_phase(self, sim_time: float, phase: DigPhase) -> None:
        """Publish the scoop's dig phase (on the simulation thread, at a change)."""
        msg = ScoopDigPhase(digging=phase.digging, phase=int(phase))
        msg.header.stamp = rospy.Time(*conversions.stamp_parts(sim_time))
        msg.header.frame_id = SCOOP_TIP_FRAME
        self._dig_phase.publish(msg)

    # ------------------------------------------------------------------ callbacks
    def _on_reset(self, _: Any) -> TriggerResponse:
        try:
            self.runner.call(self.sim.reset)
        except SimError as error:
            return TriggerResponse(success=False, message=str(error))
        return TriggerResponse(True, f"joints reset at sim time {self.sim.time:.3f} s")

    def _on_pause(self, _: Any) -> TriggerResponse:
        try:
            was = self.runner.pause_standing()
        except SimError as error:
            return TriggerResponse(success=False, message=str(error))
        return TriggerResponse(True, "already paused" if was else "paused")

    def _on_resume(self, _: Any) -> TriggerResponse:
        return TriggerResponse(True, "resumed" if self.runner.resume() else "already running")

    def _on_step(self, request: Any) -> StepSimulationResponse:
        try:
            sim_time = self.runner.step_paused(request.steps)
        except SimError as error:
            return StepSimulationResponse(False, str(error), self.sim.time)
        return StepSimulationResponse(True, f"stepped {request.steps} steps", sim_time)

    def _on_set_terrain(self, request: Any) -> SetTerrainResponse:
        try:
            self.runner.replace_terrain(self._parse_terrain(request.terrain), request.terrain)
        except SimError as error:
            return SetTerrainResponse(success=False, message=str(error))
        return SetTerrainResponse(success=True, message=f"terrain is now {request.terrain}")

    # ------------------------------------------------------------------ simulation thread
    def start(self) -> None:
        """Start the simulation thread."""
        self._thread.start()

    def stop(self) -> None:
        """Stop the simulation thread and pybullet."""
        self.runner.stop()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self.sim.close()

    def _run(self) -> None:
        try:
            self.runner.run()
        except Exception as error:  # a bug: log it loudly, then take the node down
            rospy.logfatal(f"sim: simulation thread failed: {error!r}")
            rospy.signal_shutdown("simulation thread failed")
            raise


def _batch_publisher(topic: str, data_class: type) -> wire.BatchPublisher:
    """A rospy publisher of ``topic`` (queue_size None) written in batches."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SyntaxWarning)
        publisher = rospy.Publisher(topic, data_class, queue_size=None)
    return wire.BatchPublisher(publisher, rospy.is_shutdown, rospy.logdebug)


def _set_rostime(sim_time: float) -> None:
    """Set this node's rospy time to ``sim_time`` (s)."""
    rospy.rostime._set_rostime(rospy.Time(*conversions.stamp_parts(sim_time)))


def main() -> None:
    """Entry point of ``rosrun ow_sim_bullet sim``."""
    init_node("sim")
    try:
        config = SimConfig.from_dict(rospy.get_param("~", {}))
        node = SimNode(config)
    except SimError as error:
        rospy.logfatal(f"sim: cannot start: {error}")
        raise SystemExit(1) from error
    rospy.on_shutdown(node.stop)
    node.start()
    rospy.loginfo(
        "sim: running at %.0f Hz physics, real-time factor %s, terrain %s",
        config.physics_rate_hz,
        config.real_time_factor,
        config.terrain,
    )
    spin()
