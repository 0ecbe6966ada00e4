"""The sample-collection mission of the paper (section 3): its steps, results and report.

The steps, what each asks of the arm services given the ground found so far, the per-step results,
the energy windows and the report files; no ROS. ``ow_mission.mission_node`` runs the steps
against a live stack (``rosrun ow_mission mission``).
"""

from __future__ import annotations

import bisect
import datetime as dt
import json
import math
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ow_mission.fault_schedule import AppliedFault
from ow_mission.mission_config import MissionConfig
from ow_mission.node_config import stack_parameters


@dataclass
class StepResult:
    """One mission step, as reported.

    Attributes:
        step: mission step name (e.g. ``dig_spoil``).
        service: service called (e.g. ``/arm/dig_linear``).
        request: the request's fields.
        success: the service's answer (False also when the call failed).
        message: the service's message, or why the call failed.
        planning_time_s: s of wall time the service spent planning.
        wall_time_s: s of wall time of the whole call (planning and execution).
        sim_start_s: s, simulation time when the call was made.
        sim_end_s: s, simulation time when it returned.
        mechanical_energy_j: J, integral of the mechanical power over the step.
        energy_wh: Wh, integral of the total power (with P0) over the step.
        peak_power_w: W, peak total power (with P0) during the step.
        ground_z: m, ground height found (guarded move only).
        ground_position: (3,) m, contact point in base_link (guarded move only).
    """

    step: str
    service: str
    request: dict[str, Any]
    success: bool = False
    message: str = ""
    planning_time_s: float = 0.0
    wall_time_s: float = 0.0
    sim_start_s: float = 0.0
    sim_end_s: float = 0.0
    mechanical_energy_j: float = 0.0
    energy_wh: float = 0.0
    peak_power_w: float = 0.0
    ground_z: float | None = None
    ground_position: tuple[float, float, float] | None = None

    @property
    def sim_time_s(self) -> float:
        """s of simulation time the step took."""
        return self.sim_end_s - self.sim_start_s

    def take_response(self, response: Any) -> None:
        """Fill in what the service answered (any of the paper's responses: ``success``,
        ``message``, ``planning_time``; a guarded move's ``ground_found`` and
        ``ground_position``). A guarded move that succeeded without finding ground fails."""
        self.success = bool(response.success)
        self.message = str(response.message)
        self.planning_time_s = float(response.planning_time)
        if self.step != "guarded_move" or not self.success:
            return
        if not response.ground_found:
            self.success = False
            self.message = f"no ground found: {response.message}"
            return
        contact = response.ground_position
        self.ground_z = float(contact.z)
        self.ground_position = (float(contact.x), float(contact.y), self.ground_z)

    def take_energies(self, mechanical_j: float, total_j: float, peak_w: float) -> None:
        """Fill in the step's energy window (J, J, W; see :meth:`PowerTrace.window`)."""
        self.mechanical_energy_j = mechanical_j
        self.energy_wh = total_j / 3600.0
        self.peak_power_w = peak_w


@dataclass
class MissionReport:
    """The whole run."""

    config: MissionConfig
    run_dir: Path
    steps: list[StepResult] = field(default_factory=list)
    wall_time_s: float = 0.0
    sim_time_s: float = 0.0
    peak_memory_mb: float = 0.0
    ground_z: float | None = None
    error: str = ""
    #: What became of each entry of the mission's fault schedule.
    fault_schedule: list[AppliedFault] = field(default_factory=list)

    @property
    def success(self) -> bool:
        """True when every step of the mission succeeded."""
        return (
            not self.error and len(self.steps) == len(STEPS) and all(s.success for s in self.steps)
        )

    @property
    def failed_step(self) -> str | None:
        """Name of the step that failed, or None."""
        return next((s.step for s in self.steps if not s.success), None)

    @property
    def real_time_factor(self) -> float:
        """Simulation seconds per wall-clock second over the whole run."""
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else 0.0

    def table(self) -> str:
        """The per-operation table printed at the end of a run."""
        header = (
            f"{'step':<16}{'service':<22}{'plan s':>8}{'sim s':>9}{'signed J':>10}"
            f"{'E(P0) Wh':>10}{'peak+P0 W':>10}  result"
        )
        lines = [header, "-" * len(header)]
        for s in self.steps:
            lines.append(
                f"{s.step:<16}{s.service:<22}{s.planning_time_s:>8.3f}{s.sim_time_s:>9.1f}"
                f"{s.mechanical_energy_j:>10.1f}{s.energy_wh:>10.4f}{s.peak_power_w:>10.1f}  "
                f"{'ok' if s.success else 'FAILED: ' + s.message}"
            )
        lines.append("-" * len(header))
        lines.append(
            f"total: {self.wall_time_s:.1f} s wall, {self.sim_time_s:.1f} s simulated, "
            f"real-time factor {self.real_time_factor:.1f}x, "
            f"peak memory {self.peak_memory_mb:.0f} MB"
        )
        if self.error:
            lines.append(f"MISSION STOPPED: {self.error}")
        return "\n".join(lines)

    def to_json(self) -> dict[str, Any]:
        """Machine-readable report (``report.json``)."""
        return {
            "success": self.success,
            "error": self.error,
            "failed_step": self.failed_step,
            "wall_time_s": self.wall_time_s,
            "sim_time_s": self.sim_time_s,
            "real_time_factor": self.real_time_factor,
            "peak_memory_mb": self.peak_memory_mb,
            "ground_z": self.ground_z,
            "config": {k: v for k, v in asdict(self.config).items()},
            "steps": [{**asdict(s), "sim_time_s": s.sim_time_s} for s in self.steps],
            "fault_schedule": [f.to_json() for f in self.fault_schedule],
        }


