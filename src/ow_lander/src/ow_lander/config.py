"""Configuration of the arm services, validated from the node's private parameters.

``ArmServicesConfig.from_dict(rospy.get_param("~"))`` is the only place parameters enter; every
other module receives the frozen dataclasses below. Missing keys keep their defaults, unknown keys
and bad values raise :class:`~ow_lander.errors.ConfigError` naming the key.
``config/arm_services.yaml`` lists every key with its unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from ow_lander.description import ARM_JOINTS
from ow_lander.errors import ConfigError

#: rad/s^2, default acceleration limit of every arm joint (OceanWATERS had none; the PID
#: position controllers track a trapezoid with this ramp well).
DEFAULT_ACCELERATION = 0.2


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
        connect_time_limit_s: s (wall), time cap of the RRTConnect feasibility search tried
            when RRT* found nothing within its caps (its path is then shortened by the same
            objective); 0 disables it.
        seed: OMPL random seed; the same request and state give the same plan.
        path_length_weight: J/rad, weight of joint-space path length in the work objective.
        ik_restarts: random restarts of IK for free-space goals (Cartesian steps use none).
    """

    joint_resolution_rad: float = 0.01
    cartesian_step_m: float = 0.01
    max_joint_jump_rad: float = 0.15
    terrain_margin_m: float = 0.0
    rrt_range_rad: float = 0.6
    rrt_goal_bias: float = 0.1
    rrt_rewire_factor: float = 0.01
    rrt_check_resolution_rad: float = 0.04
    rrt_max_iterations: int = 400
    rrt_improve_iterations: int = 100
    rrt_time_limit_s: float = 5.0
    rrt_cost_threshold_factor: float = 1.5
    rrt_attempts: int = 1
    connect_time_limit_s: float = 5.0
    seed: int = 42
    path_length_weight: float = 0.05
    ik_restarts: int = 40


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

    velocity_scale: float = 1.0
    guarded_velocity_scale: float = 0.25
    dig_velocity_scale: float = 0.5
    acceleration_limits: Mapping[str, float] = field(
        default_factory=lambda: dict.fromkeys(ARM_JOINTS, DEFAULT_ACCELERATION)
    )
    sample_period_s: float = 0.1


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
        start_delay_s: s (simulation time) between sending a trajectory and its first row.
        delivery_wait_s: s (wall), how long the simulation's clock stays paused while a
            trajectory is delivered to it.
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
    """

    interface: str = "trajectory"
    start_delay_s: float = 0.05
    delivery_wait_s: float = 0.1
    service_wait_s: float = 5.0
    command_rate_hz: float = 50.0
    goal_tolerance_rad: float = 0.02
    max_tracking_error_rad: float = 0.3
    settle_timeout_s: float = 10.0
    timeout_factor: float = 1.5
    guarded_settle_s: float = 2.0
    ground_detector: str = "velocity"
    ground_relative_tolerance: float = 0.3
    ground_force_threshold_n: float = 10.0
    joint_state_timeout_s: float = 5.0


@dataclass(frozen=True)
class ArmServicesConfig:
    """Everything the ``arm_services`` node reads from its private namespace.

    Attributes:
        trajectory_dir: directory of the trajectory files; "" = ``$ROS_HOME/trajectories``.
        plan_and_execute: services also execute their plan (one call per operation).
        fallback_ground_z: m, height (base_link) of the flat terrain assumed until
            ``/sim/terrain`` has been received.
        terrain_wait_s: s (wall), how long a request waits for a first ``/sim/terrain``
            before planning against the fallback ground.
        planner: see :class:`PlannerConfig`.
        timing: see :class:`TimingConfig`.
        execution: see :class:`ExecutionConfig`.
    """

    trajectory_dir: str = ""
    plan_and_execute: bool = False
    fallback_ground_z: float = -0.155
    terrain_wait_s: float = 2.0
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    timing: TimingConfig = field(default_factory=TimingConfig)
    execution: ExecutionConfig = field(default_factory=ExecutionConfig)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> ArmServicesConfig:
        """Validate a parameter dictionary (the node's ``~`` namespace).

        Raises:
            ConfigError: unknown key, wrong type or out-of-range value (the message names it).
        """
        values = dict(values)
        planner = _section(PlannerConfig, values.pop("planner", {}), "planner")
        timing_values = dict(_mapping(values.pop("timing", {}), "timing"))
        accel = _acceleration_limits(timing_values.pop("acceleration_limits", {}))
        timing = _section(TimingConfig, timing_values, "timing", acceleration_limits=accel)
        execution = _section(ExecutionConfig, values.pop("execution", {}), "execution")
        top = _section(cls, values, "", planner=planner, timing=timing, execution=execution)
        _check_ranges(top)
        return top


#: Values of ``execution/interface``.
EXECUTION_INTERFACES = ("trajectory", "position_controllers")

_NESTED = {"planner", "timing", "execution", "acceleration_limits"}


def _mapping(value: Any, key: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        msg = f"parameter {key!r} must be a mapping, got {value!r}"
        raise ConfigError(msg)
    return value


def _acceleration_limits(value: Any) -> dict[str, float]:
    limits = dict.fromkeys(ARM_JOINTS, DEFAULT_ACCELERATION)
    for joint, limit in _mapping(value, "timing/acceleration_limits").items():
        key = f"timing/acceleration_limits/{joint}"
        if joint not in ARM_JOINTS:
            msg = f"parameter {key!r}: unknown arm joint (arm joints: {', '.join(ARM_JOINTS)})"
            raise ConfigError(msg)
        limits[joint] = _positive(_number(limit, key, float), key)
    return limits


def _section(cls: Any, values: Any, prefix: str, **given: Any) -> Any:
    values = _mapping(values, prefix or "~")
    kwargs: dict[str, Any] = dict(given)
    known = {f.name: f for f in fields(cls)}
    for key, value in values.items():
        name = f"{prefix}/{key}" if prefix else key
        if key not in known or key in _NESTED:
            msg = f"unknown parameter {name!r}; known: {', '.join(sorted(known))}"
            raise ConfigError(msg)
        kwargs[key] = _number(value, name, type(known[key].default))
    return cls(**kwargs)


def _number(value: Any, key: str, kind: type) -> Any:
    if kind is bool:
        if not isinstance(value, bool):
            msg = f"parameter {key!r} must be true or false, got {value!r}"
            raise ConfigError(msg)
        return value
    if kind is str:
        if not isinstance(value, str):
            msg = f"parameter {key!r} must be a string, got {value!r}"
            raise ConfigError(msg)
        return value
    if isinstance(value, bool) or not isinstance(value, int | float):
        msg = f"parameter {key!r} must be a number, got {value!r}"
        raise ConfigError(msg)
    if kind is int:
        if int(value) != value:
            msg = f"parameter {key!r} must be an integer, got {value!r}"
            raise ConfigError(msg)
        return int(value)
    if not math.isfinite(value):
        msg = f"parameter {key!r} must be finite, got {value!r}"
        raise ConfigError(msg)
    return float(value)


def _positive(value: float, key: str) -> float:
    if value <= 0:
        msg = f"parameter {key!r} must be > 0, got {value}"
        raise ConfigError(msg)
    return value


def _check_ranges(config: ArmServicesConfig) -> None:
    if config.execution.interface not in EXECUTION_INTERFACES:
        msg = (
            f"parameter 'execution/interface' must be one of {', '.join(EXECUTION_INTERFACES)}, "
            f"got {config.execution.interface!r}"
        )
        raise ConfigError(msg)
    positive = {
        "planner/joint_resolution_rad": config.planner.joint_resolution_rad,
        "planner/cartesian_step_m": config.planner.cartesian_step_m,
        "planner/max_joint_jump_rad": config.planner.max_joint_jump_rad,
        "planner/rrt_range_rad": config.planner.rrt_range_rad,
        "planner/rrt_rewire_factor": config.planner.rrt_rewire_factor,
        "planner/rrt_check_resolution_rad": config.planner.rrt_check_resolution_rad,
        "planner/rrt_max_iterations": config.planner.rrt_max_iterations,
        "planner/rrt_improve_iterations": config.planner.rrt_improve_iterations,
        "planner/rrt_time_limit_s": config.planner.rrt_time_limit_s,
        "planner/rrt_cost_threshold_factor": config.planner.rrt_cost_threshold_factor,
        "planner/rrt_attempts": config.planner.rrt_attempts,
        "timing/sample_period_s": config.timing.sample_period_s,
        "execution/command_rate_hz": config.execution.command_rate_hz,
        "execution/goal_tolerance_rad": config.execution.goal_tolerance_rad,
        "execution/max_tracking_error_rad": config.execution.max_tracking_error_rad,
        "execution/settle_timeout_s": config.execution.settle_timeout_s,
        "execution/timeout_factor": config.execution.timeout_factor,
        "execution/joint_state_timeout_s": config.execution.joint_state_timeout_s,
        "execution/ground_force_threshold_n": config.execution.ground_force_threshold_n,
    }
    for key, value in positive.items():
        _positive(value, key)
    non_negative = {
        "planner/terrain_margin_m": config.planner.terrain_margin_m,
        "planner/seed": config.planner.seed,
        "planner/path_length_weight": config.planner.path_length_weight,
        "planner/ik_restarts": config.planner.ik_restarts,
        "execution/guarded_settle_s": config.execution.guarded_settle_s,
        "execution/start_delay_s": config.execution.start_delay_s,
        "execution/delivery_wait_s": config.execution.delivery_wait_s,
        "execution/service_wait_s": config.execution.service_wait_s,
    }
    for key, value in non_negative.items():
        if value < 0:
            msg = f"parameter {key!r} must be >= 0, got {value}"
            raise ConfigError(msg)
    if config.planner.seed == 0:
        msg = "parameter 'planner/seed' must be > 0 (OMPL treats 0 as 'no seed')"
        raise ConfigError(msg)
    if config.execution.ground_detector not in ("velocity", "force"):
        detector = config.execution.ground_detector
        msg = f"parameter 'execution/ground_detector' must be velocity or force, got {detector!r}"
        raise ConfigError(msg)
    if not 0 <= config.execution.ground_relative_tolerance < 1:
        value = config.execution.ground_relative_tolerance
        msg = f"parameter 'execution/ground_relative_tolerance' must be in [0, 1), got {value}"
        raise ConfigError(msg)
    for key in ("velocity_scale", "guarded_velocity_scale", "dig_velocity_scale"):
        value = getattr(config.timing, key)
        if not 0 < value <= 1:
            msg = f"parameter 'timing/{key}' must be in (0, 1], got {value}"
            raise ConfigError(msg)
    if not 0 <= config.planner.rrt_goal_bias <= 1:
        bias = config.planner.rrt_goal_bias
        msg = f"parameter 'planner/rrt_goal_bias' must be in [0, 1], got {bias}"
        raise ConfigError(msg)
