"""Simulation parameters: validated once, at start-up, into frozen dataclasses.

:func:`SimConfig.from_dict` takes the node's private parameters (the YAML files :data:`SIM_YAML`
and :data:`PID_YAML`) and raises :class:`ConfigError` listing every bad key at once
(:class:`ow_runtime.params.Params`). Nothing else in the package reads parameters.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ow_description.description import ALL_JOINTS, EUROPA_GRAVITY, STOWED
from ow_regolith.config import RegolithConfig
from ow_regolith.errors import ConfigError as RegolithConfigError
from ow_runtime.params import Params, suggest
from ow_sim_bullet.errors import ConfigError

#: The package's shipped parameter files, loaded into the node's private namespace by
#: ``launch/sim.launch`` (sim.yaml's keys at top level, then pid.yaml's ``gains:``).
CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
SIM_YAML = CONFIG_DIR / "sim.yaml"
PID_YAML = CONFIG_DIR / "pid.yaml"

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
    def from_dict(cls, raw: Any, where: str) -> PidGains:
        """Validate ``{p, i, d[, i_clamp]}`` given for one joint.

        Args:
            raw: the gains mapping.
            where: how messages name the mapping (``"gains of j_shou_yaw"``).

        Raises:
            ConfigError: not a mapping, or gains missing, not numbers, negative, not finite or
                unknown (every problem listed).
        """
        params = Params(raw, where, ConfigError)
        gains = cls.read(params)
        params.finish()  # also names unknown keys
        return gains

    def updated(self, changes: Mapping[str, Any], where: str) -> PidGains:
        """These gains with ``changes`` (some of p, i, d, i_clamp) applied and validated.

        Raises:
            ConfigError: as :meth:`from_dict`, for the gains after the change.
        """
        values = {"p": self.p, "i": self.i, "d": self.d, "i_clamp": self.i_clamp}
        return PidGains.from_dict({**values, **changes}, where)

    @classmethod
    def read(cls, params: Params) -> PidGains:
        """Read the gains from ``params``; problems are recorded for its root's
        :meth:`~ow_runtime.params.Params.finish` (unknown keys are the caller's to check)."""
        values = {}
        for name, unit in (("p", "N m/rad"), ("i", "N m/(rad s)"), ("d", "N m s/rad")):
            if not params.has(name):
                params.problem(f"{params.name(name)} is missing")
            values[name] = params.non_negative(name, 0.0, unit)
        i_clamp = params.raw("i_clamp")
        return cls(
            values["p"],
            values["i"],
            values["d"],
            None
            if i_clamp is None
            else params.check_number(i_clamp, params.name("i_clamp"), 0.0, low=0.0, unit="N m"),
        )


#: The gains of one joint, the fields of ``SetPidGains`` and of the PID dynamic_reconfigure.
PID_FIELDS = ("p", "i", "d", "i_clamp")


def gain_changes(values: Mapping[str, float], named: Sequence[str]) -> dict[str, float]:
    """The gains a partial ``SetPidGains`` request changes.

    Args:
        values: the request's p, i, d and i_clamp (a field left out reads 0).
        named: the request's ``set``: the gains it sets; empty: those given non-zero.

    Raises:
        ConfigError: ``named`` holds a name other than p, i, d, i_clamp.
    """
    unknown = [n for n in named if n not in PID_FIELDS]
    if unknown:
        msg = f"set names unknown gains {unknown}; gains: {list(PID_FIELDS)}"
        raise ConfigError(msg)
    names = list(named) or [n for n in PID_FIELDS if values[n] != 0.0]
    return {n: float(values[n]) for n in names}


def _pair(params: Params, key: str, default: tuple[float, float], unit: str) -> tuple[float, float]:
    """``key`` as a list of two finite numbers."""
    value = params.raw(key, list(default))
    if not isinstance(value, list | tuple) or len(value) != 2:
        params.problem(f"{params.name(key)} must be a list of two numbers ({unit}), got {value!r}")
        return default
    first, second = (
        params.check_number(v, f"{params.name(key)}[{i}]", default[i], unit=unit)
        for i, v in enumerate(value)
    )
    return first, second


def _angle(params: Params, key: str, default: float, high: float = math.pi) -> float:
    """``key`` as an angle in (0, ``high``] rad."""
    return params.number(key, default, low=0.0, low_inclusive=False, high=high, unit="rad")


def _non_empty(params: Params, key: str, default: str) -> str:
    """``key`` as a non-empty string."""
    value = params.string(key, default)
    if not value:
        params.problem(f"{params.name(key)} must be a non-empty string")
        return default
    return value


def _joint_section(params: Params, key: str) -> Params:
    """The mapping ``key`` of joint names, its unknown joints recorded as problems."""
    section = params.section(key)
    for joint in section.values:
        if joint not in ALL_JOINTS:
            section.problem(
                f"{section.name(str(joint))}: unknown joint{suggest(str(joint), ALL_JOINTS)}; "
                f"joints: {', '.join(ALL_JOINTS)}"
            )
    return section


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
        terrain_friction: Coulomb friction coefficient between the tools and the terrain
            (OceanWATERS' terrain models: 0.8).
        terrain_yield_force: N, total normal contact force above which a digging tool carves the
            terrain (outside a dig the terrain is solid).
        carve_step: m, how far below the tool a yielding cell is lowered in one carve update when
            the tool presses with ``carve_full_force`` or more (less in proportion to the force
            above ``terrain_yield_force``: a viscoplastic terrain).
        carve_full_force: N, normal force at which the terrain yields at the full ``carve_step``
            (must exceed ``terrain_yield_force``).
        carve_period: s of sim time between carve updates (and Bullet terrain refreshes); the
            scoop's dig phase and whether the grinder grinds are decided at each.
        dig_forward_angle: rad, largest angle between the scoop tip's velocity and the scoop's
            forward axis (+x of l_scoop_tip, out of its mouth) at which the scoop moves mouth
            first (OceanWATERS' ``moving_forward``, 5 degrees there).
        dig_sink_angle: rad, a dig starts (SINKING) only with the scoop's bottom normal (+z of
            l_scoop_tip) within this angle of straight down (OceanWATERS: 90 degrees).
        dig_slope: rad, slope of the tip's path separating the phases: SINKING turns to PLOWING
            once the path descends less steeply, PLOWING to RETRACTING once it rises more
            steeply.
        dig_exit_clearance: m, a RETRACTING scoop whose tip is this far above the terrain has
            left it: NOT_DIGGING.
        dig_timeout: s of sim time a dig phase lasts with the scoop tip standing still or out of
            the terrain before it ends (NOT_DIGGING).
        grind_down_angle: rad, the grinder grinds (cuts the terrain) only when its axis (+x of
            l_grinder) is within this angle of straight down and its tip moves (OceanWATERS:
            10 degrees).
        terrain_forces: terrain-force model name for ``ow_dem_bridge.models.make_model``, or "none".
        terrain_force_params: parameters passed to that factory.
        joint_state_rate_hz: Hz of sim time, /joint_states and /sim/joint_damping.
        clock_rate_hz: Hz of sim time, /clock.
        tf_rate_hz: Hz of sim time, /tf.
        wrench_rate_hz: Hz of sim time, contact wrenches and the ground-truth tip height.
        tool_state_rate_hz: Hz of sim time, /sim/scoop_state and /sim/grinder_state.
        terrain_publish_period: s of simulation time, minimum interval between /sim/terrain
            updates while carving (sim time: the terrains recorded are the same in every run).
        noise_seed: seed of the injected F/T sensor noise (>= 0; equal seeds, equal runs).
        lockstep_latency_s: s of sim time from a joint state to the commands a lockstep client
            decided on it (:mod:`ow_sim_bullet.lockstep`); at least the longest gap between two
            messages of /joint_states, /tf and the wrenches (:meth:`stream_gap_s`).
        lockstep_timeout_s: s of wall time a step waits for a lockstep client's acknowledgement
            before the client is dropped (a client that died).
        lockstep_clients: names of lockstep clients the simulation waits for from its start:
            it holds at t = 0 until each has registered (the mission's arm services).
        gains: PID gains by joint name.
        initial_positions: rad, joint positions at start-up and after a reset, by joint name.
        regolith: the regolith the simulation follows (materials, the terrain's layer columns,
            the scoop's and the dock's shapes, deposits; :class:`ow_regolith.config.
            RegolithConfig`, docs/regolith.md).
    """

    physics_rate_hz: float = 100.0
    real_time_factor: float = 1.0
    gravity: float = EUROPA_GRAVITY
    start_paused: bool = False
    gravity_feedforward: bool = True
    tool_contact: bool = True
    terrain: str = "europa:0"
    terrain_file_resolution: float = 0.04
    terrain_file_center: tuple[float, float] = (1.5, 0.0)
    terrain_png_height_range: tuple[float, float] = (-1.0, 1.0)
    terrain_material: int = 1
    terrain_friction: float = 0.8
    terrain_yield_force: float = 10.0
    carve_step: float = 0.003
    carve_full_force: float = 40.0
    carve_period: float = 0.05
    dig_forward_angle: float = 1.0
    dig_sink_angle: float = 1.48
    dig_slope: float = 0.35
    dig_exit_clearance: float = 0.02
    dig_timeout: float = 5.0
    grind_down_angle: float = 0.175
    terrain_forces: str = "none"
    terrain_force_params: Mapping[str, Any] = field(default_factory=dict)
    joint_state_rate_hz: float = 100.0
    clock_rate_hz: float = 100.0
    tf_rate_hz: float = 30.0
    wrench_rate_hz: float = 50.0
    tool_state_rate_hz: float = 10.0
    terrain_publish_period: float = 4.0
    noise_seed: int = 0
    lockstep_latency_s: float = 0.1
    lockstep_timeout_s: float = 30.0
    lockstep_clients: tuple[str, ...] = ()
    gains: Mapping[str, PidGains] = field(default_factory=_default_gains)
    initial_positions: Mapping[str, float] = field(default_factory=_default_initial)
    regolith: RegolithConfig = field(default_factory=RegolithConfig)

    @property
    def dt(self) -> float:
        """s, the physics step."""
        return 1.0 / self.physics_rate_hz

    def stream_gap_s(self) -> float:
        """s of sim time, the longest gap between two messages of the streams a lockstep client
        decides on (/joint_states, /tf, the wrenches): each is published on the first step at or
        after its tick."""
        dt = self.dt
        rates = (self.joint_state_rate_hz, self.tf_rate_hz, self.wrench_rate_hz)
        return max(math.ceil(1.0 / (rate * dt) - 1e-9) * dt for rate in rates)

    @classmethod
    def from_dict(cls, raw: Mapping[str, Any]) -> SimConfig:
        """Validate the node's private parameters; missing keys take the defaults above.

        Args:
            raw: parameter name -> value, as ``rospy.get_param('~')`` returns them.

        Raises:
            ConfigError: unknown keys, wrong types or out-of-range values, every one named with
                its key (``sim/<key>``) in one message; a misspelt key gets the nearest known one.
        """
        d = cls()
        p = Params(raw, "sim", ConfigError)
        gains_section = _joint_section(p, "gains")
        gains = dict(d.gains)
        for joint in gains_section.values:
            if joint in ALL_JOINTS:
                joint_gains = gains_section.section(joint)
                gains[joint] = PidGains.read(joint_gains)
                joint_gains.check_unknown()
        initial_section = _joint_section(p, "initial_positions")
        initial = dict(d.initial_positions)
        for joint in initial_section.values:
            if joint in ALL_JOINTS:
                initial[joint] = initial_section.number(joint, initial[joint], unit="rad")
        try:
            regolith = RegolithConfig.from_dict(p.raw("regolith"), p.name("regolith"))
        except RegolithConfigError as error:
            p.problem(str(error))
            regolith = d.regolith
        force_params = p.raw("terrain_force_params", {})
        if not isinstance(force_params, Mapping):
            p.problem(f"{p.name('terrain_force_params')} must be a mapping, got {force_params!r}")
            force_params = {}
        config = cls(
            physics_rate_hz=p.positive("physics_rate_hz", d.physics_rate_hz, "Hz"),
            real_time_factor=p.non_negative("real_time_factor", d.real_time_factor),
            gravity=p.positive("gravity", d.gravity, "m/s^2"),
            start_paused=p.boolean("start_paused", d.start_paused),
            gravity_feedforward=p.boolean("gravity_feedforward", d.gravity_feedforward),
            tool_contact=p.boolean("tool_contact", d.tool_contact),
            terrain=_non_empty(p, "terrain", d.terrain),
            terrain_file_resolution=p.positive(
                "terrain_file_resolution", d.terrain_file_resolution, "m"
            ),
            terrain_file_center=_pair(p, "terrain_file_center", d.terrain_file_center, "m"),
            terrain_png_height_range=_pair(
                p, "terrain_png_height_range", d.terrain_png_height_range, "m"
            ),
            terrain_material=p.integer("terrain_material", d.terrain_material, low=0, high=255),
            terrain_friction=p.non_negative("terrain_friction", d.terrain_friction),
            terrain_yield_force=p.non_negative("terrain_yield_force", d.terrain_yield_force, "N"),
            carve_step=p.non_negative("carve_step", d.carve_step, "m"),
            carve_full_force=p.non_negative("carve_full_force", d.carve_full_force, "N"),
            carve_period=p.positive("carve_period", d.carve_period, "s"),
            dig_forward_angle=_angle(p, "dig_forward_angle", d.dig_forward_angle),
            dig_sink_angle=_angle(p, "dig_sink_angle", d.dig_sink_angle),
            dig_slope=_angle(p, "dig_slope", d.dig_slope, math.pi / 2),
            dig_exit_clearance=p.non_negative("dig_exit_clearance", d.dig_exit_clearance, "m"),
            dig_timeout=p.positive("dig_timeout", d.dig_timeout, "s"),
            grind_down_angle=_angle(p, "grind_down_angle", d.grind_down_angle),
            terrain_forces=_non_empty(p, "terrain_forces", d.terrain_forces),
            terrain_force_params=dict(force_params),
            joint_state_rate_hz=p.positive("joint_state_rate_hz", d.joint_state_rate_hz, "Hz"),
            clock_rate_hz=p.positive("clock_rate_hz", d.clock_rate_hz, "Hz"),
            tf_rate_hz=p.positive("tf_rate_hz", d.tf_rate_hz, "Hz"),
            wrench_rate_hz=p.positive("wrench_rate_hz", d.wrench_rate_hz, "Hz"),
            tool_state_rate_hz=p.positive("tool_state_rate_hz", d.tool_state_rate_hz, "Hz"),
            terrain_publish_period=p.non_negative(
                "terrain_publish_period", d.terrain_publish_period, "s"
            ),
            noise_seed=p.integer("noise_seed", d.noise_seed, low=0),
            lockstep_latency_s=p.positive("lockstep_latency_s", d.lockstep_latency_s, "s"),
            lockstep_timeout_s=p.positive("lockstep_timeout_s", d.lockstep_timeout_s, "s"),
            lockstep_clients=p.names("lockstep_clients", d.lockstep_clients),
            gains=gains,
            initial_positions=initial,
            regolith=regolith,
        )
        if config.carve_full_force <= config.terrain_yield_force:
            p.problem(
                f"{p.name('carve_full_force')} = {config.carve_full_force:g} N must exceed "
                f"{p.name('terrain_yield_force')} = {config.terrain_yield_force:g} N"
            )
        gap = config.stream_gap_s()
        if config.lockstep_latency_s < gap - 1e-9:
            p.problem(
                f"{p.name('lockstep_latency_s')} = {config.lockstep_latency_s:g} s must be at "
                f"least {gap:g} s, the longest gap between /joint_states, /tf or wrench messages "
                "at these rates (a lockstep client would wait for a message the simulation cannot "
                "publish)"
            )
        low, high = config.terrain_png_height_range
        if high <= low:
            p.problem(f"{p.name('terrain_png_height_range')} must be increasing, got {[low, high]}")
        p.finish()
        return config
