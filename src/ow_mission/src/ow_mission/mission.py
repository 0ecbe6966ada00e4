"""The sample-collection mission of the paper (section 3): its steps, results and report.

The steps, what each asks of the arm services given the ground found so far, the per-step results,
the energy windows and the report files; no ROS. ``ow_mission.mission_node`` runs the steps
against a live stack (``rosrun ow_mission mission``).
"""

from __future__ import annotations

import datetime as dt
import json
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ow_bringup.node_config import SERVE_DOCK_INGEST, SERVE_FAULTS, STACK_NODES, stack_parameters
from ow_cameras.protocol import CAMERA_CAPTURE
from ow_dem_bridge.api import LIVE_MODEL_NAME
from ow_faults.protocol import CHANGES_TOPIC
from ow_mission.bag_prefetch import BagPrefetch
from ow_mission.fault_schedule import AppliedFault
from ow_mission.figures import FiguresProcess, start_figures
from ow_mission.mission_config import LIVE_DEM_RECORD_TOPICS, MissionConfig
from ow_mission.workspace_capture import mast_aim
from ow_power.config import BATTERY_TOPICS, TELEMETRY_TOPICS
from ow_runtime.names import (
    ARM_FAULTS_STATUS,
    ARM_GROUND_DETECTOR,
    ARM_JOINT_POSITIONS,
    ARM_UNSTOW,
    BATTERY_STATE_OF_CHARGE,
    FLAGS_JOINT_STATES,
    JOINT_STATES,
    MATERIAL_INGESTED,
    PAN_TILT_FAULTS_STATUS,
    POWER,
    POWER_FAULTS_STATUS,
    REGOLITH_BUDGET,
    ROBOT_DESCRIPTION,
    SIM_RESUME,
    STAMP_SLACK_S,
    SYSTEM_FAULTS_STATUS,
    TERRAIN_TOPIC,
)


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
    #: What the bags may lack: the recorder had not written everything the run's last state
    #: caused when the stack had to stop ("" when it had).
    recording_note: str = ""
    #: What became of each entry of the mission's fault schedule.
    fault_schedule: list[AppliedFault] = field(default_factory=list)
    #: The stereo capture of the workspace before the first arm step
    #: (:func:`ow_mission.workspace_capture.write_capture`), None before it was tried.
    capture: dict[str, Any] | None = None
    #: DockIngestSample after the delivery (:class:`Ingestion`), None before it was tried.
    ingestion: Ingestion | None = None

    @property
    def success(self) -> bool:
        """True when every step of the mission succeeded and a sample was ingested."""
        return (
            not self.error
            and len(self.steps) == len(mission_steps(self.config))
            and all(s.success for s in self.steps)
            and self.ingestion is not None
            and self.ingestion.sample_ingested
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
        if self.ingestion is not None:
            lines.append(f"sample: {self.ingestion.summary()}")
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
            "recording_note": self.recording_note,
            "config": {k: v for k, v in asdict(self.config).items()},
            "steps": [{**asdict(s), "sim_time_s": s.sim_time_s} for s in self.steps],
            "fault_schedule": [f.to_json() for f in self.fault_schedule],
            "capture": self.capture,
            "ingestion": None if self.ingestion is None else asdict(self.ingestion),
        }


#: The action that ingests what lies in the sample dock (ow_lander, OceanWATERS HEAD).
DOCK_INGEST_SAMPLE = "DockIngestSample"


@dataclass
class Ingestion:
    """DockIngestSample after the delivery, as reported.

    Attributes:
        sample_ingested: the action's result: regolith lay in the dock and was ingested (its
            volume is then > 0; the report gives it, from the bags).
        succeeded: the goal ended SUCCEEDED (it also does when the dock was empty).
        message: the goal's status text (OceanWATERS': "Sample ingested", "No sample was
            present in dock", "Removal service failed: ..."), or why no goal ended.
        sim_time_s: s, simulation time at which the sample was ingested.
        wall_time_s: s of wall time the goal took.
    """

    sample_ingested: bool = False
    succeeded: bool = False
    message: str = ""
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0

    def summary(self) -> str:
        """One line: ingested, or why the mission has no sample."""
        if self.sample_ingested:
            return f"ingested ({DOCK_INGEST_SAMPLE}: {self.message})"
        return f"none ingested: {self.failure()}"

    def failure(self) -> str:
        """Why no sample was ingested ("" when one was)."""
        if self.sample_ingested:
            return ""
        if self.succeeded:
            return (
                f"{DOCK_INGEST_SAMPLE}: {self.message}: the delivery left no regolith in the "
                "sample dock"
            )
        return f"{DOCK_INGEST_SAMPLE} failed: {self.message}"


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
    Step("unstow", ARM_UNSTOW, "Unstow", lambda c, g: {}),
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


#: The steps that make the first trench (the paper: grind the irradiated top 10 cm, dig it out
#: and discard it). A mission with ``trench_depth: 0`` leaves them out and samples the surface.
FIRST_TRENCH_STEPS = ("grind", "dig_spoil", "discard_spoil")


