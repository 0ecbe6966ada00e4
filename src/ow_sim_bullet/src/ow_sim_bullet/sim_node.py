"""ROS wiring of the simulation: parameters, topics, services and the simulation thread."""

from __future__ import annotations

import io
import struct
import threading
import time
import warnings
from collections import deque
from collections.abc import Callable
from functools import partial
from typing import Any, TypeVar

import rospy
import rospy.impl.simtime
import tf2_ros
from geometry_msgs.msg import PointStamped, WrenchStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger, TriggerRequest, TriggerResponse
from tf2_msgs.msg import TFMessage

from ow_lander.description import URDF_PATH
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_msgs.msg import ToolState as ToolStateMsg
from ow_msgs.srv import (
    SetPidGains,
    SetPidGainsRequest,
    SetPidGainsResponse,
    SetTerrain,
    SetTerrainRequest,
    SetTerrainResponse,
    StepSimulation,
    StepSimulationRequest,
    StepSimulationResponse,
)
from ow_sim_bullet import conversions, wire
from ow_sim_bullet.config import CONTROLLER_NAMES, PidGains, SimConfig
from ow_sim_bullet.errors import CommandError, SimError
from ow_sim_bullet.sim_core import BulletSim, make_force_model
from ow_sim_bullet.terrains import parse_terrain_spec
from ow_sim_bullet.tool_tracking import TOOLS, WRIST_FT_LINK, ToolSnapshot
from ow_sim_bullet.trajectory import JointTrajectory

T = TypeVar("T")

_LENGTH = struct.Struct("<I")
#: physics steps whose outputs are written together when running faster than real time.
_FLUSH_STEPS = 4

#: s of wall time a service waits for the simulation thread before giving up.
_SERVICE_TIMEOUT = 60.0


class _Periodic:
    """Fires at a fixed rate of sim time, on the first step at or after each tick."""

    def __init__(self, rate_hz: float) -> None:
        self.period = 1.0 / rate_hz
        self.next_tick = 0.0

    def due(self, now: float) -> bool:
        if now + 1e-9 < self.next_tick:
            return False
        ticks = int((now + 1e-9) / self.period) + 1
        self.next_tick = ticks * self.period
        return True


def _genpy_payload(seq: int, build: Callable[..., Any], *args: Any) -> bytes:
    """The payload of the genpy message ``build(*args)``, its header's seq set to ``seq`` (as
    ``rospy.msg.serialize_message`` does)."""
    msg = build(*args)
    if getattr(msg.__class__, "_has_header", False):
        msg.header.seq = seq
    buffer = io.BytesIO()
    msg.serialize(buffer)
    return buffer.getvalue()


