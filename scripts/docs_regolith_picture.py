"""docs/images/regolith_budget.png, the picture of docs/regolith.md: the mission report's
regolith figure (``regolith.png``, :mod:`ow_mission.regolith_plot`) of a default-mission run,
drawn from the run's bags. Prints the run's figures as one JSON line. After ``source env.sh``:

    python scripts/docs_regolith_picture.py            # runs the default mission (renders off)
                                                       #   in a temporary directory, ~1.5 min
    python scripts/docs_regolith_picture.py RUN_DIR    # draws it from a run's bags and report.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

import yaml

from ow_mission.mission_config import DEFAULT_MISSION_FILE
from ow_mission.regolith_plot import plot_regolith, regolith_series
from ow_mission.report import step_windows
from ow_power.bagread import read_messages
from ow_runtime.names import REGOLITH_BUDGET

ROOT = Path(__file__).resolve().parents[1]
DOCS_PICTURE = ROOT / "docs" / "images" / "regolith_budget.png"
#: bytes, the largest picture the docs take.
DOCS_PICTURE_LIMIT = 200_000


def run_default_mission(directory: Path) -> Path:
    """Run the default mission with its run directory under ``directory`` (no renders, the
    figures made before it exits); returns the run directory."""
    mission = yaml.safe_load(DEFAULT_MISSION_FILE.read_text())
    mission.update(output_dir=str(directory / "runs"), renders=False, figures="inline")
    path = directory / "mission.yaml"
    path.write_text(yaml.safe_dump(mission))
    subprocess.run(["rosrun", "ow_mission", "mission", str(path)], check=True)
    (run_dir,) = (directory / "runs").iterdir()
    return run_dir


def draw(run_dir: Path, png_path: Path) -> dict[str, float | None]:
    """Draw the regolith figure of ``run_dir`` into ``png_path``; its figures (m³, shares)."""
    document = json.loads((run_dir / "report.json").read_text())
    bags = sorted((run_dir / "bags").glob("*.bag"))
    budgets = read_messages(bags, [REGOLITH_BUDGET]).get(REGOLITH_BUDGET, [])
    series = regolith_series(budgets, step_windows(document))
    plot_regolith(series, png_path)
    sample = document.get("sample") or {}
    return {
        "excavated_m3": series.final_cm3("excavated") * 1e-6,
        "ingested_m3": series.final_cm3("ingested") * 1e-6,
        "dock_share": sample.get("dock_share"),
        "top_layer_share": sample.get("top_layer_share"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", nargs="?", type=Path, help="a run directory (default: run one)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="regolith_picture_") as scratch:
        run_dir = args.run_dir or run_default_mission(Path(scratch))
        png = Path(scratch) / "regolith.png"
        figures = draw(run_dir, png)
        size = png.stat().st_size
        if size > DOCS_PICTURE_LIMIT:
            msg = f"{png}: {size} bytes is more than the docs take ({DOCS_PICTURE_LIMIT})"
            raise SystemExit(msg)
        DOCS_PICTURE.write_bytes(png.read_bytes())
    print(json.dumps({"picture": str(DOCS_PICTURE.relative_to(ROOT)), "bytes": size, **figures}))


if __name__ == "__main__":
    main()