def mission_steps(config: MissionConfig) -> tuple[Step, ...]:
    """The steps ``config`` runs: :data:`STEPS`, without :data:`FIRST_TRENCH_STEPS` when its
    ``trench_depth`` is 0 (the bottom grind and the sample's dig then start at the ground)."""
    if config.trench_depth > 0.0:
        return STEPS
    return tuple(s for s in STEPS if s.name not in FIRST_TRENCH_STEPS)


def write_report(
    report: MissionReport, prefetch: BagPrefetch | None = None
) -> FiguresProcess | None:
    """Write ``report.json`` and ``report.md`` into the run directory, made from the run's bags
    after the run (:func:`ow_mission.report.write_run_report`; ``prefetch``: the files closed
    before the stack stopped, read while it stopped), with the figures (``figures: inline``)
    or without them (the numbers are the same), their process started (``after_exit``) or
    left for whoever wants them (``none``: ``python -m ow_mission.figures RUN_DIR``).

    The steps' energies and peaks become the bags' (the numbers the power plot labels), so the
    table printed afterwards (:meth:`MissionReport.table`) agrees with ``report.md``.

    Returns:
        The process making the figures (``after_exit``), or None.
    """
    from ow_mission.report import write_run_report

    document = report.to_json()
    document["config"]["terrain_spec"] = report.config.terrain_spec
    written = write_run_report(
        report.run_dir,
        document,
        renders=report.config.renders,
        prefetch=prefetch,
        draw=report.config.figures == "inline",
    )
    for step, row in zip(report.steps, written["steps"], strict=True):
        step.mechanical_energy_j = float(row["mechanical_energy_j"])
        step.energy_wh = float(row["energy_wh"])
        step.peak_power_w = float(row["peak_power_w"])
    if report.config.figures != "after_exit":
        return None
    return start_figures(report.run_dir, report.config.renders)


#: The fault status topics (owl_msgs), in the report's order.
FAULT_STATUS_TOPICS = (
    ARM_FAULTS_STATUS,
    PAN_TILT_FAULTS_STATUS,
    POWER_FAULTS_STATUS,
    SYSTEM_FAULTS_STATUS,
)
#: Fault topics the mission records: the status topics, the simulation's locked-joint flags and
#: the /faults server's configuration and its stamped changes.
FAULT_TOPICS = (
    *FAULT_STATUS_TOPICS,
    FLAGS_JOINT_STATES,
    "/faults/parameter_updates",
    CHANGES_TOPIC,
)

#: Hz of sim time, /clock in the mission's stack (the simulation's default: 100 Hz). Every
#: node takes every /clock message; at 100 Hz that was 16 % of the mission's CPU time.
MISSION_CLOCK_HZ = 10.0

#: Hz of sim time, the arm services' periodic action status in the mission (actionlib's
#: default: 5 Hz). At 5 Hz the 14 servers' heartbeats took a fifth of the node's CPU time.
MISSION_ACTION_STATUS_HZ = 1.0

#: Hz of sim time, the rate of the telemetry topics the mission records.
MISSION_TELEMETRY_HZ = 10.0


def drain_periods(params: Mapping[str, Mapping[str, Any]]) -> dict[str, float]:
    """The recorded topics that follow the simulation's states, each with its period (s of sim
    time; 0: one message per joint state), from the stack's parameters (:func:`node_parameters`).

    When the simulation stands at the end of a run, each node may still be working through the
    states it has received. The recorder holds all of the run once each of these topics has a
    message within its period of the end (:func:`topics_behind`); stopping the stack before
    that lost the last 0.35 s of ``/power`` of a loaded run, and made its replay differ.
    """
    telemetry_hz = float(params["telemetry"].get("rate_hz", 0.0))
    battery_hz = float(params["battery"].get("update_rate_hz", 1.0))
    periods = {JOINT_STATES: 0.0, POWER: 0.0}
    periods.update(dict.fromkeys(TELEMETRY_TOPICS, 1.0 / telemetry_hz if telemetry_hz > 0 else 0.0))
    periods.update(dict.fromkeys(BATTERY_TOPICS, 1.0 / battery_hz))
    recorded = set(params["record"]["topics"])
    return {topic: period for topic, period in periods.items() if topic in recorded}


#: s (wall), how long a mission waits for the recorder to hold its run before stopping the stack.
DRAIN_TIMEOUT_S = 30.0