class _WirePublisher:
    """A rospy publisher (queue_size None) that sends payloads serialised by :mod:`.wire` (or
    by genpy, :func:`_genpy_payload`, for the low-rate messages).

    rospy's ``publish()`` costs ~8 us of Python a message on top of genpy's serialisation. This
    frames the payloads (length prefix) and writes them to the publisher's connections the way
    ``rospy.topics._PublisherImpl.publish`` does (rospy 1.15, the last ROS 1 release: its
    ``publock``, ``seq``, ``connections``). Registration, connection handshakes and
    ``get_num_connections`` stay rospy's.

    Messages are queued by :meth:`publish` and written by :meth:`flush`, all queued messages
    in one socket write: a loopback TCP write that wakes the subscriber costs 20-50 us of the
    simulation thread on a busy machine, much more than the message. TCPROS is a stream of
    length-prefixed messages, so subscribers receive exactly the same messages.

    Args:
        name: topic name.
        data_class: message class (for the connection headers: type and md5sum).
    """

    def __init__(self, name: str, data_class: type) -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SyntaxWarning)
            self.publisher = rospy.Publisher(name, data_class, queue_size=None)
        self._impl = self.publisher.impl
        self._pending: list[bytes] = []

    def publish(self, serialize: Callable[..., bytes], *args: Any) -> None:
        """Queue ``serialize(seq, *args)`` for the subscribers (not built if there is none)."""
        impl = self._impl
        if not impl.connections:
            return
        with impl.publock:
            impl.seq += 1
            payload = serialize(impl.seq, *args)
            self._pending += (_LENGTH.pack(len(payload)), payload)

    def flush(self) -> None:
        """Write the queued messages to every subscriber (blocks while a subscriber lags)."""
        if not self._pending:
            return
        impl = self._impl
        with impl.publock:
            data = b"".join(self._pending)
            self._pending.clear()
            if impl.closed or rospy.is_shutdown():
                return
            for connection in list(impl.connections):
                try:
                    connection.write_data(data)
                except Exception as error:  # what rospy does: drop the connection
                    rospy.logdebug(f"sim: dropping a subscriber of {impl.resolved_name}: {error}")
                    try:
                        connection.close()
                    except Exception as close_error:
                        rospy.logdebug(f"sim: closing it failed too: {close_error}")
            impl.message_data_sent += len(data)


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
        /arm_end_effector_force_torque (geometry_msgs/WrenchStamped): the wrist force/torque
            sensor of later OceanWATERS at j_dist_pitch, tared (gravity of the distal links not
            included): the tools' external wrench, N and N m about the joint, in l_dist, at
            ``~wrench_rate_hz``.
        /sim/scoop_tip_ground (geometry_msgs/PointStamped): base_link x, y of l_scoop_tip and
            z = true terrain height there (m), at ``~wrench_rate_hz``.
        /sim/scoop_state, /sim/grinder_state (ow_msgs/ToolState): at ``~tool_state_rate_hz``.
        /sim/scoop_model_state, /sim/grinder_model_state (ow_msgs/ToolState): with each tool
            state (same stamp), the state the terrain-force model was given in that step (the
            tool state's depth is measured after the step and differs when it carved the
            terrain ahead of the tip); depth 0 when no model ran.
        /sim/scoop_model_wrench, /sim/grinder_model_wrench (geometry_msgs/WrenchStamped): same
            stamp, the model's wrench applied in that step for that state: N and N m in the tool
            link frame about the link COM; zero when no model ran (no model, or tool above the
            surface).
        /sim/terrain (ow_msgs/HeightMap, latched): the terrain; republished after carving at
            most every ``~terrain_publish_period`` s of wall time.

    Subscriptions:
        /<controller>_position_controller/command (std_msgs/Float64): rad, set-point of one joint
            (controllers shou_yaw, shou_pitch, prox_pitch, dist_pitch, hand_yaw, scoop_yaw,
            grinder_yaw, ant_pan, ant_tilt); cancels that joint's trajectory.
        /sim/joint_trajectory (trajectory_msgs/JointTrajectory): interpolated by the sim; a zero
            header stamp starts it on arrival, else at that sim time.

    Services (std_srvs/Trigger unless given):
        ~reset: joints back to ``~initial_positions`` (stowed), at rest, trajectories cleared.
        ~pause, ~resume: stop and restart the clock.
        ~step (ow_msgs/StepSimulation): advance a paused simulation by N physics steps.
        ~set_pid_gains (ow_msgs/SetPidGains): change one joint's gains now.
        ~set_terrain (ow_msgs/SetTerrain): replace the terrain (spec as ``~terrain``).

    Parameters: see :class:`ow_sim_bullet.config.SimConfig` and docs/simulation.md.
    """

    def __init__(self, config: SimConfig) -> None:
        self.config = config
        heightmap = self._parse_terrain(config.terrain)
        self.sim = BulletSim(
            config, heightmap, make_force_model(config.terrain_forces, config.terrain_force_params)
        )
        if self.sim.corrected_inertias:
            rospy.logwarn(
                "inertia tensors of %s break the triangle inequality (Bullet would zero them); "
                "added the smallest isotropic inertia that makes them physical",
                ", ".join(self.sim.corrected_inertias),
            )
        self._frames = [
            f for f in conversions.joint_frames(URDF_PATH.read_text()) if f.axis is not None
        ]
        self._frame_joint_index = [self.sim.names.index(f.joint) for f in self._frames]
        self._joint_state_wire = wire.JointStateWire(self.sim.names)
        self._tf_wire = wire.TfWire(self._frames, self._frame_joint_index)
        self._tool_wire = {tool: wire.StampedWire(link) for tool, (link, _) in TOOLS.items()}
        self._base_wire = wire.StampedWire("base_link")
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._queue: deque[Callable[[], None]] = deque()
        self._paused = config.start_paused
        self._shutdown = False

        # High-rate outputs publish synchronously (queue_size None): rospy's queued publishing
        # hands every message to a writer thread, which costs ~110 us a message, and the
        # simulator runs at tens of times real time. A subscriber that cannot keep up slows the
        # simulation down instead of losing messages. They are serialised by .wire.
        self._clock_pub = _WirePublisher("/clock", Clock)
        self._joint_pub = _WirePublisher("/joint_states", JointState)
        self._damping_pub = _WirePublisher("~joint_damping", JointState)
        self._tf_pub = _WirePublisher("/tf", TFMessage)
        self._wrench_pubs = {
            tool: _WirePublisher(f"~{tool}_wrench", WrenchStamped) for tool in TOOLS
        }
        self._tip_ground_pub = _WirePublisher("~scoop_tip_ground", PointStamped)
        self._wrist_pub = _WirePublisher("/arm_end_effector_force_torque", WrenchStamped)
        self._wrist_wire = wire.StampedWire(WRIST_FT_LINK)
        # The tool states are genpy messages (10 Hz), written with the others.
        self._tool_pubs = {tool: _WirePublisher(f"~{tool}_state", ToolStateMsg) for tool in TOOLS}
        self._model_state_pubs = {
            tool: _WirePublisher(f"~{tool}_model_state", ToolStateMsg) for tool in TOOLS
        }
        self._model_wrench_pubs = {
            tool: _WirePublisher(f"~{tool}_model_wrench", WrenchStamped) for tool in TOOLS
        }
        #: in the order their queued messages are written: /clock first.
        self._wire_pubs = [
            self._clock_pub,
            self._joint_pub,
            self._damping_pub,
            self._tf_pub,
            *self._wrench_pubs.values(),
            self._tip_ground_pub,
            self._wrist_pub,
            *self._tool_pubs.values(),
            *self._model_state_pubs.values(),
            *self._model_wrench_pubs.values(),
        ]
        self._unflushed_steps = 0
        #: s of sim time of the last /clock message queued, and of the node's rospy time.
        self._clock_time = self._rostime = -1.0
        self._terrain_pub = rospy.Publisher("~terrain", HeightMapMsg, queue_size=1, latch=True)
        # With /use_sim_time rospy subscribes every node to /clock, this one too. The sim is the
        # clock: it sets rospy's time itself rather than receive its own /clock over TCP, a
        # thread waking up and taking the GIL from the simulation thread at every tick.
        own_clock = getattr(rospy.impl.simtime, "_clock_sub", None)
        self._sets_rostime = own_clock is not None
        if own_clock is not None:
            own_clock.unregister()
        self._static_tf = tf2_ros.StaticTransformBroadcaster()
        self._static_tf.sendTransform(
            [
                conversions.transform_msg(f, 0.0, 0.0)
                for f in conversions.joint_frames(URDF_PATH.read_text())
                if f.axis is None
            ]
        )
        self._publish_terrain()

        self._clock_tick = _Periodic(config.clock_rate_hz)
        self._joint_tick = _Periodic(config.joint_state_rate_hz)
        self._tf_tick = _Periodic(config.tf_rate_hz)
        self._wrench_tick = _Periodic(config.wrench_rate_hz)
        self._tool_tick = _Periodic(config.tool_state_rate_hz)
        self._snapshots: dict[str, ToolSnapshot] = {}
        self._terrain_published_version = self.sim.terrain_version
        self._terrain_published_wall = time.monotonic()

        for joint, controller in CONTROLLER_NAMES.items():
            rospy.Subscriber(
                f"/{controller}_position_controller/command",
                Float64,
                partial(self._on_setpoint, joint),
                queue_size=10,
            )
        try:
            from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg
        except ImportError:
            rospy.logerr(
                "sim: ~joint_trajectory is disabled: trajectory_msgs is not installed "
                "(apt package python3-trajectory-msgs)"
            )
        else:
            rospy.Subscriber(
                "~joint_trajectory", JointTrajectoryMsg, self._on_trajectory, queue_size=10
            )
        rospy.Service("~reset", Trigger, self._on_reset)
        rospy.Service("~pause", Trigger, self._on_pause)
        rospy.Service("~resume", Trigger, self._on_resume)
        rospy.Service("~step", StepSimulation, self._on_step)
        rospy.Service("~set_pid_gains", SetPidGains, self._on_set_gains)
        rospy.Service("~set_terrain", SetTerrain, self._on_set_terrain)
        self._thread = threading.Thread(target=self._run, name="sim", daemon=True)

    def _parse_terrain(self, spec: str) -> Any:
        c = self.config
        return parse_terrain_spec(
            spec, c.terrain_file_resolution, c.terrain_file_center, c.terrain_png_height_range
        )

    # ------------------------------------------------------------------ callbacks
    def _enqueue(self, command: Callable[[], None]) -> None:
        with self._wake:
            self._queue.append(command)
            self._wake.notify()

    def _call(self, command: Callable[[], T], timeout_s: float = _SERVICE_TIMEOUT) -> T:
        """Run ``command`` on the simulation thread and return its result (or raise its error)."""
        done = threading.Event()
        result: dict[str, Any] = {}

        def run() -> None:
            try:
                result["value"] = command()
            except Exception as error:
                result["error"] = error
            finally:
                done.set()

        self._enqueue(run)
        deadline = time.monotonic() + timeout_s
        while not done.wait(0.1):
            if rospy.is_shutdown() or self._shutdown or time.monotonic() > deadline:
                msg = "the simulation thread did not answer (shutting down or stalled)"
                raise SimError(msg)
        if "error" in result:
            raise result["error"]
        return result["value"]

    def _on_setpoint(self, joint: str, msg: Float64) -> None:
        def apply() -> None:
            try:
                self.sim.set_setpoint(joint, msg.data)
            except CommandError as error:
                rospy.logerr_throttle(1.0, f"sim: {error}")

        self._enqueue(apply)

    def _on_trajectory(self, msg: Any) -> None:
        velocities = None
        if msg.points and all(len(p.velocities) for p in msg.points):
            velocities = [list(p.velocities) for p in msg.points]
        elif any(len(p.velocities) for p in msg.points):
            rospy.logerr("sim: trajectory ignored: give velocities on every point or on none")
            return
        start = msg.header.stamp.to_sec()

        def apply() -> None:
            try:
                trajectory = JointTrajectory.build(
                    msg.joint_names,
                    start if start > 0 else self.sim.time,
                    [p.time_from_start.to_sec() for p in msg.points],
                    [list(p.positions) for p in msg.points],
                    velocities,
                    self.sim.names,
                )
            except CommandError as error:
                rospy.logerr(f"sim: trajectory ignored: {error}")
                return
            self.sim.set_trajectory(trajectory)

        self._enqueue(apply)

    def _on_reset(self, _: TriggerRequest) -> TriggerResponse:
        try:
            self._call(self.sim.reset)
        except SimError as error:
            return TriggerResponse(success=False, message=str(error))
        return TriggerResponse(
            success=True, message=f"joints reset at sim time {self.sim.time:.3f} s"
        )

    def _on_pause(self, _: TriggerRequest) -> TriggerResponse:
        with self._wake:
            was = self._paused
            self._paused = True
        return TriggerResponse(success=True, message="already paused" if was else "paused")

    def _on_resume(self, _: TriggerRequest) -> TriggerResponse:
        with self._wake:
            was = self._paused
            self._paused = False
            self._wake.notify()
        return TriggerResponse(success=True, message="resumed" if was else "already running")

    def _on_step(self, request: StepSimulationRequest) -> StepSimulationResponse:
        if request.steps == 0:
            return StepSimulationResponse(False, "steps must be > 0", self.sim.time)
        with self._wake:
            if not self._paused:
                return StepSimulationResponse(
                    False, "the simulation is running; call ~pause first", self.sim.time
                )

        def take_steps() -> float:
            for _ in range(request.steps):
                self._advance()
            self._flush()
            return self.sim.time

        try:
            sim_time = self._call(take_steps, _SERVICE_TIMEOUT + 0.01 * request.steps)
        except SimError as error:
            return StepSimulationResponse(False, str(error), self.sim.time)
        return StepSimulationResponse(True, f"stepped {request.steps} steps", sim_time)

    def _on_set_gains(self, request: SetPidGainsRequest) -> SetPidGainsResponse:
        values = {"p": request.p, "i": request.i, "d": request.d, "i_clamp": request.i_clamp}
        try:
            gains = PidGains.from_dict(values, f"gains of {request.joint}")
            self._call(partial(self.sim.set_gains, request.joint, gains))
        except SimError as error:
            return SetPidGainsResponse(success=False, message=str(error))
        return SetPidGainsResponse(
            success=True,
            message=f"{request.joint}: p {gains.p} i {gains.i} d {gains.d} i_clamp {gains.i_clamp}",
        )

    def _on_set_terrain(self, request: SetTerrainRequest) -> SetTerrainResponse:
        try:
            heightmap = self._parse_terrain(request.terrain)

            def install() -> None:
                self.sim.set_terrain(heightmap)
                self._publish_terrain()

            self._call(install)
        except SimError as error:
            return SetTerrainResponse(success=False, message=str(error))
        return SetTerrainResponse(success=True, message=f"terrain is now {request.terrain}")

    # ------------------------------------------------------------------ simulation thread
    def start(self) -> None:
        """Start the simulation thread."""
        self._thread.start()

    def stop(self) -> None:
        """Stop the simulation thread and pybullet."""
        with self._wake:
            self._shutdown = True
            self._wake.notify()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self.sim.close()

    def _run(self) -> None:
        try:
            self._loop()
        except Exception as error:  # a bug: log it loudly, then take the node down
            rospy.logfatal(f"sim: simulation thread failed: {error!r}")
            rospy.signal_shutdown("simulation thread failed")
            raise

    def _loop(self) -> None:
        rtf = self.config.real_time_factor
        pace_wall = time.monotonic()
        pace_sim = self.sim.time
        self._publish(force=True)
        self._flush()
        while not rospy.is_shutdown():
            with self._wake:
                while not self._shutdown and not self._queue and self._paused:
                    self._wake.wait(timeout=0.1)
                    self._publish_terrain_if_due()
                if self._shutdown:
                    return
                commands = list(self._queue)
                self._queue.clear()
                paused = self._paused
            for command in commands:
                command()
            if paused:
                self._flush()
                pace_wall, pace_sim = time.monotonic(), self.sim.time
                continue
            self._advance()
            if rtf > 0:
                ahead = (self.sim.time - pace_sim) / rtf - (time.monotonic() - pace_wall)
                if ahead > 0:
                    self._flush()
                    time.sleep(ahead)
                elif ahead < -0.5:
                    # Too slow to keep up: do not try to catch up later.
                    pace_wall, pace_sim = time.monotonic(), self.sim.time

    def _publish(self, force: bool = False) -> None:
        """Publish what is due at the current sim time (messages are only built for subscribers)."""
        sim = self.sim
        now = sim.time
        if self._clock_tick.due(now) or force:
            self._clock_pub.publish(wire.clock, now)
            self._clock_time = now
        sample = sim.sample
        t = sample.time
        if self._joint_tick.due(t) or force:
            joint_state = self._joint_state_wire
            position, velocity = sample.position, sample.velocity
            self._joint_pub.publish(joint_state, t, position, velocity, sample.effort)
            self._damping_pub.publish(joint_state, t, position, velocity, sample.damping_effort)
        if self._tf_tick.due(t) or force:
            self._tf_pub.publish(self._tf_wire, t, sample.position)
        if self._wrench_tick.due(t) or force:
            # Snapshots are taken even without subscribers: they reset the force averages.
            for tool, publisher in self._wrench_pubs.items():
                snapshot = sim.tool_snapshot(tool)
                self._snapshots[tool] = snapshot
                publisher.publish(
                    self._tool_wire[tool].wrench, snapshot.time, snapshot.force, snapshot.torque
                )
            wrist_force, wrist_torque = sim.wrist_wrench()
            self._wrist_pub.publish(self._wrist_wire.wrench, t, wrist_force, wrist_torque)
            scoop = self._snapshots["scoop"]
            self._tip_ground_pub.publish(
                self._base_wire.point,
                scoop.time,
                float(scoop.tip[0]),
                float(scoop.tip[1]),
                scoop.terrain_z,
            )
        if self._tool_tick.due(sample.time) or force:
            for publishers, build in (
                (self._tool_pubs, conversions.tool_state_msg),
                (self._model_state_pubs, conversions.model_state_msg),
                (self._model_wrench_pubs, conversions.model_wrench_msg),
            ):
                for tool, publisher in publishers.items():
                    if tool in self._snapshots:
                        publisher.publish(_genpy_payload, build, self._snapshots[tool])
        self._publish_terrain_if_due()

    def _advance(self) -> None:
        """One physics step and its outputs (written every ``_FLUSH_STEPS`` steps)."""
        self.sim.step()
        self._publish()
        self._unflushed_steps += 1
        if self._unflushed_steps >= _FLUSH_STEPS:
            self._flush()

    def _flush(self) -> None:
        """Write the queued high-rate messages; the node's own rospy time follows the /clock
        written (set here rather than at every tick: rospy's setter costs ~10 us)."""
        self._unflushed_steps = 0
        if self._sets_rostime and self._clock_time != self._rostime:
            rospy.rostime._set_rostime(rospy.Time(*conversions.stamp_parts(self._clock_time)))
            self._rostime = self._clock_time
        for publisher in self._wire_pubs:
            publisher.flush()

    def _publish_terrain_if_due(self) -> None:
        if self.sim.terrain_version == self._terrain_published_version:
            return
        if time.monotonic() - self._terrain_published_wall < self.config.terrain_publish_period:
            return
        self._publish_terrain()

    def _publish_terrain(self) -> None:
        self._terrain_published_version = self.sim.terrain_version
        self._terrain_published_wall = time.monotonic()
        self._terrain_pub.publish(conversions.heightmap_msg(self.sim.heightmap, self.sim.time))


def main() -> None:
    """Entry point of ``rosrun ow_sim_bullet sim``."""
    rospy.init_node("sim")
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
    rospy.spin()