@dataclass(frozen=True)
class Step:
    """A mission step: which service, and its request given the ground found so far."""

    name: str
    service: str
    srv_type: str
    request: Callable[[MissionConfig, float], dict[str, Any]]


def _trench_bottom(c: MissionConfig, ground: float) -> float:
    return ground - c.trench_depth


def _dig(name: str, depth: Callable[[MissionConfig], float], below: bool) -> Step:
    """A dig step (linear or circular per the mission) at the trench start."""

    def request(c: MissionConfig, ground: float) -> dict[str, Any]:
        surface = _trench_bottom(c, ground) if below else ground
        fields: dict[str, Any] = {"x": c.x, "y": c.y, "depth": depth(c), "ground_position": surface}
        if c.dig == "linear":
            fields["length"] = c.dig_length
        else:
            fields["parallel"] = c.parallel
        return fields

    return Step(name, "/arm/dig_{dig}", "Dig{Dig}", request)


STEPS: tuple[Step, ...] = (
    Step("unstow", "/arm/unstow", "Unstow", lambda c, g: {}),
    Step(
        "guarded_move",
        "/arm/guarded_move",
        "GuardedMove",
        lambda c, g: {
            "x": c.x,
            "y": c.y,
            "z": c.expected_ground + c.approach_height,
            "direction_x": 0.0,
            "direction_y": 0.0,
            "direction_z": 1.0,
            "search_distance": c.search_distance,
        },
    ),
    Step(
        "grind",
        "/arm/grind",
        "Grind",
        lambda c, g: {
            "x": c.x,
            "y": c.y,
            "depth": c.trench_depth,
            "length": c.trench_length,
            "parallel": c.parallel,
            "ground_position": g,
        },
    ),
    _dig("dig_spoil", lambda c: c.trench_depth, below=False),
    Step(
        "discard_spoil",
        "/arm/deliver_sample",
        "DeliverSample",
        lambda c, g: {"x": c.discard[0], "y": c.discard[1], "z": c.discard[2]},
    ),
    Step(
        "grind_bottom",
        "/arm/grind",
        "Grind",
        lambda c, g: {
            "x": c.x,
            "y": c.y,
            "depth": c.bottom_grind_depth,
            "length": c.trench_length,
            "parallel": c.parallel,
            "ground_position": _trench_bottom(c, g),
        },
    ),
    _dig("dig_sample", lambda c: c.bottom_grind_depth, below=True),
    Step(
        "deliver_sample",
        "/arm/deliver_sample",
        "DeliverSample",
        lambda c, g: {"use_defaults": True},
    ),
    Step("stow", "/arm/stow", "Stow", lambda c, g: {}),
)


