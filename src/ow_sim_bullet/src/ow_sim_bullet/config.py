"""Simulation parameters: validated once, at start-up, into frozen dataclasses.

:func:`SimConfig.from_dict` takes the node's private parameters (the YAML files ``config/sim.yaml``
and ``config/pid.yaml``) and raises :class:`ConfigError` naming the first bad key. Nothing else in
the package reads parameters.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ow_lander.description import ALL_JOINTS, STOWED
from ow_sim_bullet.errors import ConfigError

#: N m / rad, N m / (rad s), N m s / rad: spec section 4.2 (OceanWATERS v6.0 lander_control.yaml).
SPEC_GAINS: dict[str, tuple[float, float, float]] = {
    "j_shou_yaw": (1000.0, 10.0, 300.0),
    "j_shou_pitch": (2000.0, 0.2, 150.0),
    "j_prox_pitch": (1100.0, 2.0, 100.0),
    "j_dist_pitch": (700.0, 0.06, 20.0),
    "j_hand_yaw": (100.0, 0.01, 10.0),
    "j_scoop_yaw": (100.0, 0.01, 10.0),
    "j_grinder": (2.0, 0.01, 0.1),
    "j_ant_pan": (100.0, 0.01, 10.0),
    "j_ant_tilt": (100.0, 0.01, 10.0),
}

#: The original's controller names: /<name>_position_controller/command drives the joint.
CONTROLLER_NAMES: dict[str, str] = {
    "j_shou_yaw": "shou_yaw",
    "j_shou_pitch": "shou_pitch",
    "j_prox_pitch": "prox_pitch",
    "j_dist_pitch": "dist_pitch",
    "j_hand_yaw": "hand_yaw",
    "j_scoop_yaw": "scoop_yaw",
    "j_grinder": "grinder_yaw",
    "j_ant_pan": "ant_pan",
    "j_ant_tilt": "ant_tilt",
}


@dataclass(frozen=True)
class PidGains:
    """Gains of one joint's PID position controller (effort = p e + i integral(e) + d de/dt).

    Attributes:
        p: N m / rad.
        i: N m / (rad s).
        d: N m s / rad, acting on the velocity error (set-point velocity minus joint velocity).
        i_clamp: N m, bound on the integral term's torque; None means the joint's effort limit.
    """

    p: float
    i: float
    d: float
    i_clamp: float | None = None

    @classmethod
    def from_dict(cls, raw: Any, key: str) -> PidGains:
        """Validate ``{p, i, d[, i_clamp]}`` found under parameter ``key``.

        Raises:
            ConfigError: a gain is missing, not a number, negative or not finite.
        """
        if not isinstance(raw, Mapping):
            msg = f"{key} must be a mapping with p, i, d (and optionally i_clamp), got {raw!r}"
            raise ConfigError(msg)
        unknown = set(raw) - {"p", "i", "d", "i_clamp"}
        if unknown:
            msg = f"{key} has unknown keys {sorted(unknown)}; allowed: p, i, d, i_clamp"
            raise ConfigError(msg)
        values = {}
        for name in ("p", "i", "d"):
            if name not in raw:
                msg = f"{key}.{name} is missing"
                raise ConfigError(msg)
            values[name] = _non_negative(raw[name], f"{key}.{name}")
        i_clamp = raw.get("i_clamp")
        return cls(
            values["p"],
            values["i"],
            values["d"],
            None if i_clamp is None else _non_negative(i_clamp, f"{key}.i_clamp"),
        )


def _number(value: Any, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        msg = f"{key} must be a number, got {value!r}"
        raise ConfigError(msg)
    if not math.isfinite(value):
        msg = f"{key} must be finite, got {value!r}"
        raise ConfigError(msg)
    return float(value)


def _non_negative(value: Any, key: str) -> float:
    number = _number(value, key)
    if number < 0:
        msg = f"{key} must be >= 0, got {number}"
        raise ConfigError(msg)
    return number


def _positive(value: Any, key: str) -> float:
    number = _number(value, key)
    if number <= 0:
        msg = f"{key} must be > 0, got {number}"
        raise ConfigError(msg)
    return number


def _pair(value: Any, key: str) -> tuple[float, float]:
    if not isinstance(value, list | tuple) or len(value) != 2:
        msg = f"{key} must be a list of two numbers, got {value!r}"
        raise ConfigError(msg)
    return _number(value[0], f"{key}[0]"), _number(value[1], f"{key}[1]")


def _default_gains() -> dict[str, PidGains]:
    return {joint: PidGains(*SPEC_GAINS[joint]) for joint in ALL_JOINTS}


def _default_initial() -> dict[str, float]:
    return {joint: STOWED.get(joint, 0.0) for joint in ALL_JOINTS}


@dataclass(frozen=True)
class SimConfig:
    """Everything the simulation is configured with. Units in each attribute's comment.

    Attributes:
        physics_rate_hz: Hz, fixed physics (and controller) step rate.
        real_time_factor: sim seconds per wall second to pace to; 0 runs as fast as possible.
        gravity: m/s^2, magnitude of gravity along -z of base_link (Europa 1.315).
        start_paused: start with the simulation paused (advance with the step service).
        gravity_feedforward: the joint controllers add the gravity torque of the measured pose
            to their PID output (model-based gravity compensation, as arm controllers on real
            robots do), so the arm rests at its set-points. False: pure PID as the paper, where
            a joint holds a load only with an error ``(tau_g - I) / Kp`` (the arm rests ~2 mm
            low at the scoop at full reach; see docs/simulation.md).
        tool_contact: the scoop and grinder collide with the terrain (Bullet contact). False:
            they pass through it (still carving it) and only the terrain-force model acts on
            them: the setting for a DEM that supplies all the terrain's forces.
        terrain: terrain spec, ``flat:<z>``, ``europa:<seed>`` or ``file:<path>``.
        terrain_file_resolution: m per cell of a ``.npy`` or PNG height-map file.
        terrain_file_center: (x, y) m in base_link of the centre of a ``.npy`` or PNG file's grid.
        terrain_png_height_range: (z at pixel 0, z at pixel 65535) m for 16-bit PNG files.
        terrain_material: material id reported to terrain-force models.
        terrain_yield_force: N, total normal contact force above which a tool carves the terrain.
        carve_step: m, how far below the tool a yielding cell is lowered in one carve update when
            the tool presses with ``carve_full_force`` or more (less in proportion to the force
            above ``terrain_yield_force``: a viscoplastic terrain).
        carve_full_force: N, normal force at which the terrain yields at the full ``carve_step``
            (must exceed ``terrain_yield_force``).
        carve_period: s of sim time between carve updates (and Bullet terrain refreshes).
        terrain_forces: terrain-force model name for ``ow_dem_bridge.models.make_model``, or "none".
        terrain_force_params: parameters passed to that factory.
        joint_state_rate_hz: Hz of sim time, /joint_states and /sim/joint_damping.
        clock_rate_hz: Hz of sim time, /clock.
        tf_rate_hz: Hz of sim time, /tf.
        wrench_rate_hz: Hz of sim time, contact wrenches and the ground-truth tip height.
        tool_state_rate_hz: Hz of sim time, /sim/scoop_state and /sim/grinder_state.
        terrain_publish_period: s of wall time, minimum interval between /sim/terrain updates.
        gains: PID gains by joint name.
        initial_positions: rad, joint positions at start-up and after a reset, by joint name.
    """

    physics_rate_hz: float = 100.0
    real_time_factor: float = 1.0
    gravity: float = 1.315
    start_paused: bool = False
    gravity_feedforward: bool = True
    tool_contact: bool = True
    terrain: str = "europa:0"
    terrain_file_resolution: float = 0.04
    terrain_file_center: tuple[float, float] = (1.5, 0.0)
    terrain_png_height_range: tuple[float, float] = (-1.0, 1.0)
    terrain_material: int = 1
    terrain_yield_force: float = 10.0
    carve_step: float = 0.003
    carve_full_force: float = 40.0
    carve_period: float = 0.05
    terrain_forces: str = "none"
    terrain_force_params: Mapping[str, Any] = field(default_factory=dict)
    joint_state_rate_hz: float = 100.0
    clock_rate_hz: float = 100.0
    tf_rate_hz: float = 30.0
    wrench_rate_hz: float = 50.0
    tool_state_rate_hz: float = 10.0
    terrain_publish_period: float = 0.5
    gains: Mapping[str, PidGains] = field(default_factory=_default_gains)
    initial_positions: Mapping[str, float] = field(default_factory=_default_initial)

    @property
    def dt(self) -> float:
        """s, the physics step."""
        return 1.0 / self.physics_rate_hz

    @classmethod
    def from_dict(cls, raw: Mapping[str, Any]) -> SimConfig:
        """Validate the node's private parameters; missing keys take the defaults above.

        Args:
            raw: parameter name -> value, as ``rospy.get_param('~')`` returns them.

        Raises:
            ConfigError: unknown key, wrong type or out-of-range value, naming the key.
        """
        defaults = cls()
        allowed = set(cls.__dataclass_fields__)
        unknown = sorted(set(raw) - allowed)
        if unknown:
            msg = f"unknown parameter(s) {unknown}; known: {sorted(allowed)}"
            raise ConfigError(msg)
        kwargs: dict[str, Any] = {}
        positive = (
            "physics_rate_hz",
            "gravity",
            "terrain_file_resolution",
            "carve_period",
            "joint_state_rate_hz",
            "clock_rate_hz",
            "tf_rate_hz",
            "wrench_rate_hz",
            "tool_state_rate_hz",
        )
        for key in positive:
            if key in raw:
                kwargs[key] = _positive(raw[key], key)
        for key in (
            "real_time_factor",
            "terrain_yield_force",
            "carve_step",
            "carve_full_force",
            "terrain_publish_period",
        ):
            if key in raw:
                kwargs[key] = _non_negative(raw[key], key)
        for key in ("terrain_file_center", "terrain_png_height_range"):
            if key in raw:
                kwargs[key] = _pair(raw[key], key)
        for key in ("terrain", "terrain_forces"):
            if key in raw:
                if not isinstance(raw[key], str) or not raw[key]:
                    msg = f"{key} must be a non-empty string, got {raw[key]!r}"
                    raise ConfigError(msg)
                kwargs[key] = raw[key]
        for key in ("start_paused", "gravity_feedforward", "tool_contact"):
            if key in raw:
                if not isinstance(raw[key], bool):
                    msg = f"{key} must be true or false, got {raw[key]!r}"
                    raise ConfigError(msg)
                kwargs[key] = raw[key]
        if "terrain_material" in raw:
            material = raw["terrain_material"]
            if (
                isinstance(material, bool)
                or not isinstance(material, int)
                or not 0 <= material < 256
            ):
                msg = f"terrain_material must be an integer 0..255, got {material!r}"
                raise ConfigError(msg)
            kwargs["terrain_material"] = material
        if "terrain_force_params" in raw:
            if not isinstance(raw["terrain_force_params"], Mapping):
                msg = f"terrain_force_params must be a mapping, got {raw['terrain_force_params']!r}"
                raise ConfigError(msg)
            kwargs["terrain_force_params"] = dict(raw["terrain_force_params"])
        if "gains" in raw:
            kwargs["gains"] = _gains(raw["gains"], defaults.gains)
        if "initial_positions" in raw:
            kwargs["initial_positions"] = _initial(raw["initial_positions"], defaults)
        yield_force = kwargs.get("terrain_yield_force", defaults.terrain_yield_force)
        full_force = kwargs.get("carve_full_force", defaults.carve_full_force)
        if full_force <= yield_force:
            msg = f"carve_full_force={full_force} N must exceed terrain_yield_force={yield_force} N"
            raise ConfigError(msg)
        png_low, png_high = kwargs.get(
            "terrain_png_height_range", defaults.terrain_png_height_range
        )
        if png_high <= png_low:
            msg = f"terrain_png_height_range must be increasing, got {[png_low, png_high]}"
            raise ConfigError(msg)
        return cls(**kwargs)


def _gains(raw: Any, defaults: Mapping[str, PidGains]) -> dict[str, PidGains]:
    if not isinstance(raw, Mapping):
        msg = f"gains must be a mapping joint -> {{p, i, d}}, got {raw!r}"
        raise ConfigError(msg)
    unknown = sorted(set(raw) - set(ALL_JOINTS))
    if unknown:
        msg = f"gains has unknown joint(s) {unknown}; joints: {list(ALL_JOINTS)}"
        raise ConfigError(msg)
    gains = dict(defaults)
    for joint, value in raw.items():
        gains[joint] = PidGains.from_dict(value, f"gains.{joint}")
    return gains


def _initial(raw: Any, defaults: SimConfig) -> dict[str, float]:
    if not isinstance(raw, Mapping):
        msg = f"initial_positions must be a mapping joint -> rad, got {raw!r}"
        raise ConfigError(msg)
    unknown = sorted(set(raw) - set(ALL_JOINTS))
    if unknown:
        msg = f"initial_positions has unknown joint(s) {unknown}; joints: {list(ALL_JOINTS)}"
        raise ConfigError(msg)
    initial = dict(defaults.initial_positions)
    for joint, value in raw.items():
        initial[joint] = _number(value, f"initial_positions.{joint}")
    return initial
