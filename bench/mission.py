"""End-to-end cost of the sample-collection mission (issue 8): wall time, sim time, memory.

Runs ``rosrun ow_mission mission`` on the default mission (config/mission.yaml) as a user would,
with its run directory in a temporary folder, and prints one JSON line per metric from the run's
``report.json``, and the CPU time of each node of its stack (``cpu_s`` per node, read from
``/proc`` every 0.2 s until it exits: where the time goes, docs/performance.md). Bar (issue 8):
the whole mission in at most 30 s of wall time on the project's 2-core machine (OceanWATERS:
~363 s of simulated time at ~0.8x real time); issue 18: 15 s.

    source env.sh && python bench/mission.py [mission.yaml]
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from ow_mission.mission_config import DEFAULT_MISSION_FILE

#: s of wall time between two readings of the stack's CPU times.
CPU_POLL_S = 0.2


def node_cpu(mission_pid: int, seen: dict[int, tuple[str, float]]) -> None:
    """Update ``seen`` (pid -> (node, CPU s)) from /proc: the mission and every ROS node (a
    process with ``__name:=``) and the master."""
    tick = os.sysconf("SC_CLK_TCK")
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            raw = Path(f"/proc/{entry}/cmdline").read_bytes().split(b"\0")
            stat = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        args = [a.decode(errors="replace") for a in raw if a]
        names = [a.split(":=", 1)[1] for a in args if a.startswith("__name:=")]
        if int(entry) == mission_pid:
            names = ["mission"]
        elif any(a.endswith("rosmaster") for a in args[:2]):
            names = ["rosmaster"]
        if names and not any(a.endswith("rosrun") for a in args[:2]):
            seen[int(entry)] = (names[0], (int(stat[11]) + int(stat[12])) / tick)


def main() -> int:
    source = Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_MISSION_FILE
    with tempfile.TemporaryDirectory(prefix="ow_bench_mission_") as tmp:
        mission = yaml.safe_load(source.read_text()) or {}
        mission["output_dir"] = tmp
        path = Path(tmp) / "mission.yaml"
        path.write_text(yaml.safe_dump(mission))
        started = time.monotonic()
        seen: dict[int, tuple[str, float]] = {}
        with (
            tempfile.TemporaryFile("w+") as out,
            subprocess.Popen(
                ["rosrun", "ow_mission", "mission", str(path)], stdout=out, stderr=out, text=True
            ) as proc,
        ):
            while proc.poll() is None:
                node_cpu(proc.pid, seen)
                time.sleep(CPU_POLL_S)
            out.seek(0)
            output = out.read()
        wall = time.monotonic() - started
        reports = sorted(Path(tmp).glob("*/report.json"))
        if not reports:
            print(output[-4000:], file=sys.stderr)
            return 1
        report = json.loads(reports[-1].read_text())
    common = {"bench": "mission", "mission": str(source), "success": report["success"]}
    metrics = [
        ("wall_time_s", wall, "s", "rosrun to exit, incl. start-up and report"),
        ("mission_wall_time_s", report["wall_time_s"], "s", "as measured by the mission"),
        ("sim_time_s", report["sim_time_s"], "s", "simulated time at the end"),
        ("real_time_factor", report["sim_time_s"] / wall, "x", "sim s per wall s"),
        ("planning_wall_time_s", sum(s["planning_time_s"] for s in report["steps"]), "s", ""),
        ("peak_memory_mb", report["peak_memory_mb"], "MB", "sum of VmHWM of all processes"),
    ]
    cpu: dict[str, float] = {}
    for node, seconds in seen.values():
        cpu[node] = cpu.get(node, 0.0) + seconds
    metrics.append(("cpu_s_total", sum(cpu.values()), "s", "CPU time of the whole stack"))
    for node, seconds in sorted(cpu.items(), key=lambda item: -item[1]):
        metrics.append((f"cpu_s_{node}", seconds, "s", "CPU time of one node"))
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