class PowerTrace:
    """Cumulative energies from ``/power``, to integrate any window of simulation time."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.t: list[float] = []
        self.mechanical_j: list[float] = []
        self.energy_j: list[float] = []
        self.total_w: list[float] = []

    def add(self, t: float, mechanical_j: float, energy_j: float, total_w: float) -> None:
        """Record one ``/power`` message (stamp s, cumulative J, J, instantaneous W)."""
        with self._lock:
            self.t.append(t)
            self.mechanical_j.append(mechanical_j)
            self.energy_j.append(energy_j)
            self.total_w.append(total_w)

    def last_stamp_s(self) -> float:
        """s, stamp of the newest message (-inf before the first)."""
        with self._lock:
            return self.t[-1] if self.t else -math.inf

    def wait_until(self, t: float, timeout_s: float) -> bool:
        """Wait (wall time) until a message stamped at or after ``t`` s has arrived.

        The subscriber runs behind the simulation: a window closed before its last messages
        arrived would miss its end. Returns False when none came within ``timeout_s``.
        """
        deadline = time.monotonic() + timeout_s
        while self.last_stamp_s() < t:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.01)
        return True

    def window(self, t0: float, t1: float) -> tuple[float, float, float]:
        """(mechanical J, total J, peak total W) between simulation times t0 and t1."""
        with self._lock:
            if len(self.t) < 2:
                return 0.0, 0.0, 0.0
            t = np.asarray(self.t)
            mech = float(np.interp(t1, t, self.mechanical_j) - np.interp(t0, t, self.mechanical_j))
            total = float(np.interp(t1, t, self.energy_j) - np.interp(t0, t, self.energy_j))
            i0 = bisect.bisect_left(self.t, t0)
            i1 = bisect.bisect_right(self.t, t1)
            peak = max(self.total_w[i0:i1], default=0.0)
        return mech, total, float(peak)


def write_report(report: MissionReport) -> None:
    """Write ``report.json``, ``report.md`` and the figures into the run directory, all made
    from the run's bags after the run (:func:`ow_mission.report.write_run_report`).

    The steps' energies and peaks become the bags' (the numbers the power plot labels), so the
    table printed afterwards (:meth:`MissionReport.table`) agrees with ``report.md``.
    """
    from ow_mission.report import write_run_report

    document = report.to_json()
    document["config"]["terrain_spec"] = report.config.terrain_spec
    written = write_run_report(report.run_dir, document, renders=report.config.renders)
    for step, row in zip(report.steps, written["steps"], strict=True):
        step.mechanical_energy_j = float(row["mechanical_energy_j"])
        step.energy_wh = float(row["energy_wh"])
        step.peak_power_w = float(row["peak_power_w"])


#: The fault status topics (owl_msgs), in the report's order.
FAULT_STATUS_TOPICS = (
    "/arm_faults_status",
    "/pan_tilt_faults_status",
    "/power_faults_status",
    "/system_faults_status",
)
#: Fault topics the mission records: the status topics, the simulation's locked-joint flags and
#: the /faults server's configuration and its stamped changes.
FAULT_TOPICS = (
    *FAULT_STATUS_TOPICS,
    "/flags/joint_states",
    "/faults/parameter_updates",
    "/faults/changes",
)

#: Hz of sim time, the rate of the telemetry topics the mission records.
MISSION_TELEMETRY_HZ = 10.0


def node_parameters(config: MissionConfig, run_dir: Path) -> dict[str, dict[str, Any]]:
    """Private parameters of each node of the mission's stack: the packages' YAML files (as the
    launch files load them), then the mission's own settings, then its ``node_params``."""
    shipped = stack_parameters()
    mission: dict[str, dict[str, Any]] = {
        "sim": {
            "terrain": config.terrain_spec,
            "real_time_factor": config.real_time_factor,
            "terrain_forces": config.terrain_forces,
            # Paused until every node is up: a simulation running at full speed while the
            # others start would take their CPU and add idle minutes to the mission's sim time.
            "start_paused": True,
            # Deterministic (docs/determinism.md): the simulation waits for the arm services'
            # decisions on every joint state, from t = 0 until they have registered ...
            "lockstep_clients": ["/arm_services"],
        },
        "arm_services": {
            "plan_and_execute": True,
            "trajectory_dir": str(run_dir / "trajectories"),
            # ... and stops where each step ends, so the next starts there whenever it is called.
            "execution": {"lockstep": True, "lockstep_hold": True},
        },
        # OceanWATERS' telemetry in the bags at 10 Hz of sim time (the full-rate /joint_states
        # are there too); node_params {telemetry: {rate_hz: 0}} records one per joint state.
        "telemetry": {"rate_hz": MISSION_TELEMETRY_HZ},
        "record": {
            "output_dir": str(run_dir / "bags"),
            "prefix": "mission",
            # The terrain too: the trench the mission dug is part of its result; and the guarded
            # move's detector samples for the report's Figure 11.
            "topics": [
                *shipped["record"]["topics"],
                "/sim/terrain",
                "/sim/scoop_tip_ground",
                "/arm/ground_detector",
                "/battery_state_of_charge",
                "/battery_remaining_useful_life",
                "/battery_temperature",
                "/battery_state",
                # The faults: what the server holds, what the simulation flags, what the
                # detector reports (the report's faults section).
                *FAULT_TOPICS,
            ],
        },
    }
    params = stack_parameters(mission, config.node_params)
    execution = params["arm_services"].setdefault("execution", {})
    if not execution.get("lockstep"):  # node_params turned the lockstep off: no waiting
        execution["lockstep_hold"] = False
        params["sim"]["lockstep_clients"] = []
    return params


def new_run_dir(config: MissionConfig, workspace: Path) -> Path:
    """A run directory ``<output_dir>/<timestamp>[_n]`` that does not exist yet (an earlier run
    is never overwritten); a relative ``output_dir`` is taken from ``workspace``."""
    stamp = dt.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    base = Path(config.output_dir)
    base = base if base.is_absolute() else workspace / base
    run_dir, suffix = base / stamp, 1
    while run_dir.exists():
        run_dir, suffix = base / f"{stamp}_{suffix}", suffix + 1
    return run_dir


def load_report(run_dir: Path) -> Mapping[str, Any]:
    """The ``report.json`` of a run directory."""
    return json.loads((Path(run_dir) / "report.json").read_text())
