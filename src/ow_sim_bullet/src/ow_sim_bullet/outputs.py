"""What the simulation node publishes after each physics step, and when.

:class:`SimOutputs` decides which outputs are due at the sample's sim time, builds their payloads
from the simulation (wire serialisers for the high-rate ones, genpy messages for the rest) and
queues them on publishers it is given: anything with ``publish(serialize, *args)`` and
``flush()`` (:class:`ow_sim_bullet.wire.BatchPublisher` in the node, a recorder in tests). No
rospy here.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from typing import Any, Protocol

from geometry_msgs.msg import PointStamped, WrenchStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from ow_msgs.msg import JointStatesFlag
from ow_msgs.msg import ToolState as ToolStateMsg
from ow_regolith.conversions import regolith_budget
from ow_runtime.names import (
    ARM_END_EFFECTOR_FORCE_TORQUE,
    CLOCK,
    FLAGS_JOINT_STATES,
    JOINT_STATES,
    TF,
)
from ow_sim_bullet import conversions, wire
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.conversions import JointFrame
from ow_sim_bullet.scheduling import Periodic, Throttle
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.tool_tracking import TOOLS, WRIST_FT_LINK, DigPhase, ToolSnapshot
from owl_msgs.msg import ArmEndEffectorForceTorque

#: physics steps whose outputs are written together when running faster than real time (a
#: socket write wakes the subscriber and costs more than the messages: bench/sim_speed.py held at
#: 84-85x with 4, 93-96x with 10, 102-104x with 25, 2026-11-25). Not more: the nodes' clocks then
#: jump by as much at once, and a rospy timer of 5 Hz (the action servers' status) fired in bursts
#: and resets with 25 (test_actions' status rate failed once in six suites). Paced, held by a
#: lockstep client (every 0.1 s of sim time by default), stepped or paused, they are written at
#: once.
FLUSH_STEPS = 10
#: physics steps whose outputs are written together to every subscriber while a lockstep client
#: is registered. The nodes a step waits for (:meth:`SimOutputs.flush` with ``only``) get them
#: each time it waits, every ~8 steps in a mission; the others (the recorder, the monitors) need
#: them only in order and whole: written to every subscriber at each wait, they cost the
#: simulation 3.4 of its 8.7 CPU-s in a mission (docs/history/performance-journal.md, eleventh
#: round).
LOCKSTEP_FLUSH_STEPS = 50

#: OceanWATERS' topic of the scoop's dig phase (ow_msgs/ScoopDigPhase, latched, at each change).
DIG_PHASE_TOPIC = "/ow_dynamic_terrain/scoop_dig_phase"

#: (topic, message class) of every output written with the wire publishers, in the order their
#: queued messages are written: /clock first.
WIRE_TOPICS: tuple[tuple[str, type], ...] = (
    (CLOCK, Clock),
    (JOINT_STATES, JointState),
    ("~joint_damping", JointState),
    # OceanWATERS' locked-joint flags (ow_faults), with every joint state.
    (FLAGS_JOINT_STATES, JointStatesFlag),
    (TF, TFMessage),
    *((f"~{tool}_wrench", WrenchStamped) for tool in TOOLS),
    ("~scoop_tip_ground", PointStamped),
    # OceanWATERS' type: Header + Wrench, the same bytes as a WrenchStamped.
    (ARM_END_EFFECTOR_FORCE_TORQUE, ArmEndEffectorForceTorque),
    *((f"~{tool}_state", ToolStateMsg) for tool in TOOLS),
    *((f"~{tool}_model_state", ToolStateMsg) for tool in TOOLS),
    *((f"~{tool}_model_wrench", WrenchStamped) for tool in TOOLS),
)


class WirePublisher(Protocol):
    """Queues serialised messages and writes them on :meth:`flush`."""

    def publish(self, serialize: Callable[..., bytes], *args: Any) -> None:
        """Queue the payload ``serialize(seq, *args)``."""
        ...

    def flush(self, only: Collection[str] | None = None) -> None:
        """Write the queued payloads (to the subscribers of the nodes ``only``: the others'
        wait for a flush for everyone)."""
        ...


class MessagePublisher(Protocol):
    """Publishes whole messages (the latched terrain, the regolith budget)."""

    def publish(self, msg: Any) -> None:
        """Publish ``msg``."""
        ...


class SimOutputs:
    """The node's outputs of one simulation.

    Args:
        sim: the simulation (read on the simulation thread only).
        config: rates and the terrain's republication period.
        publishers: one per topic of :data:`WIRE_TOPICS`.
        terrain: publisher of the ``ow_msgs/HeightMap`` of the terrain.
        frames: the URDF's joint frames; the movable ones go on /tf.
        on_clock: called with the sim time (s) of the last /clock written, when it changed, at
            each :meth:`flush` (the node sets its own ROS time), or None.
        on_dig_phase: called with the sim time (s) and the scoop's dig phase when it changes
            (and by :meth:`publish_dig_phase`), or None.
        budget: publisher of the ``ow_msgs/RegolithBudget`` of the regolith, at each change
            (a carve update or an ingestion changed an account; :meth:`publish_budget`), or None.
        dem_digs: publisher of an ``ow_msgs/DemDig`` for each dig of a live terrain-force
            model that ended or failed (``BulletSim.finished_dem_digs``), or None.
    """

    def __init__(
        self,
        sim: BulletSim,
        config: SimConfig,
        publishers: Mapping[str, WirePublisher],
        terrain: MessagePublisher,
        frames: Sequence[JointFrame],
        on_clock: Callable[[float], None] | None = None,
        on_dig_phase: Callable[[float, DigPhase], None] | None = None,
        budget: MessagePublisher | None = None,
        dem_digs: MessagePublisher | None = None,
    ) -> None:
        self.sim = sim
        self._dem_digs_pub = dem_digs
        self._on_dig_phase = on_dig_phase
        self._budget_pub = budget
        #: the regolith's version last published (-1: none yet).
        self._budget_version = -1
        #: the dig phase last told on_dig_phase.
        self._dig_phase = sim.dig_phase
        self._publishers = [publishers[topic] for topic, _ in WIRE_TOPICS]
        self._clock_pub = publishers[CLOCK]
        self._joint_pub = publishers[JOINT_STATES]
        self._damping_pub = publishers["~joint_damping"]
        self._flags_pub = publishers[FLAGS_JOINT_STATES]
        self._tf_pub = publishers[TF]
        self._wrench_pubs = {tool: publishers[f"~{tool}_wrench"] for tool in TOOLS}
        self._tip_ground_pub = publishers["~scoop_tip_ground"]
        self._wrist_pub = publishers[ARM_END_EFFECTOR_FORCE_TORQUE]
        tool_wires = {tool: wire.ToolWire(tool, link) for tool, (link, _) in TOOLS.items()}
        self._tool_pubs = [
            (
                {tool: publishers[f"~{tool}_{kind}"] for tool in TOOLS},
                {tool: getattr(tool_wires[tool], kind) for tool in TOOLS},
            )
            for kind in ("state", "model_state", "model_wrench")
        ]
        self._terrain_pub = terrain
        self._on_clock = on_clock
        moving = [f for f in frames if f.axis is not None]
        self._joint_state_wire = wire.JointStateWire(sim.names)
        self._flags_wire = wire.JointFlagsWire()
        self._tf_wire = wire.TfWire(moving, [sim.names.index(f.joint) for f in moving])
        self._tool_wire = {tool: wire.StampedWire(link) for tool, (link, _) in TOOLS.items()}
        self._base_wire = wire.StampedWire("base_link")
        self._wrist_wire = wire.StampedWire(WRIST_FT_LINK)
        self._clock_tick = Periodic(config.clock_rate_hz)
        self._joint_tick = Periodic(config.joint_state_rate_hz)
        self._tf_tick = Periodic(config.tf_rate_hz)
        self._wrench_tick = Periodic(config.wrench_rate_hz)
        self._tool_tick = Periodic(config.tool_state_rate_hz)
        # In simulation time: the terrains a bag holds are the same in every equal run.
        self._terrain_throttle = Throttle(config.terrain_publish_period, lambda: self.sim.time)
        #: the tools' last snapshots (the tool states are published from them).
        self.snapshots: dict[str, ToolSnapshot] = {}
        self._unflushed_steps = 0
        #: s of sim time, the stamp of the newest /joint_states queued (-1: none yet).
        self.joint_stamp = -1.0
        #: how many of the simulation's finished DEM digs went out.
        self._dem_digs_out = 0
        #: s, the stamp of the newest /sim/terrain published (-1: none yet).
        self.terrain_stamp = -1.0
        #: s of sim time of the last /clock message queued, and of the last one told on_clock.
        self._clock_time = self._told_time = -1.0

    def publish(self, force: bool = False) -> None:
        """Queue what is due at the current sim time (messages are only built for subscribers,
        but the tools' snapshots are taken anyway: they restart the force means); ``force``
        queues every output. Publishes the terrain if it is due."""
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
            self.joint_stamp = t
            self._damping_pub.publish(joint_state, t, position, velocity, sample.damping_effort)
            names, flags = sim.locks.flags()
            self._flags_pub.publish(self._flags_wire, t, names, flags)
        if self._tf_tick.due(t) or force:
            self._tf_pub.publish(self._tf_wire, t, sample.position)
        if self._wrench_tick.due(t) or force:
            for tool, publisher in self._wrench_pubs.items():
                snapshot = sim.tool_snapshot(tool)
                self.snapshots[tool] = snapshot
                publisher.publish(
                    self._tool_wire[tool].wrench, snapshot.time, snapshot.force, snapshot.torque
                )
            wrist_force, wrist_torque = sim.wrist_wrench()
            self._wrist_pub.publish(self._wrist_wire.wrench, t, wrist_force, wrist_torque)
            scoop = self.snapshots["scoop"]
            self._tip_ground_pub.publish(
                self._base_wire.point,
                scoop.time,
                float(scoop.tip[0]),
                float(scoop.tip[1]),
                scoop.terrain_z,
            )
        if self._tool_tick.due(sample.time) or force:
            for publishers, serializers in self._tool_pubs:
                for tool, publisher in publishers.items():
                    if tool in self.snapshots:
                        publisher.publish(serializers[tool], self.snapshots[tool])
        if sim.dig_phase is not self._dig_phase:
            self.publish_dig_phase()
        self.publish_budget_if_changed()
        if len(sim.finished_dem_digs) > self._dem_digs_out:
            for time_s, summary in sim.finished_dem_digs[self._dem_digs_out :]:
                if self._dem_digs_pub is not None:
                    self._dem_digs_pub.publish(conversions.dem_dig_msg(time_s, "scoop", summary))
            self._dem_digs_out = len(sim.finished_dem_digs)
        self.publish_terrain_if_due()

    def publish_dig_phase(self) -> None:
        """Tell ``on_dig_phase`` the scoop's dig phase now (the node: at start, so that the
        latched topic holds NOT_DIGGING from the beginning, as OceanWATERS')."""
        self._dig_phase = self.sim.dig_phase
        if self._on_dig_phase is not None:
            self._on_dig_phase(self.sim.time, self._dig_phase)

    def publish_budget(self) -> None:
        """Publish the regolith budget now (the node: at start, so that the latched topic holds
        it from the beginning; then at each change, by :meth:`publish`)."""
        regolith = self.sim.regolith
        self._budget_version = regolith.version
        if self._budget_pub is not None:
            self._budget_pub.publish(
                regolith_budget(
                    regolith.snapshot(),
                    regolith.database,
                    regolith.column,
                    conversions.stamp(self.sim.time),
                )
            )

    def publish_budget_if_changed(self) -> None:
        """Publish the regolith budget if it changed since its last publication: after each
        step (it changes at carve updates only) and after a command that changed it (an
        ingestion, also on a paused simulation)."""
        if self.sim.regolith.version != self._budget_version:
            self.publish_budget()

    def publish_standing(self, terrain: bool = True) -> None:
        """Where the simulation stops (paused, held by a lockstep client, after ``~step``):
        queue /clock at the current sim time unless it went out at that time already, so every
        node's clock reaches the time it stands at whatever ``clock_rate_hz`` is; with
        ``terrain``, publish the terrain if it changed since its last publication, whatever
        its wall-time throttle says, so that the terrain it stands on is recorded in every run
        alike (not where it only waits for an acknowledgement: when is a matter of load)."""
        now = self.sim.time
        if self._clock_time != now:
            self._clock_pub.publish(wire.clock, now)
            self._clock_time = now
        if terrain and self._terrain_throttle.changed(self.sim.terrain_version):
            self.publish_terrain()

    def after_step(self, lockstep: bool = False) -> None:
        """Queue the outputs of the step just taken; write them to every subscriber every
        :data:`FLUSH_STEPS` (with ``lockstep`` clients registered: every
        :data:`LOCKSTEP_FLUSH_STEPS`)."""
        self.publish()
        self._unflushed_steps += 1
        if self._unflushed_steps >= (LOCKSTEP_FLUSH_STEPS if lockstep else FLUSH_STEPS):
            self.flush()

    def flush(self, only: Collection[str] | None = None) -> None:
        """Write the queued messages, /clock first; tell ``on_clock`` the /clock written (once
        per flush rather than at every tick: setting rospy's time costs ~10 us).

        Args:
            only: write to the subscribers of these nodes (caller ids) only; the others get
                theirs at the next flush for everyone. None: everyone.
        """
        if only is None:
            self._unflushed_steps = 0
        if self._on_clock is not None and self._clock_time != self._told_time:
            self._on_clock(self._clock_time)
            self._told_time = self._clock_time
        for publisher in self._publishers:
            publisher.flush(only)

    def publish_terrain_if_due(self) -> None:
        """Publish the terrain if it changed and the last publication is old enough."""
        if self._terrain_throttle.due(self.sim.terrain_version):
            self.publish_terrain()

    def publish_terrain(self) -> None:
        """Publish the terrain now."""
        self._terrain_throttle.done(self.sim.terrain_version)
        msg = conversions.heightmap_msg(self.sim.heightmap, self.sim.time)
        self._terrain_pub.publish(msg)
        self.terrain_stamp = msg.header.stamp.to_sec()  # as written: sim.time rounded to 1 ns
