"""End-to-end cost of the sample-collection mission (issue 8): wall time, sim time, memory.

Runs ``rosrun ow_mission mission`` on the default mission (config/mission.yaml) as a user would,
with its run directory in a temporary folder, and prints one JSON line per metric from the run's
``report.json``, and the CPU time of each node of its stack (``cpu_s`` per node, read from
``/proc`` every 0.2 s until it exits: where the time goes, docs/performance.md; the report's
forked renderers are ``mission_workers``, their CPU time as last read before each exits).
``peak_pss_mb`` is the largest sum of the processes' proportional set sizes at one reading: the
memory the stack uses together, with this process's share of the pages it shares with them (it
imports nothing heavy), where ``peak_memory_mb`` (the mission's own figure) adds each process's
high-water mark, whenever it was reached, and counts shared pages once per process.
Bar (issue 8): the whole mission in at most 30 s of wall time on the project's 2-core machine
(OceanWATERS: ~363 s of simulated time at ~0.8x real time); issue 18: 15 s, 500 MB.

    source env.sh && python bench/mission.py [mission.yaml]
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import yaml

from ow_mission.figures import figures_status
from ow_mission.mission_config import DEFAULT_MISSION_FILE

#: s of wall time between two readings of the stack's CPU times.
CPU_POLL_S = 0.2


def _pss_mb(pid: str) -> float:
    """MB, the process's proportional set size: its private pages plus its share of the pages
    it shares (libraries, copy-on-write pages of a fork), so that the sum over processes is the
    memory they use together."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def _own_shared_mb() -> float:
    """MB, this process's share of the file pages it shares with others: those of the libraries
    it imports as the stack does (libpython, numpy). Each process sharing a page carries a part of
    it in its PSS, so the stack's sum leaves this part out: it is added (an upper bound: it counts
    pages shared with unrelated processes too, ~0.6 MB). This process imports nothing heavy for
    that reason (tests/unit/ow_mission/test_mission_imports.py): through the mission's
    configuration it once imported pinocchio, and the sum was ~20 MB short."""
    total_kb = pss_kb = private_kb = 0
    file_backed = False
    with open("/proc/self/smaps") as smaps:
        for line in smaps:
            fields = line.split()
            if not fields[0].endswith(":"):  # a mapping's header line: address, perms, ..., path
                total_kb += pss_kb - private_kb if file_backed else 0
                file_backed = len(fields) >= 6 and fields[5].startswith("/")
                pss_kb = private_kb = 0
            elif fields[0] == "Pss:":
                pss_kb = int(fields[1])
            elif fields[0] in ("Private_Clean:", "Private_Dirty:"):
                private_kb += int(fields[1])
    total_kb += pss_kb - private_kb if file_backed else 0
    return total_kb / 1024


