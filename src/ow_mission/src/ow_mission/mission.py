"""The autonomous sample-collection mission of the paper (section 3), through the real services.

``rosrun ow_mission mission [file.yaml]`` (and ``make demo``) starts a private rosmaster, the
simulation, the arm services (plan-and-execute), the power node and the bag recorder, then acts
as an autonomy client would: unstow; guarded move at the selected location; grind a trench; dig
it out and discard the spoil at a remote point; grind again at the bottom; dig the sample; deliver
it to the sample dock; stow. The ground the guarded move finds feeds every later step.

Everything goes to ``runs/<timestamp>/``: the bags, the trajectory files, ``report.md``,
``report.json``, the power plot and renders of the arm at key moments. A failed step stops the
mission; what was recorded up to then is kept and the report says what failed.
"""

from __future__ import annotations

import bisect
import datetime as dt
import json
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ow_lander.terrain import HeightMap
from ow_mission.errors import ConfigError
from ow_mission.mission_config import DEFAULT_MISSION_FILE, MissionConfig
from ow_mission.stack import HarnessError, NodeProcess, RosStack, private_master
from ow_power.config import DEFAULT_RECORD_TOPICS

#: s of wall time to wait for /power to catch up with the simulation clock.
POWER_WAIT_S = 5.0

#: Steps after which a render of the arm is taken.
RENDER_AFTER = ("guarded_move", "grind", "dig_sample", "deliver_sample")


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
            f"{'step':<16}{'service':<22}{'plan s':>8}{'sim s':>9}{'mech J':>10}"
            f"{'E(P0) Wh':>10}{'peak W':>9}  result"
        )
        lines = [header, "-" * len(header)]
        for s in self.steps:
            lines.append(
                f"{s.step:<16}{s.service:<22}{s.planning_time_s:>8.3f}{s.sim_time_s:>9.1f}"
                f"{s.mechanical_energy_j:>10.1f}{s.energy_wh:>10.4f}{s.peak_power_w:>9.1f}  "
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


class MissionRunner:
    """Starts the stack, runs the steps, writes the run directory.

    Args:
        config: the mission.
        workspace: directory a relative ``output_dir`` is taken from (the command line's
            working directory).
    """

    def __init__(self, config: MissionConfig, workspace: Path) -> None:
        self.config = config
        stamp = dt.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
        base = Path(config.output_dir)
        base = base if base.is_absolute() else workspace / base
        self.run_dir = base / stamp
        suffix = 1
        while self.run_dir.exists():  # never overwrite an earlier run
            self.run_dir = base / f"{stamp}_{suffix}"
            suffix += 1
        self.report = MissionReport(config, self.run_dir)
        self.power = PowerTrace()
        self._clock = 0.0
        self._joints: dict[str, float] = {}
        self._joint_stamp = 0.0
        self._terrain: HeightMap | None = None
        self._lock = threading.Lock()

    # ------------------------------------------------------------------------- ROS callbacks
    def _on_clock(self, msg: Any) -> None:
        self._clock = msg.clock.to_sec()

    def _on_joints(self, msg: Any) -> None:
        with self._lock:
            self._joints = dict(zip(msg.name, msg.position, strict=False))
            self._joint_stamp = msg.header.stamp.to_sec()

    def _last_joint_stamp(self, quiet_s: float = 0.05, limit_s: float = 2.0) -> float:
        """s, the stamp of the last /joint_states once none has arrived for ``quiet_s`` (wall):
        with the simulation paused, the last one it published."""
        deadline = time.monotonic() + limit_s
        while True:
            with self._lock:
                stamp = self._joint_stamp
            time.sleep(quiet_s)
            with self._lock:
                if self._joint_stamp == stamp or time.monotonic() > deadline:
                    return self._joint_stamp

    def _on_terrain(self, msg: Any) -> None:
        heights = np.asarray(msg.heights, dtype=np.float64).reshape(msg.rows, msg.cols)
        with self._lock:
            self._terrain = HeightMap(heights, msg.resolution, msg.origin_x, msg.origin_y)

    def _on_power(self, msg: Any) -> None:
        self.power.add(
            msg.header.stamp.to_sec(), msg.mechanical_energy, msg.energy, msg.total_power
        )

    # --------------------------------------------------------------------------------- run
    def node_params(self) -> dict[str, dict[str, Any]]:
        """Private parameters of each node of the stack (mission values, then overrides)."""
        c = self.config
        params: dict[str, dict[str, Any]] = {
            "sim": {
                "terrain": c.terrain_spec,
                "real_time_factor": c.real_time_factor,
                "terrain_forces": c.terrain_forces,
                # Paused until every node is up: a simulation running at full speed while the
                # others start would take their CPU and add idle minutes to the mission's sim time.
                "start_paused": True,
            },
            "arm_services": {
                "plan_and_execute": True,
                "trajectory_dir": str(self.run_dir / "trajectories"),
            },
            "power": {},
            "record": {
                "output_dir": str(self.run_dir / "bags"),
                "prefix": "mission",
                # The terrain too: the trench the mission dug is part of its result.
                "topics": [*DEFAULT_RECORD_TOPICS, "/sim/terrain", "/sim/scoop_tip_ground"],
            },
        }
        for node, extra in c.node_params.items():
            params.setdefault(node, {}).update(extra)
        return params

    def run(self) -> MissionReport:
        """Run the mission; never raises for a failed step (the report says what failed)."""
        wall0 = time.monotonic()
        self.run_dir.mkdir(parents=True)
        (self.run_dir / "renders").mkdir()
        nodes: list[NodeProcess] = []
        try:
            with private_master(self.run_dir / "ros") as master:
                os.environ.update(
                    ROS_MASTER_URI=master.uri,
                    ROS_HOSTNAME="127.0.0.1",
                    ROS_HOME=str(master.log_dir),
                )
                stack = RosStack(master)
                try:
                    nodes = self._start(stack)
                    self._run_steps()
                finally:
                    self.report.peak_memory_mb = _peak_memory_mb(nodes)
                    self.report.sim_time_s = self._clock
                    stack.shutdown()  # the recorder closes its bag on SIGINT
        except (HarnessError, ConfigError) as exc:
            self.report.error = str(exc)
        self.report.wall_time_s = time.monotonic() - wall0
        self._write_outputs()
        return self.report

    def _start(self, stack: RosStack) -> list[NodeProcess]:
        import rospy
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import JointState

        from ow_msgs.msg import HeightMap as HeightMapMsg
        from ow_msgs.msg import Power

        rospy.init_node("mission", disable_signals=True)
        params = self.node_params()
        # Started side by side (the simulation paused), then waited for: each node spends a
        # second or two importing, and they need nothing from one another to start.
        ready = {
            ("ow_power", "record"): ((), ()),
            ("ow_power", "power"): ((), ("/power",)),
            ("ow_sim_bullet", "sim"): (("/sim/resume",), ("/joint_states",)),
            ("ow_lander", "arm_services"): (
                tuple(s.service.format(dig=self.config.dig) for s in STEPS),
                (),
            ),
        }
        nodes = [
            stack.start_node(package, executable, params=params[executable], wait=False)
            for package, executable in ready
        ]
        for node, (services, topics) in zip(nodes, ready.values(), strict=True):
            stack.wait_ready(node, services, topics)
        rospy.Subscriber("/clock", Clock, self._on_clock, queue_size=10)
        rospy.Subscriber("/joint_states", JointState, self._on_joints, queue_size=10)
        rospy.Subscriber("/sim/terrain", HeightMapMsg, self._on_terrain, queue_size=1)
        rospy.Subscriber("/power", Power, self._on_power, queue_size=1000)
        # The sim node is ready (it offers /sim/resume): start its clock.
        error = self._sim_clock("resume")
        if error is not None:
            msg = f"could not start the simulation's clock: {error}"
            raise HarnessError(msg)
        # The first step's energy window must start inside the trace.
        if not self.power.wait_until(0.0, POWER_WAIT_S):
            msg = f"no /power message within {POWER_WAIT_S} s of subscribing"
            raise HarnessError(msg)
        return nodes

    def _run_steps(self) -> None:
        import rospy

        import ow_msgs.srv

        c = self.config
        ground = c.expected_ground
        for step in STEPS:
            service = step.service.format(dig=c.dig)
            srv_name = step.srv_type.format(Dig=c.dig.capitalize())
            fields = step.request(c, ground)
            result = StepResult(step.name, service, fields)
            self.report.steps.append(result)
            proxy = rospy.ServiceProxy(service, getattr(ow_msgs.srv, srv_name))
            # The simulation runs only during the steps: what the mission does in between
            # (energies, renders) neither adds sim time nor competes with it for the CPU.
            result.sim_start_s = self._clock
            self._sim_clock_between_steps("resume")
            wall0 = time.monotonic()
            try:
                response = _call_with_timeout(proxy, fields, c.step_timeout_s)
            except (rospy.ServiceException, TypeError) as exc:
                result.message = f"service call failed: {exc}"
                response = None
            except TimeoutError:
                result.message = (
                    f"no answer within step_timeout_s = {c.step_timeout_s:g} s of wall time"
                )
                response = None
            result.wall_time_s = time.monotonic() - wall0
            self._sim_clock_between_steps("pause")
            # The power node computes /power from each /joint_states: the step's window ends
            # at the last one, which the power trace then reaches.
            result.sim_end_s = self._last_joint_stamp()
            self.power.wait_until(result.sim_end_s, POWER_WAIT_S)
            if response is not None:
                result.success = bool(response.success)
                result.message = response.message
                result.planning_time_s = float(response.planning_time)
            mech, total, peak = self.power.window(result.sim_start_s, result.sim_end_s)
            result.mechanical_energy_j = mech
            result.energy_wh = total / 3600.0
            result.peak_power_w = peak
            if step.name == "guarded_move" and result.success:
                if not response.ground_found:
                    result.success = False
                    result.message = f"no ground found: {response.message}"
                else:
                    contact = response.ground_position
                    ground = float(contact.z)
                    result.ground_z = ground
                    result.ground_position = (float(contact.x), float(contact.y), ground)
                    self.report.ground_z = ground
            print(
                f"[mission] {step.name}: {'ok' if result.success else 'FAILED'} "
                f"({result.wall_time_s:.2f} s wall) {result.message}",
                flush=True,
            )
            if self.config.renders and step.name in RENDER_AFTER:
                self._render(step.name)
            if not result.success:
                self.report.error = f"step {step.name} ({service}) failed: {result.message}"
                return

    def _sim_clock(self, action: str) -> str | None:
        """Call ``/sim/pause`` or ``/sim/resume``; None on success, else what went wrong."""
        import rospy
        from std_srvs.srv import Trigger

        try:
            reply = rospy.ServiceProxy(f"/sim/{action}", Trigger)()
        except (rospy.ROSException, rospy.ServiceException) as exc:
            return f"/sim/{action} failed: {exc}"
        return None if reply.success else f"/sim/{action} refused: {reply.message}"

    def _sim_clock_between_steps(self, action: str) -> None:
        """:meth:`_sim_clock`, a failure printed, not fatal (the step's own checks report a
        simulation that does not run)."""
        error = self._sim_clock(action)
        if error is not None:
            print(f"[mission] {error}", flush=True)

    def _render(self, label: str) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from ow_mission.render import Camera, render_scene

        with self._lock:
            joints = dict(self._joints)
            terrain = self._terrain
        index = len(list((self.run_dir / "renders").glob("*.png")))
        image = render_scene(joints, terrain, Camera(target=(self.config.x, self.config.y, 0.1)))
        plt.imsave(self.run_dir / "renders" / f"{index:02d}_{label}.png", image)

    # ------------------------------------------------------------------------------ outputs
    def _write_outputs(self) -> None:
        report = self.report
        (self.run_dir / "report.json").write_text(json.dumps(report.to_json(), indent=2))
        plot = self._power_plot()
        lines = [
            f"# Mission report: {report.config.name}",
            "",
            f"Result: **{'success' if report.success else 'FAILED'}**"
            + (f": {report.error}" if report.error else ""),
            "",
            f"Terrain `{report.config.terrain_spec}`, trench at "
            f"({report.config.x:.3f}, {report.config.y:.3f}) m in base_link; ground found at "
            + (f"z = {report.ground_z:.4f} m." if report.ground_z is not None else "(none)."),
            "",
            "```",
            report.table(),
            "```",
            "",
        ]
        if plot:
            lines += ["![power over time](power.png)", "", plot, ""]
        for png in sorted((self.run_dir / "renders").glob("*.png")):
            lines.append(f"![{png.stem}](renders/{png.name})")
        lines += [
            "",
            "Files: `bags/` (ROS 1 bags: /power, /joint_states, /arm/operation, ...), "
            "`trajectories/` (the planned CSV trajectories), `ros/` (node logs).",
        ]
        (self.run_dir / "report.md").write_text("\n".join(lines) + "\n")

    def _power_plot(self) -> str:
        """Plot power over time from the bags with operations marked; '' or a note on failure."""
        bags = sorted((self.run_dir / "bags").glob("*.bag"))
        if not bags:
            return "No bag was recorded."
        try:
            from ow_power.analysis import analyze, plot_power

            plot_power(analyze(bags), self.run_dir / "power.png")
        except Exception as exc:  # a plot must never cost the user the rest of the report
            return f"The power plot could not be made: {exc}"
        return ""


def _call_with_timeout(
    proxy: Callable[..., Any], fields: Mapping[str, Any], timeout_s: float
) -> Any:
    """``proxy(**fields)``, or TimeoutError after ``timeout_s`` s of wall time.

    A call that times out is left running in a daemon thread; the mission then stops and shuts
    the stack down, which ends it.

    Raises:
        TimeoutError: no answer within ``timeout_s``.
        Exception: whatever the call raised.
    """
    outcome: dict[str, Any] = {}

    def call() -> None:
        try:
            outcome["response"] = proxy(**fields)
        except Exception as exc:  # re-raised in the caller's thread
            outcome["error"] = exc

    worker = threading.Thread(target=call, name="mission-step", daemon=True)
    worker.start()
    worker.join(timeout_s)
    if worker.is_alive():
        raise TimeoutError
    if "error" in outcome:
        raise outcome["error"]
    return outcome["response"]


def _peak_memory_mb(nodes: list[NodeProcess]) -> float:
    """MB, sum of the peak resident memory (VmHWM) of the stack's node processes and this one."""
    pids = [os.getpid()]
    for node in nodes:
        pids += _process_tree(node.proc.pid)
    total_kb = 0
    for pid in pids:
        try:
            for line in Path(f"/proc/{pid}/status").read_text().splitlines():
                if line.startswith("VmHWM:"):
                    total_kb += int(line.split()[1])
        except OSError:
            continue
    return total_kb / 1024.0


def _process_tree(pid: int) -> list[int]:
    out = [pid]
    try:
        children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return out
    for child in children:
        out += _process_tree(int(child))
    return out


def main(argv: list[str] | None = None) -> int:
    """``rosrun ow_mission mission [file]``: run a mission, print the table; 0 on success."""
    args = sys.argv[1:] if argv is None else argv
    args = [a for a in args if ":=" not in a]  # ROS remapping arguments added by rosrun/roslaunch
    if len(args) > 1 or (args and args[0] in ("-h", "--help")):
        print(
            f"usage: rosrun ow_mission mission [mission.yaml]   (default: {DEFAULT_MISSION_FILE})"
        )
        return 0 if args and args[0] in ("-h", "--help") else 2
    path = Path(args[0]) if args else DEFAULT_MISSION_FILE
    try:
        config = MissionConfig.load(path)
    except ConfigError as exc:
        print(f"mission: {exc}", file=sys.stderr)
        return 2
    runner = MissionRunner(config, Path.cwd())
    print(f"[mission] {config.name}: writing {runner.run_dir}", flush=True)
    report = runner.run()
    print(report.table())
    print(f"[mission] report: {runner.run_dir / 'report.md'}")
    return 0 if report.success else 1


def load_report(run_dir: Path) -> Mapping[str, Any]:
    """The ``report.json`` of a run directory."""
    return json.loads((Path(run_dir) / "report.json").read_text())
