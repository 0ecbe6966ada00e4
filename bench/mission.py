"""End-to-end cost of the sample-collection mission (issue 8): wall time, sim time, memory.

Runs ``rosrun ow_mission mission`` on the default mission (config/mission.yaml) as a user would,
with its run directory in a temporary folder, and prints one JSON line per metric from the run's
``report.json``. Bar (issue 8): the whole mission in at most 30 s of wall time on the project's
2-core machine (OceanWATERS: ~363 s of simulated time at ~0.8x real time).

    source env.sh && python bench/mission.py [mission.yaml]
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from ow_mission.mission_config import DEFAULT_MISSION_FILE


def main() -> int:
    source = Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_MISSION_FILE
    with tempfile.TemporaryDirectory(prefix="ow_bench_mission_") as tmp:
        mission = yaml.safe_load(source.read_text()) or {}
        mission["output_dir"] = tmp
        path = Path(tmp) / "mission.yaml"
        path.write_text(yaml.safe_dump(mission))
        started = time.monotonic()
        run = subprocess.run(
            ["rosrun", "ow_mission", "mission", str(path)],
            capture_output=True,
            text=True,
            check=False,
        )
        wall = time.monotonic() - started
        reports = sorted(Path(tmp).glob("*/report.json"))
        if not reports:
            print(run.stdout[-2000:], run.stderr[-2000:], file=sys.stderr)
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
