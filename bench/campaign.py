"""Campaign throughput (issue 16): missions per hour on this machine, local engine and Ray.

Runs ``rosrun ow_mission campaign`` as a user would, on a campaign of N missions (default 4) of
the default mission without renders (trench location randomized within reach), with 2 workers:
once on the local engine, once on a local Ray instance (2 CPUs). Prints one JSON line per metric.
The missions draw no figures (a campaign's default, ``figures: none``); ``--figures inline``
draws them in every mission, ``--engines local`` leaves Ray out.

    source env.sh && python bench/campaign.py [missions] [--figures inline] [--engines local]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml


def run(engine: str, missions: int, tmp: Path, figures: str) -> list[dict[str, object]]:
    path = tmp / f"{engine}.yaml"
    campaign = {
        "name": f"bench {engine}",
        "seed": 16,
        "missions": missions,
        "mission": {"renders": False},
        "randomize": {"x": [1.55, 1.75], "y": [-0.1, 0.1]},
        "engine": engine,
        "workers": 2,
        "directory": str(tmp / engine),
        "figures": figures,
    }
    path.write_text(yaml.safe_dump(campaign))
    started = time.monotonic()
    command = ["rosrun", "ow_mission", "campaign", str(path)]
    proc = subprocess.run(command, capture_output=True, text=True, check=False)
    wall = time.monotonic() - started
    load = os.getloadavg()[0]
    report_path = tmp / engine / "report.json"
    if not report_path.exists():
        print(proc.stdout[-2000:], proc.stderr[-2000:], file=sys.stderr)
        return [{"metric": "error", "value": f"no report (exit {proc.returncode})"}]
    report = json.loads(report_path.read_text())
    mission_wall = report["wall_time_s"].get("mean", 0.0)
    return [
        {"metric": "missions_per_hour", "value": round(missions / wall * 3600, 1), "unit": "1/h"},
        {"metric": "campaign_wall_time_s", "value": round(wall, 1), "unit": "s"},
        {"metric": "mission_wall_time_mean_s", "value": round(mission_wall, 1), "unit": "s"},
        {"metric": "missions_succeeded", "value": report["missions_succeeded"], "unit": ""},
        # The machine is shared: its load at the end says how comparable the figures are.
        {"metric": "load_average_1min_at_end", "value": round(load, 2), "unit": ""},
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description="campaign throughput")
    parser.add_argument("missions", nargs="?", type=int, default=4)
    parser.add_argument("--figures", choices=("none", "inline"), default="none")
    parser.add_argument("--engines", default="local,ray", help="comma-separated: local, ray")
    args = parser.parse_args()
    ok = True
    for engine in args.engines.split(","):
        with tempfile.TemporaryDirectory(prefix=f"ow_bench_campaign_{engine}_") as tmp:
            for line in run(engine, args.missions, Path(tmp), args.figures):
                common = {"bench": "campaign", "engine": engine, "workers": 2}
                common["figures"] = args.figures
                print(json.dumps({**common, "missions": args.missions, **line}), flush=True)
                ok = ok and line["metric"] != "error"
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
