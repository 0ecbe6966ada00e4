"""``rosrun ow_mission mission [file.yaml]`` (and ``make demo``): the sample-collection mission
of the paper (section 3) through the real services, as an autonomy client would run it.

It starts a private rosmaster, the simulation, the arm services (plan-and-execute), the power node
and the bag recorder, configured from the packages' YAML files (``ow_mission.node_config``, the
same files the launch files load) with the mission file's settings on top, then calls: unstow;
guarded move at the selected location; grind a trench; dig it out and discard the spoil at a
remote point; grind again at the bottom; dig the sample; deliver it to the sample dock; stow. The
ground the guarded move finds feeds every later step.

Everything goes to ``runs/<timestamp>/``: the bags, the trajectory files, ``report.md``,
``report.json``, the power plot and renders of the arm at key moments. A failed step stops the
mission; what was recorded up to then is kept and the report says what failed.
"""

from __future__ import annotations

import datetime as dt
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import rospy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

import ow_msgs.srv
from ow_lander.terrain import HeightMap
from ow_mission.errors import ConfigError
from ow_mission.mission import (
    RENDER_AFTER,
    STEPS,
    MissionReport,
    PowerTrace,
    StepResult,
    write_report,
)
from ow_mission.mission_config import DEFAULT_MISSION_FILE, MissionConfig
from ow_mission.node_config import STACK_NODES, stack_parameters
from ow_mission.stack import HarnessError, NodeProcess, RosStack, peak_memory_mb, private_master
from ow_msgs.msg import HeightMap as HeightMapMsg
from ow_msgs.msg import Power

#: s of wall time to wait for /power to catch up with the simulation clock.
POWER_WAIT_S = 5.0


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
        """Private parameters of each node: the packages' YAML files (as the launch files load
        them), then the mission's own settings, then the mission file's ``node_params``."""
        c = self.config
        shipped = stack_parameters()
        mission: dict[str, dict[str, Any]] = {
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
            "record": {
                "output_dir": str(self.run_dir / "bags"),
                "prefix": "mission",
                # The terrain too: the trench the mission dug is part of its result.
                "topics": [*shipped["record"]["topics"], "/sim/terrain", "/sim/scoop_tip_ground"],
            },
        }
        return stack_parameters(mission, c.node_params)

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
                    self.report.peak_memory_mb = peak_memory_mb(node.proc.pid for node in nodes)
                    self.report.sim_time_s = self._clock
                    stack.shutdown()  # the recorder closes its bag on SIGINT
        except (HarnessError, ConfigError) as exc:
            self.report.error = str(exc)
        self.report.wall_time_s = time.monotonic() - wall0
        write_report(self.report)
        return self.report

    def _start(self, stack: RosStack) -> list[NodeProcess]:
        rospy.init_node("mission", disable_signals=True)
        params = self.node_params()
        # Started side by side (the simulation paused), then waited for: each node spends a
        # second or two importing, and they need nothing from one another to start.
        ready: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
            "record": ((), ()),
            "power": ((), ("/power",)),
            "sim": (("/sim/resume",), ("/joint_states",)),
            "arm_services": (tuple(s.service.format(dig=self.config.dig) for s in STEPS), ()),
        }
        nodes = [
            stack.start_node(n.package, n.executable, params=params[n.executable], wait=False)
            for n in STACK_NODES
        ]
        for node, spec in zip(nodes, STACK_NODES, strict=True):
            stack.wait_ready(node, *ready[spec.executable])
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
