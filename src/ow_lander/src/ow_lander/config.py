"""Configuration of the arm services, validated from the node's private parameters.

``ArmServicesConfig.from_dict(rospy.get_param("~"))`` is the only place parameters enter; every
other module receives the frozen dataclasses below. Missing keys keep their defaults; unknown keys
and bad values are collected by :class:`~ow_runtime.params.Params` and raised together as one
:class:`~ow_lander.errors.ConfigError` naming each key (a misspelt key gets the nearest known one).
:data:`CONFIG_FILE` lists every key with its unit. Each attribute's range is the ``metadata`` of
its field (:data:`POSITIVE`, ...): the keyword arguments of the :class:`Params` read.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from types import MappingProxyType
from typing import Any

from ow_description.description import ARM_JOINTS, DEFAULT_GROUND_Z
from ow_description.trajectory import Speed
from ow_lander.errors import ConfigError
from ow_runtime.params import Params

#: The shipped parameter file; its ``arm_services:`` section is the node's private namespace.
CONFIG_FILE = Path(__file__).resolve().parents[2] / "config" / "arm_services.yaml"

#: rad/s^2, default acceleration limit of every arm joint (OceanWATERS had none; the PID
#: position controllers track a trapezoid with this ramp well).
DEFAULT_ACCELERATION = 0.2

#: Values of ``execution/interface``.
EXECUTION_INTERFACES = ("trajectory", "position_controllers")
#: Values of ``execution/ground_detector``.
GROUND_DETECTORS = ("velocity", "force")

#: Ranges of a field (its ``metadata``): the keyword arguments of its :class:`Params` read.
POSITIVE: Mapping[str, Any] = MappingProxyType({"low": 0.0, "low_inclusive": False})
NON_NEGATIVE: Mapping[str, Any] = MappingProxyType({"low": 0.0})
AT_LEAST_ONE: Mapping[str, Any] = MappingProxyType({"low": 1})
SCALE: Mapping[str, Any] = MappingProxyType({"low": 0.0, "low_inclusive": False, "high": 1.0})


def _choices(*values: str) -> Mapping[str, Any]:
    return MappingProxyType({"choices": values})


@dataclass(frozen=True)
class PlannerConfig:
    """How plans are made (see docs/arm_services.md, "Planning").

    Attributes:
        joint_resolution_rad: rad, largest joint step between two collision-checked states of
            every planned path (the direct segment, Cartesian steps, the final path check).
        cartesian_step_m: m, spacing of IK waypoints along Cartesian lines.
        max_joint_jump_rad: rad, largest joint change allowed between two Cartesian waypoints.
        terrain_margin_m: m, clearance required between the terrain and links that must stay
            above it.
        rrt_range_rad: rad, RRT* extension length.
        rrt_goal_bias: probability of sampling the goal.
        rrt_rewire_factor: RRT* rewiring factor (smaller = fewer neighbours, faster).
        rrt_check_resolution_rad: rad, motion-check step inside RRT* (the result is re-checked
            at ``joint_resolution_rad``).
        rrt_max_iterations: iteration cap of one RRT* solve.
        rrt_improve_iterations: iterations RRT* keeps improving after its first solution (the
            usual end of a solve: it depends on the request, not on the machine's load).
        rrt_time_limit_s: s (wall), time cap of one RRT* solve (a safety net; a solve that
            hits it is no longer reproducible).
        rrt_cost_threshold_factor: RRT* stops once its cost is below this factor times the cost
            of the (invalid) straight joint-space segment.
        rrt_attempts: solves tried (seeds ``seed``, ``seed + 1``, ...) before giving up.
        connect_max_iterations: iteration cap of one RRTConnect feasibility search, tried
            when RRT* found nothing within its caps (its path is then shortened by the same
            objective): its usual end when it finds nothing, reproducible at any load.
        connect_time_limit_s: s (wall), time cap of one RRTConnect search (a safety net, as
            ``rrt_time_limit_s``); 0 disables the RRTConnect searches.
        seed: OMPL random seed (> 0); the same request and state give the same plan.
        path_length_weight: J/rad, weight of joint-space path length in the work objective.
        ik_restarts: random restarts of IK for free-space goals (Cartesian steps use none).
    """

    joint_resolution_rad: float = field(default=0.01, metadata=POSITIVE)
    cartesian_step_m: float = field(default=0.01, metadata=POSITIVE)
    max_joint_jump_rad: float = field(default=0.15, metadata=POSITIVE)
    terrain_margin_m: float = field(default=0.0, metadata=NON_NEGATIVE)
    rrt_range_rad: float = field(default=0.6, metadata=POSITIVE)
    rrt_goal_bias: float = field(default=0.1, metadata={"low": 0.0, "high": 1.0})
    rrt_rewire_factor: float = field(default=0.01, metadata=POSITIVE)
    rrt_check_resolution_rad: float = field(default=0.04, metadata=POSITIVE)
    rrt_max_iterations: int = field(default=400, metadata=AT_LEAST_ONE)
    rrt_improve_iterations: int = field(default=100, metadata=AT_LEAST_ONE)
    rrt_time_limit_s: float = field(default=5.0, metadata=POSITIVE)
    rrt_cost_threshold_factor: float = field(default=1.5, metadata=POSITIVE)
    rrt_attempts: int = field(default=1, metadata=AT_LEAST_ONE)
    connect_max_iterations: int = field(default=1000, metadata=AT_LEAST_ONE)
    connect_time_limit_s: float = 30.0
    seed: int = field(default=42, metadata=NON_NEGATIVE)
    path_length_weight: float = field(default=0.05, metadata=NON_NEGATIVE)
    ik_restarts: int = field(default=40, metadata=NON_NEGATIVE)


@dataclass(frozen=True)
class TimingConfig:
    """How plans are timed.

    Attributes:
        velocity_scale: fraction (0, 1] of the URDF velocity limits used by plans.
        guarded_velocity_scale: fraction (0, 1] of the URDF velocity limits for the guarded
            descent (OceanWATERS: 0.5 at planning and half-rate playback).
        dig_velocity_scale: fraction (0, 1] of the URDF velocity limits while a tool is in the
            ground (trench passes, cuts, sweeps).
        acceleration_limits: rad/s^2 per arm joint, by name.
        sample_period_s: s, time between rows of a trajectory file.
    """

    velocity_scale: float = field(default=1.0, metadata=SCALE)
    guarded_velocity_scale: float = field(default=0.25, metadata=SCALE)
    dig_velocity_scale: float = field(default=0.5, metadata=SCALE)
    acceleration_limits: Mapping[str, float] = field(
        default_factory=lambda: dict.fromkeys(ARM_JOINTS, DEFAULT_ACCELERATION)
    )
    sample_period_s: float = field(default=0.1, metadata=POSITIVE)

    @property
    def speed_scales(self) -> dict[Speed, float]:
        """Fraction of the velocity limits of each segment speed class."""
        return {
            Speed.FREE: self.velocity_scale,
            Speed.DIG: self.dig_velocity_scale,
            Speed.GUARDED: self.guarded_velocity_scale,
        }


@dataclass(frozen=True)
class ExecutionConfig:
    """How trajectories are executed.

    Attributes:
        interface: "trajectory": the whole trajectory goes to the simulation's joint
            trajectory controller (``/sim/joint_trajectory``) at once and is followed on
            simulation time (deterministic at any speed); "position_controllers": set-points are
            streamed to ``/<joint>_position_controller/command`` at ``command_rate_hz`` as in
            the paper (faithful at real_time_factor 1; lags when the simulation runs faster than
            this node can stream).
        start_delay_s: s (simulation time) between sending a trajectory and its first row,
            for a simulation that sends no receipts (ours starts a trajectory when it queues
            it, clock paused, and says when on ``/sim/trajectory_received``).
        delivery_wait_s: s (wall), how long the simulation's clock stays paused while a
            trajectory is delivered to a simulation that sends no receipt.
        service_wait_s: s (wall), how long to look for the simulation's ``/sim/pause`` and
            ``/sim/resume`` services (once).
        command_rate_hz: Hz (simulation time), set-point rate of the "position_controllers"
            interface.
        goal_tolerance_rad: rad, every joint within this of the final set-point = arrived.
        max_tracking_error_rad: rad, abort when a joint lags its set-point by more.
        settle_timeout_s: s (simulation time) allowed after the last row to reach the goal.
        timeout_factor: the whole execution may take at most this factor times the
            trajectory's duration plus ``settle_timeout_s``.
        guarded_settle_s: s, pause before the guarded descent (OceanWATERS: 2 s).
        ground_detector: "velocity": the paper's detector on the scoop tip's vertical velocity
            from tf; "force": the later OceanWATERS detector, contact when the force measured
            by the wrist force/torque sensor (``/arm_end_effector_force_torque``) rises by
            ``ground_force_threshold_n`` over its value at the start of the steady descent.
        ground_relative_tolerance: 1, the velocity detector's smallest margin above the steady
            descent velocity, as a fraction of the descent speed (ours; the paper's margin is
            one standard deviation, which a smooth simulation makes vanishingly small).
        ground_force_threshold_n: N, rise of the wrist force that means contact (force
            detector).
        joint_state_timeout_s: s (wall), how long to wait for /joint_states before refusing.
        lockstep: join the simulation's lockstep (docs/determinism.md) when it offers one: the
            simulation waits for this node's decisions on every joint state, and its holds and
            set-points take effect at the stamp decided on plus the lockstep latency, whatever
            the load (the mission's setting; it costs the simulation about 30 % of its speed in
            a stack of the simulation and the arm services). False: commands go out on the
            controllers' topics as they are decided.
        lockstep_hold: with lockstep, the simulation also stops where an execution ends (its
            final hold) until the next trajectory is delivered, so the next operation starts at
            a time that does not depend on when it is requested: the mission's setting. Time
            then passes only during executions.
        lockstep_settle_s: s (sim) the simulation runs on after an execution's final hold takes
            effect before ``lockstep_hold`` stops it: the arm settles at the hold (a guarded
            move's scoop comes back to where it touched the ground).
    """

    interface: str = field(default="trajectory", metadata=_choices(*EXECUTION_INTERFACES))
    start_delay_s: float = field(default=0.05, metadata=NON_NEGATIVE)
    delivery_wait_s: float = field(default=0.1, metadata=NON_NEGATIVE)
    service_wait_s: float = field(default=5.0, metadata=NON_NEGATIVE)
    command_rate_hz: float = field(default=50.0, metadata=POSITIVE)
    goal_tolerance_rad: float = field(default=0.02, metadata=POSITIVE)
    max_tracking_error_rad: float = field(default=0.3, metadata=POSITIVE)
    settle_timeout_s: float = field(default=10.0, metadata=POSITIVE)
    timeout_factor: float = field(default=1.5, metadata=POSITIVE)
    guarded_settle_s: float = field(default=2.0, metadata=NON_NEGATIVE)
    ground_detector: str = field(default="velocity", metadata=_choices(*GROUND_DETECTORS))
    ground_relative_tolerance: float = field(
        default=0.3, metadata={"low": 0.0, "high": 1.0, "high_inclusive": False}
    )
    ground_force_threshold_n: float = field(default=10.0, metadata=POSITIVE)
    joint_state_timeout_s: float = field(default=5.0, metadata=POSITIVE)
    lockstep: bool = False
    lockstep_hold: bool = False
    lockstep_settle_s: float = field(default=1.0, metadata=NON_NEGATIVE)


@dataclass(frozen=True)
class ArmServicesConfig:
    """Everything the ``arm_services`` node reads from its private namespace.

    Attributes:
        trajectory_dir: directory of the trajectory files; "" = ``$ROS_HOME/trajectories``.
        plan_and_execute: services also execute their plan (one call per operation).
        fallback_ground_z: m, height (base_link) of the flat terrain assumed until
            ``/sim/terrain`` has been received.
        terrain_wait_s: s (wall) from start-up during which a request waits for a first
            ``/sim/terrain`` before planning against the fallback ground.
        actionlib_status_frequency: Hz of sim time, the action servers' periodic status (read
            by actionlib itself; every goal transition is also published when it happens; > 0:
            clients count a server as connected once they have its status).
        planner: see :class:`PlannerConfig`.
        timing: see :class:`TimingConfig`.
        execution: see :class:`ExecutionConfig`.
    """

    trajectory_dir: str = ""
    plan_and_execute: bool = False
    fallback_ground_z: float = DEFAULT_GROUND_Z
    terrain_wait_s: float = 2.0
    actionlib_status_frequency: float = field(default=5.0, metadata=POSITIVE)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    timing: TimingConfig = field(default_factory=TimingConfig)
    execution: ExecutionConfig = field(default_factory=ExecutionConfig)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> ArmServicesConfig:
        """Validate a parameter dictionary (the node's ``~`` namespace).

        Raises:
            ConfigError: unknown keys, wrong types or out-of-range values, every one named in
                the one message.
        """
        p = Params(values, "arm_services", ConfigError)
        planner = _read(PlannerConfig, p.section("planner"))
        if planner.seed == 0:
            p.problem(f"{p.name('planner/seed')} must be > 0 (OMPL treats 0 as 'no seed')")
        timing = p.section("timing")
        accelerations = timing.section("acceleration_limits")
        limits = {j: accelerations.positive(j, DEFAULT_ACCELERATION, "rad/s^2") for j in ARM_JOINTS}
        accelerations.check_unknown()
        config = _read(
            cls,
            p,
            unknown=False,  # finish() checks the top level
            planner=planner,
            timing=_read(TimingConfig, timing, acceleration_limits=limits),
            execution=_read(ExecutionConfig, p.section("execution")),
        )
        p.finish()
        return config


def _read(cls: Any, p: Params, unknown: bool = True, **given: Any) -> Any:
    """An instance of the dataclass ``cls`` from ``p``: each field not ``given`` read by the
    type of its default within the range of its metadata; then, with ``unknown``, the keys of
    ``p`` that are no field are recorded as problems."""
    values = dict(given)
    for f in fields(cls):
        if f.name in given:
            continue
        default = f.default
        if default is MISSING:
            msg = f"{cls.__name__}.{f.name} has no default to read it by"
            raise TypeError(msg)
        if isinstance(default, bool):
            values[f.name] = p.boolean(f.name, default)
        elif isinstance(default, str):
            values[f.name] = p.string(f.name, default, f.metadata.get("choices"))
        elif isinstance(default, int):
            values[f.name] = p.integer(f.name, default, **f.metadata)
        else:
            values[f.name] = p.number(f.name, default, **f.metadata)
    if unknown:
        p.check_unknown()
    return cls(**values)
