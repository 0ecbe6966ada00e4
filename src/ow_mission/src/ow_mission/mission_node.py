"""``rosrun ow_mission mission [file.yaml]`` (and ``make demo``): the paper's sample-collection
mission (section 3) through the real services, as an autonomy client runs it (see
``docs/mission.md``). It starts a private master and the stack configured by
:mod:`ow_bringup.node_config`, calls the steps of :func:`ow_mission.mission.mission_steps`,
ingests the delivered sample (DockIngestSample) and writes ``runs/<timestamp>/``; a failed step,
or a delivery that left nothing to ingest, stops it, keeping everything recorded up to then. Before
the first step it captures the workspace with the stereo camera
(:mod:`ow_mission.workspace_capture`).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import rospy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

import ow_msgs.srv
from ow_bringup.processes import peak_memory_mb
from ow_bringup.stack import (
    HarnessError,
    NodeProcess,
    RosStack,
    call_with_timeout,
    private_master,
    wait_until,
)
from ow_description.description import ANTENNA_JOINTS
from ow_mission.action_client_node import ActionStepClient, ingest_sample
from ow_mission.bag_prefetch import BagPrefetch
from ow_mission.camera_client_node import capture_workspace
from ow_mission.errors import CaptureError
from ow_mission.fault_schedule_node import FaultScheduleRunner
from ow_mission.figures import FiguresProcess, tell_figures
from ow_mission.mission import (
    DRAIN_TIMEOUT_S,
    MissionReport,
    StepResult,
    drain_periods,
    mission_steps,
    new_run_dir,
    node_parameters,
    stack_processes,
    write_report,
)
from ow_mission.mission_config import USAGE, WAIT_FIGURES, MissionConfig, config_from_argv
from ow_mission.report import preload, report_reader
from ow_mission.stack_client_node import sim_clock, stands_at, wait_recorded
from ow_mission.workspace_capture import failed_capture, trench_footprint, write_capture
from ow_runtime.errors import ConfigError as AnyConfigError
from ow_runtime.lockstep_client import LockstepError, wait_until_held
from ow_runtime.names import CLOCK, JOINT_STATES
from ow_runtime.node import init_node, signal_shutdown


class MissionRunner:
    """Starts the stack, runs the steps, writes the run directory.

    Args:
        config: the mission.
        workspace: directory a relative ``output_dir`` is taken from (the command line's
            working directory).
    """

    def __init__(self, config: MissionConfig, workspace: Path) -> None:
        self.config = config
        self.run_dir = new_run_dir(config, workspace)
        self.report = MissionReport(config, self.run_dir)
        self._clock = self._joint_stamp = 0.0  # s (sim), the newest received
        self._lock = threading.Lock()
        self._actions = ActionStepClient(config.dig) if config.interface == "actions" else None
        self._faults: FaultScheduleRunner | None = None
        self._drain: dict[str, float] = {}
        self._hold = False  # the stack holds the simulation between steps (lockstep)
        self._aim: dict[str, float] = {}  # rad by joint, the mast's pan and tilt from the start
        self.figures: FiguresProcess | None = None  # drawing them after the mission (after_exit)

    # ------------------------------------------------------------------------- ROS callbacks
    def _on_clock(self, msg: Any) -> None:
        self._clock = msg.clock.to_sec()

    def _on_joints(self, msg: Any) -> None:
        with self._lock:
            self._joint_stamp = msg.header.stamp.to_sec()

    def _last_joint_stamp(self, quiet_s: float = 0.05, limit_s: float = 2.0) -> float:
        """s, the last /joint_states stamp once none came for ``quiet_s`` (wall): a paused sim's."""
        deadline = time.monotonic() + limit_s
        while True:
            with self._lock:
                stamp = self._joint_stamp
            time.sleep(quiet_s)
            with self._lock:
                if self._joint_stamp == stamp or time.monotonic() > deadline:
                    return self._joint_stamp

    # --------------------------------------------------------------------------------- run
    def run(self) -> MissionReport:
        """Run the mission; never raises for a failed step (the report says what failed)."""
        wall0 = time.monotonic()
        self.run_dir.mkdir(parents=True)
        (self.run_dir / "renders").mkdir()
        nodes: list[NodeProcess] = []
        prefetch: BagPrefetch | None = None
        try:
            # The master on threads of this process: ~40 MB less than a process of its own.
            with private_master(self.run_dir / "ros", in_process=True) as master:
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
                    if self._faults is not None:
                        self._faults.stop()
                        self.report.fault_schedule = self._faults.results()
                    self.report.peak_memory_mb = peak_memory_mb(node.proc.pid for node in nodes)
                    # Nothing more happens: stopping the nodes lets the simulation step on
                    # (a lockstep client leaving), and a loaded run recorded one step more.
                    sim_clock("pause", between_steps=True)
                    try:  # where the lockstep holds it (its last /clock may be on its way)
                        end, state = stands_at(5.0) if self._hold else (self._clock, -1.0)
                    except LockstepError:
                        end, state = 0.0, -1.0
                    state = state if state >= 0.0 else self._last_joint_stamp()
                    self.report.sim_time_s = max(end, state, self._clock)
                    # The report's imports while the stack stops (not during the steps).
                    draws = self.config.figures == "inline"
                    threading.Thread(target=preload, args=(draws,), daemon=True).start()
                    # Stop once the recorder has the last states (a loaded run lost 0.35 s).
                    self.report.recording_note = wait_recorded(state, self._drain, DRAIN_TIMEOUT_S)
                    # The closed split files are read while the stack stops (docs/mission.md).
                    prefetch = BagPrefetch(self.run_dir / "bags", report_reader(self.config))
                    stack.shutdown(last=("record",), delete_params=False)  # the bag: at SIGINT
                    signal_shutdown("mission done")  # leaves the master while it runs
        except (HarnessError, AnyConfigError) as exc:
            self.report.error = str(exc)
        self.report.wall_time_s = time.monotonic() - wall0
        self.figures = write_report(self.report, prefetch)
        return self.report

    def _start(self, stack: RosStack) -> list[NodeProcess]:
        params = node_parameters(self.config, self.run_dir)
        self._drain = drain_periods(params)
        self._hold = bool(params["arm_services"]["execution"].get("lockstep_hold"))
        initial = params["sim"]["initial_positions"]
        self._aim = {joint: float(initial[joint]) for joint in ANTENNA_JOINTS}
        # Started side by side (the simulation paused), then waited for: each node spends a
        # second or two importing, and they need nothing from one another to start.
        processes = stack_processes(params, self.config.dig)
        nodes = [
            stack.start_node(p.package, p.executable, params=p.params, wait=False)
            for p in processes
        ]
        init_node("mission", disable_signals=True)  # while they import (rospy's takes 0.1 s)
        for node, process in zip(nodes, processes, strict=True):
            stack.wait_ready(node, process.services, process.topics)
        rospy.Subscriber(CLOCK, Clock, self._on_clock, queue_size=10)
        if not self._hold:  # the lockstep says where each step starts and ends
            rospy.Subscriber(JOINT_STATES, JointState, self._on_joints, queue_size=10)
        self._faults = FaultScheduleRunner(self.config.faults, stack.master.publishers, self._hold)
        # All connected before the first state is published: equal runs record equal messages.
        if not wait_until(lambda: not stack.master.unconnected(), 10.0):
            print("[mission] not every subscription connected within 10 s", flush=True)
        self._faults.start(self._clock)  # those due at t = 0 in place; the next one held for
        error = sim_clock("resume")  # the sim offers /sim/resume: start its clock
        if error is not None:
            msg = f"could not start the simulation's clock: {error}"
            raise HarnessError(msg)
        return nodes

    def _run_steps(self) -> None:
        c = self.config
        ground = c.expected_ground
        held = self._held()  # where the lockstep holds the simulation (None: no lockstep)
        self._capture_workspace()
        for step in mission_steps(c):
            service = step.service.format(dig=c.dig)
            srv_name = step.srv_type.format(Dig=c.dig.capitalize())
            fields = step.request(c, ground)
            result = StepResult(step.name, service, fields)
            self.report.steps.append(result)
            # The simulation runs only during the steps: what the mission does in between
            # (energies, renders) neither adds sim time nor competes with it for the CPU. In the
            # lockstep it stands where the last step ended (docs/determinism.md).
            result.sim_start_s = self._last_joint_stamp() if held is None else held
            if self._faults is not None:  # faults due at the step's start, before it runs
                self._faults.step_started(step.name, result.sim_start_s)
            sim_clock("resume", between_steps=True)
            wall0 = time.monotonic()
            try:
                if self._actions is not None:
                    response: Any = self._actions.call(step.name, fields, c.step_timeout_s)
                else:
                    proxy = rospy.ServiceProxy(service, getattr(ow_msgs.srv, srv_name))
                    response = call_with_timeout(proxy, fields, c.step_timeout_s)
            except (rospy.ServiceException, TypeError) as exc:
                result.message = f"service call failed: {exc}"
                response = None
            except TimeoutError:
                result.message = f"no answer within step_timeout_s = {c.step_timeout_s:g} s (wall)"
                response = None
            result.wall_time_s = time.monotonic() - wall0
            held = self._held()  # in the lockstep the step ends where it is held
            sim_clock("pause", between_steps=True)
            # Its energies come from the bags' /power over [sim_start_s, sim_end_s] (the report).
            result.sim_end_s = self._last_joint_stamp() if held is None else held
            if response is not None:
                result.take_response(response)
            if result.ground_z is not None:
                ground = self.report.ground_z = result.ground_z
            print(
                f"[mission] {step.name}: {'ok' if result.success else 'FAILED'} "
                f"({result.wall_time_s:.2f} s wall) {result.message}",
                flush=True,
            )
            if not result.success:
                self.report.error = f"step {step.name} ({service}) failed: {result.message}"
                return
            if step.name == "deliver_sample" and not self._ingest(result.sim_end_s):
                return

    def _capture_workspace(self) -> None:
        """One stereo capture of the workspace, the simulation paused where it stands (t = 0
        in the lockstep), into the run directory and the report; a failed one is reported, and
        the steps go on (the trench is the mission file's)."""
        sim_clock("pause", between_steps=True)
        wall0 = time.monotonic()
        try:
            shot = capture_workspace(self.config.step_timeout_s)
            capture = write_capture(
                self.run_dir, shot, self._aim, trench_footprint(asdict(self.config))
            )
            share = 100 * capture["site"]["valid_fraction"]
            outcome = f"{share:.0f} % of the trench's footprint has stereo points"
        except CaptureError as exc:
            capture, outcome = failed_capture(str(exc)), f"FAILED: {exc}"
        # The only wall-clock number of the entry: left out of run comparisons.
        capture["wall_time_s"] = time.monotonic() - wall0
        self.report.capture = capture
        print(f"[mission] capture: {capture['wall_time_s']:.2f} s wall, {outcome}", flush=True)

    def _ingest(self, sim_time_s: float) -> bool:
        """DockIngestSample once the delivery has ended, the simulation standing where it
        ended (the ingestion takes no simulated time); whether a sample was ingested (if not,
        the mission stops saying why)."""
        wall0 = time.monotonic()
        ingestion = ingest_sample(self.config.step_timeout_s)
        ingestion.sim_time_s = sim_time_s
        ingestion.wall_time_s = time.monotonic() - wall0
        self.report.ingestion = ingestion
        print(f"[mission] sample: {ingestion.summary()}", flush=True)
        if not ingestion.sample_ingested:
            self.report.error = f"no sample was ingested: {ingestion.failure()}"
        return ingestion.sample_ingested

    def _held(self) -> float | None:
        """s, where the arm services hold the simulation (the lockstep); None without the
        lockstep, or when it did not hold within a step's timeout (said why)."""
        if not self._hold:
            return None
        try:
            # max: before its first joint state the simulation reports -1 (it starts at 0).
            return max(wait_until_held("/arm_services", self.config.step_timeout_s), 0.0)
        except LockstepError as exc:
            print(f"[mission] {exc}", flush=True)
            return None


def main(argv: list[str] | None = None) -> int:
    """``rosrun ow_mission mission [file]``: run a mission, print the table; 0 on success."""
    args = sys.argv[1:] if argv is None else argv
    try:
        config = config_from_argv(args)
    except AnyConfigError as exc:
        print(f"mission: {exc}", file=sys.stderr)
        return 2
    if config is None:
        print(USAGE)
        return 0
    runner = MissionRunner(config, Path.cwd())
    print(f"[mission] {config.name}: writing {runner.run_dir}", flush=True)
    report = runner.run()
    print(report.table())
    if report.recording_note:
        print(f"[mission] {report.recording_note}")
    tell_figures(runner.figures, runner.run_dir, WAIT_FIGURES in args, print)
    return 0 if report.success else 1
