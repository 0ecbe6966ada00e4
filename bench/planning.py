"""Planning benchmark: wall time per service (20 seeds) and work of our plans vs path-length RRT*.

Prints one JSON line per metric. Run: ``source env.sh && python bench/planning.py``.
"""

from __future__ import annotations

import dataclasses
import json
import time

import numpy as np

from ow_lander.config import PlannerConfig
from ow_lander.description import STOWED, UNSTOWED
from ow_lander.errors import PlanningError
from ow_lander.model import LanderModel
from ow_lander.operations import Operations
from ow_lander.planning import ArmPlanner, CheckContext
from ow_lander.terrain import HeightMap

SEEDS = range(1, 21)
REQUESTS = {
    "unstow": (STOWED, None),
    "stow": (UNSTOWED, None),
    "guarded_move": (UNSTOWED, {"use_defaults": True}),
    "grind": (UNSTOWED, {"use_defaults": True}),
    "dig_linear": (UNSTOWED, {"use_defaults": True}),
    "dig_circular": (UNSTOWED, {"use_defaults": True}),
    "deliver_sample": (UNSTOWED, {"use_defaults": True}),
}


def main() -> None:
    model = LanderModel()
    terrain = HeightMap.flat(-0.155)
    for name, (pose, request) in REQUESTS.items():
        times = []
        failures = 0
        for seed in SEEDS:
            ops = Operations(ArmPlanner(model, PlannerConfig(seed=seed)))
            q = model.q_from(pose)
            method = getattr(ops, f"plan_{name}")
            start = time.perf_counter()
            try:
                method(q, terrain) if request is None else method(q, terrain, request)
            except PlanningError:
                failures += 1
            times.append(time.perf_counter() - start)
        print(
            json.dumps(
                {
                    "metric": f"planning_time_{name}",
                    "unit": "s",
                    "median": round(float(np.median(times)), 4),
                    "p95": round(float(np.percentile(times, 95)), 4),
                    "n": len(times),
                    "failures": failures,
                }
            )
        )
    # Work of RRT* with our objective vs with path length, on free segments the direct motion
    # cannot make (random goals from the unstowed pose), same seeds.
    planner = ArmPlanner(model, PlannerConfig(rrt_time_limit_s=1.0))
    ctx = CheckContext(model.q_from(UNSTOWED), terrain)
    rng = np.random.default_rng(7)
    start = planner.arm(ctx.base)
    ours, length_only = [], []
    while len(ours) < 10:
        goal = rng.uniform(planner.lower, planner.upper)
        if not planner.is_valid(goal, ctx):
            continue
        if planner.first_invalid(np.vstack([start, goal]), ctx) is None:
            continue
        try:
            a = planner.plan_free(start, goal, ctx, "work")
            b = planner.plan_free(start, goal, ctx, "length")
        except Exception:
            continue
        ours.append(planner.work(a, ctx.base))
        length_only.append(planner.work(b, ctx.base))
    print(
        json.dumps(
            {
                "metric": "rrt_star_work_ours_vs_path_length",
                "unit": "J",
                "ours_median": round(float(np.median(ours)), 2),
                "path_length_median": round(float(np.median(length_only)), 2),
                "ratio_median": round(float(np.median(np.array(ours) / np.array(length_only))), 3),
                "n_segments": len(ours),
                "config": {
                    k: v
                    for k, v in dataclasses.asdict(PlannerConfig()).items()
                    if k.startswith("rrt_")
                },
            }
        )
    )


if __name__ == "__main__":
    main()