def topics_behind(
    latest_s: Mapping[str, float], end_s: float, periods: Mapping[str, float]
) -> dict[str, float]:
    """Of the ``periods``' topics, those the recorder has not yet written up to ``end_s``: a
    topic is behind while its newest record time is more than its period before the end.
    Topics the recorder has had no message of are not waited for (their node is not running).

    Args:
        latest_s: topic -> s (sim), the newest record time written (``~progress``).
        end_s: s (sim), where the simulation stands.
        periods: topic -> s (sim), from :func:`drain_periods`.

    Returns:
        topic -> its newest record time, for each topic behind.
    """
    return {
        topic: latest_s[topic]
        for topic, period in periods.items()
        if topic in latest_s and latest_s[topic] < end_s - period - STAMP_SLACK_S
    }


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
            # Every rospy node receives /clock; the mission's nodes work on the states' stamps
            # and the clock reaches every time the simulation stops at (docs/performance.md).
            "clock_rate_hz": MISSION_CLOCK_HZ,
            # The mast looks at the trench from the start: the capture before the first arm
            # step sees it, and no step of the simulation moves the mast (node_params may).
            "initial_positions": mast_aim(asdict(config)),
        },
        # The paper's power: OceanWATERS' mast lights draw 9.6 W all the time at full
        # intensity, which would add to every step's energy with P0; the sun lights the
        # capture (node_params {camera: {lights: {left: 1, right: 1}}} turns them on).
        "camera": {
            "actionlib_status_frequency": MISSION_ACTION_STATUS_HZ,
            "lights": {"left": 0.0, "right": 0.0},
        },
        "arm_services": {
            "plan_and_execute": True,
            "trajectory_dir": str(run_dir / "trajectories"),
            # ... and stops where each step ends, so the next starts there whenever it is called.
            "execution": {"lockstep": True, "lockstep_hold": True},
            # actionlib's heartbeat of each of the 14 servers' status (every transition is
            # published when it happens; clients connect on the first status they receive).
            "actionlib_status_frequency": MISSION_ACTION_STATUS_HZ,
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
                TERRAIN_TOPIC,
                "/sim/scoop_tip_ground",
                ARM_GROUND_DETECTOR,
                *BATTERY_TOPICS,
                # The faults: what the server holds, what the simulation flags, what the
                # detector reports (the report's faults section).
                *FAULT_TOPICS,
                # The regolith: where the scooped volume went, and the sample ingested (the
                # report's sample section).
                REGOLITH_BUDGET,
                MATERIAL_INGESTED,
                # With the live DEM: its forces and digs (the report's live DEM section).
                *(LIVE_DEM_RECORD_TOPICS if config.terrain_forces == LIVE_MODEL_NAME else ()),
            ],
        },
    }
    params = stack_parameters(mission, config.node_params)
    execution = params["arm_services"].setdefault("execution", {})
    if not execution.get("lockstep"):  # node_params turned the lockstep off: no waiting
        execution["lockstep_hold"] = False
        params["sim"]["lockstep_clients"] = []
    return params


#: The stack's nodes the mission runs as components of one node, ``ow_mission monitors``: each
#: stream is then received once for all of them, and one Python process starts instead of six
#: (the fault server is one, ~30 MB, for a few requests a mission).
MONITORS = ("power", "battery", "telemetry", "viz", "detector", "faults")

#: What shows a node of the stack is ready: (services it offers, topics it publishes).
READY: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "record": ((), ()),
    "power": ((), (POWER,)),
    "battery": ((), (BATTERY_STATE_OF_CHARGE,)),
    "sim": ((SIM_RESUME,), (JOINT_STATES,)),
    "arm_services": ((), ()),  # and the services of the mission's steps
    "viz": ((), (ROBOT_DESCRIPTION,)),
    "telemetry": ((), (ARM_JOINT_POSITIONS,)),
    # Its action servers (the renderer starts beside them; a capture asked for meanwhile waits).
    "camera": ((), (f"/{CAMERA_CAPTURE}/status",)),
    "faults": (("/faults/set_parameters",), ("/faults/parameter_updates",)),
    "detector": ((), (SYSTEM_FAULTS_STATUS,)),
}


@dataclass(frozen=True)
class StackProcess:
    """A process of the mission's stack: ``rosrun <package> <executable>`` with ``params`` in
    its private namespace, ready once it offers ``services`` and publishes ``topics``."""

    package: str
    executable: str
    params: dict[str, Any]
    services: tuple[str, ...]
    topics: tuple[str, ...]


def stack_processes(params: Mapping[str, dict[str, Any]], dig: str) -> list[StackProcess]:
    """The mission's processes, in start order, from the nodes' parameters
    (:func:`node_parameters`): every node of :data:`STACK_NODES` on its own, but those of
    :data:`MONITORS`, which are components of one ``monitors`` node, each with its parameters
    in that node's namespace of its name. The arm services are ready once they offer the
    services of the mission's steps (``dig``: "linear" or "circular")."""
    ready = {**READY, "arm_services": (tuple(s.service.format(dig=dig) for s in STEPS), ())}
    processes = []
    # DockIngestSample, after the delivery: served by the monitors (the stack has no pan_tilt).
    monitors: dict[str, Any] = {SERVE_DOCK_INGEST: True}
    services: tuple[str, ...] = ()
    topics: tuple[str, ...] = (f"/{DOCK_INGEST_SAMPLE}/status",)
    for node in STACK_NODES:
        ready_services, ready_topics = ready[node.executable]
        if node.executable in MONITORS:
            if node.executable == "faults":
                monitors[SERVE_FAULTS] = True
            if params[node.executable]:
                monitors[node.executable] = params[node.executable]
            services, topics = services + ready_services, topics + ready_topics
            continue
        processes.append(
            StackProcess(
                node.package, node.executable, params[node.executable], *ready[node.executable]
            )
        )
    processes.append(StackProcess("ow_bringup", "monitors", monitors, services, topics))
    return processes


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
