"""Cost of a terrain-force lookup and wall time of the YADE table regeneration.

Prints one JSON line per metric:

* ``table_lookup_us``: one ``TableModel.wrench(state)`` on the shipped table (the sim's per-step
  call), median over random states inside the table's range; ``table_lookup_raw_us`` the bare
  ``ForceTable.lookup``; ``balovnev_us`` one ``BalovnevModel.wrench``.
* ``regeneration_wall_s``: wall time of the last ``make dem-tables``, read from the provenance
  file it wrote (``src/ow_dem_bridge/data/default_table.json``; the full run takes minutes, so
  the bench does not repeat it). With ``--smoke`` it also runs the tiny test-suite scenario and
  reports ``smoke_regeneration_wall_s``.

    source env.sh && python bench/dem.py [--smoke]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from ow_dem_bridge.api import ToolState
from ow_dem_bridge.make_tables import regenerate, smoke_scenario
from ow_dem_bridge.models import DEFAULT_TABLE_PATH, make_model
from ow_dem_bridge.table import load_table


def emit(metric: str, value: float, unit: str, **extra: Any) -> None:
    print(json.dumps({"bench": "dem", "metric": metric, "value": value, "unit": unit, **extra}))


def median_us(fn: Any, args: list[Any], repeats: int = 5) -> float:
    """Median over ``repeats`` passes of the mean cost of ``fn(a)`` over ``args``, in us."""
    costs = []
    for _ in range(repeats):
        start = time.perf_counter()
        for a in args:
            fn(a)
        costs.append((time.perf_counter() - start) / len(args) * 1e6)
    return round(float(np.median(costs)), 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="also time the smoke regeneration")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    table = load_table(DEFAULT_TABLE_PATH)
    depths = table.depths("scoop", 1)
    states = [
        ToolState(
            "scoop",
            1,
            float(rng.uniform(0.5 * depths[0], 1.2 * depths[-1])),
            float(rng.uniform(0.0, 0.45)),
            np.array([0.1, 0.0, 0.0]),
            np.zeros(3),
        )
        for _ in range(20000)
    ]
    model = make_model("table", {})
    emit("table_lookup_us", median_us(model.wrench, states), "us", table=DEFAULT_TABLE_PATH.name)
    raw = [(s.tool, s.material, s.depth, s.progress) for s in states]
    emit("table_lookup_raw_us", median_us(lambda a: table.lookup(*a), raw), "us")
    balovnev = make_model("balovnev", {"grinder_table": ""})
    emit("balovnev_us", median_us(balovnev.wrench, states), "us")
    record = json.loads(DEFAULT_TABLE_PATH.with_suffix(".json").read_text())
    emit(
        "regeneration_wall_s",
        record["wall_time_s"],
        "s",
        source="recorded by make dem-tables",
        workers=record["workers"],
        yade_runs=len(record["runs"]),
    )
    if args.smoke:
        with tempfile.TemporaryDirectory() as tmp:
            start = time.monotonic()
            regenerate(smoke_scenario(), Path(tmp) / "t.csv", Path(tmp) / "work", workers=1)
            emit("smoke_regeneration_wall_s", round(time.monotonic() - start, 1), "s")


if __name__ == "__main__":
    main()
