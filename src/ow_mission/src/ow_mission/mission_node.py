"""``rosrun ow_mission mission [file.yaml]`` (and ``make demo``): the paper's sample-collection
mission (section 3) through the real services, as an autonomy client runs it (see
``docs/mission.md``). It starts a private master and the stack configured by
:mod:`ow_mission.node_config`, calls the steps of :data:`ow_mission.mission.STEPS`, and writes
``runs/<timestamp>/``; a failed step stops it, keeping everything recorded up to then.

Nothing of ROS is imported here before the stack's nodes are started: the mission's ROS side
(:mod:`ow_mission.mission_session_node`) is imported while they import theirs.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from ow_mission.errors import ConfigError
from ow_mission.figures import FiguresProcess, tell_figures
from ow_mission.mission import (
    MissionReport,
    new_run_dir,
    node_parameters,
    stack_processes,
    write_report,
)
from ow_mission.mission_config import USAGE, WAIT_FIGURES, MissionConfig, config_from_argv
from ow_mission.stack import HarnessError, RosStack, private_master


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
        self.figures: FiguresProcess | None = None  # drawing them after the mission (after_exit)

    def run(self) -> MissionReport:
        """Run the mission; never raises for a failed step (the report says what failed)."""
        wall0 = time.monotonic()
        self.run_dir.mkdir(parents=True)
        (self.run_dir / "renders").mkdir()
        prefetch = None
        try:
            # The master on threads of this process: ~40 MB less than a process of its own.
            with private_master(self.run_dir / "ros", in_process=True) as master:
                os.environ.update(
                    ROS_MASTER_URI=master.uri,
                    ROS_HOSTNAME="127.0.0.1",
                    ROS_HOME=str(master.log_dir),
                )
                stack = RosStack(master)
                params = node_parameters(self.config, self.run_dir)
                # Started side by side (the simulation paused), then waited for: each node
                # spends a second or two importing, and they need nothing from one another to
                # start.
                processes = stack_processes(params, self.config.dig)
                nodes = [
                    stack.start_node(p.package, p.executable, params=p.params, wait=False)
                    for p in processes
                ]
                try:  # the mission's ROS side imports while the nodes import theirs
                    from ow_mission.mission_session_node import MissionSession

                    session = MissionSession(self.config, self.report, params)
                except BaseException:
                    stack.shutdown(delete_params=False)
                    raise
                try:
                    session.start(stack, nodes, processes)
                    session.run_steps()
                finally:
                    prefetch = session.stop(stack, nodes)
        except (HarnessError, ConfigError) as exc:
            self.report.error = str(exc)
        self.report.wall_time_s = time.monotonic() - wall0
        self.figures = write_report(self.report, prefetch)
        return self.report


def main(argv: list[str] | None = None) -> int:
    """``rosrun ow_mission mission [file]``: run a mission, print the table; 0 on success."""
    args = sys.argv[1:] if argv is None else argv
    try:
        config = config_from_argv(args)
    except ConfigError as exc:
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
