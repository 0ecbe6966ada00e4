"""The execution side of ``arm_services`` (rospy wiring only; a node module of the arm_services
node): trajectories go to the simulation, its observations to an
:class:`~ow_lander.execution.monitor.ExecutionMonitor`, whose decisions are published."""

from __future__ import annotations

import threading
import time

import rospy

from ow_description.model import LanderModel
from ow_description.trajectory import Trajectory
from ow_lander import conversions as conv
from ow_lander.arm_services.decisions import DecisionOutlet
from ow_lander.arm_services.delivery import TrajectoryDelivery
from ow_lander.arm_services.live_dem import LIVE_DEM_OPERATIONS, live_dem_failure
from ow_lander.arm_services.lock_flags import LockFlags, without_locks
from ow_lander.arm_services.observer import ArmObserver, SampleCallback
from ow_lander.arm_services.stop_clock import StopPause
from ow_lander.config import ExecutionConfig
from ow_lander.execution.monitor import (
    Decision,
    ExecutionMonitor,
    ExecutionResult,
    start_error,
    unknown_joints,
    with_settle_pause,
)
from ow_lander.fault_watch_node import FaultWatch
from ow_msgs.msg import GuardedMoveResult
from ow_runtime.clock_client import TrajectoryDeliveryError
from ow_runtime.latched import latched_publisher
from ow_runtime.names import GUARDED_MOVE_RESULT