def node_cpu(
    mission_pid: int,
    seen: dict[tuple[int, int], tuple[str, float, float]],
    ours: set[int],
    run_root: str,
) -> float:
    """Update ``seen`` ((pid, start time) -> (node, CPU s, peak resident MB)) from /proc: the
    mission, every ROS node (a process with ``__name:=``), the master and the mission's other
    children (the report's forked renderers, ``mission_workers``) and the process drawing the
    figures after the mission exits, with its renderers (``figures``). Only the mission's own
    processes count: ``ours`` (pids) grows by every process whose parent is in it, and the
    figures' process is known by its run directory under ``run_root`` too (the mission may exit
    before it is seen, and it is then no child of it): on a machine shared with other stacks
    (a test suite, another mission), theirs are left out. Returns MB, the sum of their PSS now."""
    tick = os.sysconf("SC_CLK_TCK")
    pss_mb = 0.0
    stats: dict[int, list[str]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stats[int(entry)] = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
    grew = True
    while grew:  # to a fixed point: a child's pid may come before its parent's (pids wrap)
        known = len(ours)
        ours.update(pid for pid, stat in stats.items() if int(stat[1]) in ours)
        grew = len(ours) > known
    for pid, stat in stats.items():
        entry = str(pid)
        try:
            raw = Path(f"/proc/{entry}/cmdline").read_bytes().split(b"\0")
            status = Path(f"/proc/{entry}/status").read_text().splitlines()
        except OSError:
            continue
        args = [a.decode(errors="replace") for a in raw if a]
        if not args:  # an exited process not yet waited for: nothing more to read
            continue
        if pid not in ours:
            if not ("ow_mission.figures" in args and any(run_root in a for a in args)):
                continue
            ours.add(pid)  # the figures' process: its renderers are its children
        names = [a.split(":=", 1)[1] for a in args if a.startswith("__name:=")]
        if int(entry) == mission_pid:
            names = ["mission"]
        elif any(a.endswith("rosmaster") for a in args[:2]):
            names = ["rosmaster"]
        elif "ow_mission.figures" in args:
            names = ["figures"]  # the process drawing the figures after the mission, its pool
        elif not names and int(stat[1]) == mission_pid:
            names = ["mission_workers"]
        if names and not any(a.endswith("rosrun") for a in args[:2]):
            hwm_kb = next((int(x.split()[1]) for x in status if x.startswith("VmHWM:")), 0)
            cpu_s = (int(stat[11]) + int(stat[12])) / tick
            # An exiting process (a zombie) has no VmHWM any more: keep the largest seen. Keyed
            # by pid and start time: the report's workers get the pids of the exited nodes.
            # A node is briefly a copy of the mission between fork and exec: its name is the
            # one it has once it runs.
            key = (int(entry), int(stat[19]))
            name, cpu_before, mb_before = seen.get(key, (names[0], 0.0, 0.0))
            name = name if names[0] == "mission_workers" else names[0]
            seen[key] = (name, max(cpu_s, cpu_before), max(hwm_kb / 1024, mb_before))
            pss_mb += _pss_mb(entry)
    return pss_mb


def main() -> int:
    source = Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_MISSION_FILE
    with tempfile.TemporaryDirectory(prefix="ow_bench_mission_") as tmp:
        mission = yaml.safe_load(source.read_text()) or {}
        mission["output_dir"] = tmp
        path = Path(tmp) / "mission.yaml"
        path.write_text(yaml.safe_dump(mission))
        started = time.monotonic()
        seen: dict[tuple[int, int], tuple[str, float, float]] = {}
        ours: set[int] = set()
        with (
            tempfile.TemporaryFile("w+") as out,
            subprocess.Popen(
                ["rosrun", "ow_mission", "mission", str(path)], stdout=out, stderr=out, text=True
            ) as proc,
        ):
            ours.add(proc.pid)  # rosrun execs the mission: the same process
            peak_pss_mb = peak_pss_at_s = 0.0

            def sample_while(running: Callable[[], bool]) -> float:
                """Read the processes every CPU_POLL_S while ``running()``; s from rosrun."""
                nonlocal peak_pss_mb, peak_pss_at_s
                while running():
                    pss_mb = node_cpu(proc.pid, seen, ours, tmp) + _own_shared_mb()
                    if pss_mb > peak_pss_mb:
                        peak_pss_mb, peak_pss_at_s = pss_mb, time.monotonic() - started
                    time.sleep(CPU_POLL_S)
                return time.monotonic() - started

            wall = sample_while(lambda: proc.poll() is None)
            reports = sorted(Path(tmp).glob("*/report.json"))
            # The figures drawn after the mission exits (``figures: after_exit``): their
            # process's CPU and memory count, and when they are done.
            done = sample_while(
                lambda: bool(reports) and figures_status(reports[-1].parent) == "drawing"
            )
            out.seek(0)
            output = out.read()
        if not reports:
            print(output[-4000:], file=sys.stderr)
            return 1
        report = json.loads(reports[-1].read_text())
    common = {"bench": "mission", "mission": str(source), "success": report["success"]}
    metrics = [
        ("wall_time_s", wall, "s", "rosrun to exit, incl. start-up and report"),
        ("figures_done_s", done, "s", "rosrun to the figures drawn (after the exit: after_exit)"),
        ("mission_wall_time_s", report["wall_time_s"], "s", "as measured by the mission"),
        ("sim_time_s", report["sim_time_s"], "s", "simulated time at the end"),
        ("real_time_factor", report["sim_time_s"] / wall, "x", "sim s per wall s"),
        ("planning_wall_time_s", sum(s["planning_time_s"] for s in report["steps"]), "s", ""),
        ("steps_wall_time_s", sum(s["wall_time_s"] for s in report["steps"]), "s", "the calls"),
        ("report_wall_time_s", report.get("report_seconds", 0.0), "s", "report from the bags"),
        ("figures_wall_time_s", report.get("figures_seconds", 0.0), "s", "figures, after exit"),
        ("peak_memory_mb", report["peak_memory_mb"], "MB", "sum of VmHWM of all processes"),
        ("peak_pss_mb", peak_pss_mb, "MB", "largest sum of PSS of the processes at one time"),
        ("peak_pss_at_s", peak_pss_at_s, "s", "when, from rosrun"),
    ]
    cpu: dict[str, float] = {}
    memory: dict[str, float] = {}
    for node, seconds, peak_mb in seen.values():
        cpu[node] = cpu.get(node, 0.0) + seconds
        memory[node] = max(memory.get(node, 0.0), peak_mb)
    metrics.append(("cpu_s_total", sum(cpu.values()), "s", "CPU time of the whole stack"))
    for node, seconds in sorted(cpu.items(), key=lambda item: -item[1]):
        metrics.append((f"cpu_s_{node}", seconds, "s", "CPU time of one node"))
    for node, peak_mb in sorted(memory.items(), key=lambda item: -item[1]):
        metrics.append((f"peak_mb_{node}", peak_mb, "MB", "VmHWM of one node (largest seen)"))
    for name, value, unit, note in metrics:
        line = {**common, "metric": name, "value": round(float(value), 3), "unit": unit}
        if note:
            line["note"] = note
        print(json.dumps(line))
    if not report["success"]:
        print(json.dumps({**common, "metric": "error", "value": report["error"]}))
    return 0 if report["success"] else 1


if __name__ == "__main__":
    sys.exit(main())