class ArmExecutor(ArmObserver):
    """Executes trajectories on the simulation, watched on simulation time.

    Subscribes and publishes as :class:`~ow_lander.arm_services.observer.ArmObserver`, and
    Publishes: trajectories through :class:`~ow_lander.arm_services.delivery.TrajectoryDelivery`
        (interface ``trajectory``); the set-points (interface ``position_controllers``) and
        holds of its decisions through :class:`~ow_lander.arm_services.decisions.DecisionOutlet`;
        ``/guarded_move_result`` (ow_msgs/GuardedMoveResult, latched) once per guarded descent.
    Calls: ``/sim/pause``, ``/sim/resume`` (std_srvs/Trigger) around a delivery and a stop;
        ``/sim/lockstep_register`` once, when ``lockstep`` is set.
    Faults (:class:`~ow_lander.fault_watch_node.FaultWatch`): an execution stops and fails
        naming the fault when :meth:`~ow_lander.execution.fault_reaction.FaultReaction.stop_reason`
        says so (an arm execution error with ``arm_motion_continues_in_fault`` false).

    Args:
        config: the ``execution/*`` parameters.
        model: the lander, for the monitor's forward kinematics.
    """

    def __init__(self, config: ExecutionConfig, model: LanderModel) -> None:
        super().__init__(config.joint_state_timeout_s)
        self.config = config
        self.model = model
        self._stopped = threading.Event()
        self.delivery = TrajectoryDelivery(config, self)
        self._sim_clock = self.delivery.sim_clock
        self.result_pub = latched_publisher(GUARDED_MOVE_RESULT, GuardedMoveResult, queue_size=10)
        self.outlet = DecisionOutlet(config)
        self.faults = FaultWatch(self._on_fault_status)
        self._flags = LockFlags() if config.lockstep else None
        self._stop_requested = False  # by a user or the telemetry: braking goes out at once
        self.stop_pause = StopPause(self._sim_clock, self, config.delivery_wait_s)
        self._braking_sent = threading.Event()  # a requested stop's braking went out
        self._braking_confirmed = False  # and the simulation confirmed it has it
        if config.lockstep:
            self.start_joining_lockstep(config.lockstep_hold)

    def executing(self) -> bool:
        """Whether an execution runs now (a stop would stop it)."""
        with self._state_changed:
            return self._monitor is not None

    def settle(self) -> None:
        """With ``lockstep_hold``, after an execution: wait until the simulation stands where this
        node holds it (see :meth:`~ow_runtime.lockstep_client.LockstepClient.settle`)."""
        if self._lockstep is not None and self.config.lockstep_hold:
            self._lockstep.settle(self.joint_state_timeout_s)

    def _decides_locks(self) -> bool:
        """Whether the decisions act on the simulation's lock flags (in the lockstep: at the
        same simulation time in every run) rather than on the detector's HARDWARE status."""
        return self._flags is not None and self._lockstep is not None

    def _on_fault_status(self, stamp: float) -> None:
        """Stop the running execution, from the fault's stamp, when a fault says so (in a
        thread of its own: the stop waits for joint states)."""
        with self._state_changed:
            monitor = self._monitor
        if monitor is None or monitor.stop_time is not None:
            return
        reaction = self.faults.now()
        if self._decides_locks():
            reaction = without_locks(reaction)  # the decisions see the locks, stamp by stamp
        reason = reaction.stop_reason(monitor.watches_force)
        if reason is not None:
            threading.Thread(target=self.stop, args=(reason, stamp), daemon=True).start()

    # ------------------------------------------------------------------------------ execution
    def execute(
        self,
        trajectory: Trajectory,
        wrench_limits: tuple[float, float] | None = None,
        on_sample: SampleCallback | None = None,
        config: ExecutionConfig | None = None,
    ) -> ExecutionResult:
        """Execute ``trajectory`` and watch it until it ends (see
        :mod:`ow_lander.execution.monitor`); publish a guarded descent's result once.
        ``wrench_limits`` (N, N m): a guarded action's force/torque thresholds; ``on_sample``:
        called on every joint state meanwhile; ``config``: instead of the node's execution
        configuration (an action goal's constraints).

        Raises:
            PlanningError: no joint state to start from.
        """
        cfg = self.config if config is None else config
        refused = unknown_joints(trajectory) or start_error(trajectory, self.current_joints(), cfg)
        if refused is not None:
            return refused
        trajectory = with_settle_pause(trajectory, cfg)

        def watch(t_start: float) -> None:  # every joint state from now on goes to the monitor
            with self._state_changed:
                monitor = ExecutionMonitor(
                    trajectory, t_start, cfg, self.model, self._joints, wrench_limits
                )
                self._monitor, self._on_sample = monitor, on_sample
                self._pending.clear()
                self._stopped.clear()
                self._stop_requested = False
                # A fault that arrived while the trajectory was being delivered.
                fault = self.faults.now().stop_reason(monitor.watches_force)
                if fault is not None:
                    monitor.request_stop(self._joint_stamp, fault)

        if cfg.interface == "trajectory":
            try:  # watched from its start: the monitor is set before the clock runs on
                self.delivery.send(trajectory, watch)
            except TrajectoryDeliveryError as error:
                return ExecutionResult(False, str(error))
        else:
            with self._state_changed:
                t_start = self._joint_stamp + cfg.start_delay_s
            watch(t_start)
        monitor = self._monitor
        assert monitor is not None  # set by watch
        if self._lockstep is not None:  # the monitor sees every joint state from now on
            self._lockstep.release()
        try:
            result = self._follow(monitor)
        finally:
            with self._state_changed:
                self._monitor, self._on_sample = None, None
                if self._lockstep is not None:  # the joint states no decision was taken on
                    self._lockstep.ack(self._joint_stamp, force=True)
            self._stopped.set()
        if result.success and trajectory.operation in LIVE_DEM_OPERATIONS:
            # A dig during which the live DEM failed fails, with the DEM's reason.
            failure = live_dem_failure(monitor.t_start, monitor.t_start + result.duration)
            if failure is not None:
                result.success, result.message = False, failure
        standing = self.faults.now().arm_error()
        if not result.success and result.fault is None and standing is not None:
            result.message = f"{standing}: {result.message}"  # e.g. a tracking error it caused
        if result.reports_ground:
            found = result.contact_time
            stamp = rospy.Time.now() if found is None else rospy.Time(found)
            self.result_pub.publish(conv.guarded_move_result_msg(result, stamp))
        return result

    def _follow(self, monitor: ExecutionMonitor) -> ExecutionResult:
        """Give the monitor every joint state in order, however late this thread wakes up (the
        same states give the same decisions whatever the load), and carry out its decisions
        until it says the execution is over."""
        while not rospy.is_shutdown():

            def news() -> bool:
                stop = monitor.stop_time is not None and monitor.braking is None
                return bool(self._pending) or stop

            with self._state_changed:
                arrived = self._state_changed.wait_for(news, self.config.joint_state_timeout_s)
                if self._pending:
                    stamp, joints = self._pending.popleft()
                else:
                    stamp, joints = self._joint_stamp, dict(self._joints)
                if arrived:
                    self._wait_stream(monitor, stamp)
            flags = self._flags if self._decides_locks() else None
            if arrived and flags is not None and monitor.stop_time is None:
                fault = flags.stop_reason(
                    self.faults.now(), stamp, monitor.watches_force, self.joint_state_timeout_s
                )
                if fault is not None:  # a lock flagged with this state: brake from it
                    with self._state_changed:
                        monitor.request_stop(stamp, fault)
            with self._state_changed:
                unbraked = monitor.braking is None
                decision = monitor.decide(stamp, joints) if arrived else monitor.stalled()
                braking = unbraked and monitor.braking is not None
            now = braking and self._stop_requested  # the rest goes as every decision does
            if now:
                decision = self._deliver_braking(decision)
            self.outlet.apply(decision, stamp, self._lockstep, now=now)
            if braking:
                self._braking_sent.set()
            if decision.result is not None:
                return decision.result
        return ExecutionResult(False, "shutting down")

    def _deliver_braking(self, decision: Decision) -> Decision:
        """Send a requested stop's braking hold as a trajectory the simulation confirms (while
        its clock is paused for the stop: the hold takes effect before it runs on); return
        what is left to publish (nothing, or all of it when the simulation sends no receipts
        or the delivery failed, logged)."""
        try:
            self._braking_confirmed = self.delivery.hold(decision.hold or {})
        except TrajectoryDeliveryError as error:
            rospy.logwarn(f"arm services: the braking hold went out as set-points: {error}")
            self._braking_confirmed = False
        if self._braking_confirmed:
            return Decision(result=decision.result)
        return decision

    def stop(self, fault: str | None = None, stamp: float | None = None) -> bool:
        """Stop the running execution and hold the arm where it comes to rest; False when none
        runs. The simulation's clock is paused from the stop request until the braking hold is
        delivered (:class:`~ow_lander.arm_services.stop_clock.StopPause`; a pause taken ahead of the
        request is used), so the arm starts braking at once in simulation time at any speed and
        load. A ``fault`` (its message) makes the execution fail with it, braking from ``stamp``
        (s sim, when the fault arose; default: the newest joint state)."""
        self._stop_requested = True
        paused_here = self.stop_pause.take()
        try:
            with self._state_changed:
                monitor = self._monitor
                fresh = monitor is not None and monitor.stop_time is None
                if monitor is not None:
                    self._braking_sent.clear()
                    since = self._joint_stamp if stamp is None else min(stamp, self._joint_stamp)
                    monitor.request_stop(since, fault)
                    self._state_changed.notify_all()
            if fresh and paused_here is not None:  # the braking goes out before the clock runs
                self._braking_sent.wait(timeout=self.config.joint_state_timeout_s)
                if not self._braking_confirmed:
                    time.sleep(self.config.delivery_wait_s)  # set-points: time to arrive
        finally:
            if paused_here:
                self._sim_clock.resume()
        if monitor is not None:
            self._stopped.wait(timeout=self.config.joint_state_timeout_s)
        return monitor is not None
