"""Planning benchmark: wall time per service (20 seeds) and work of our plans vs path-length RRT*.

Prints one JSON line per metric. Run: ``source env.sh && python bench/planning.py``.
"""

from __future__ import annotations

import dataclasses
import json
import time

import numpy as np

from ow_lander.config import PlannerConfig
from ow_lander.description import DEFAULT_GROUND_Z, STOWED, UNSTOWED
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
    terrain = HeightMap.flat(DEFAULT_GROUND_Z)
    for name, (pose, request) in REQUESTS.items():
        times: list[float] = []
        failures = 0
        for seed in SEEDS:
            ops = Operations(ArmPlanner(model, PlannerConfig(seed=seed)))
            q = model.q_from(pose)
            method = getattr(ops, f"plan_{name}")
            began = time.perf_counter()
            try:
                method(q, terrain) if request is None else method(q, terrain, request)
            except PlanningError:
                failures += 1
            times.append(time.perf_counter() - began)
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
    # Work of RRT* with our objective vs with path length, on free segments that neither the
    # direct segment nor the staged moves can make (random goals from the unstowed pose), same
    # seeds; and the wall time of those RRT* solves (the fallback the services rarely need).
    config = PlannerConfig()
    planner = ArmPlanner(model, config)
    ctx = CheckContext(model.q_from(UNSTOWED), terrain)
    rng = np.random.default_rng(7)
    origin = planner.arm(ctx.base)
    ours: list[float] = []
    length_only: list[float] = []
    solve_times: list[float] = []
    while len(ours) < 10:
        goal = rng.uniform(planner.lower, planner.upper)
        if not planner.is_valid(goal, ctx) or planner.plan_straight(origin, goal, ctx) is not None:
            continue
        try:
            began = time.perf_counter()
            a = planner.plan_sampled(origin, goal, ctx, "work")
            elapsed = time.perf_counter() - began
            b = planner.plan_sampled(origin, goal, ctx, "length")
        except PlanningError:
            continue
        solve_times.append(elapsed)
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
                    k: v for k, v in dataclasses.asdict(config).items() if k.startswith("rrt_")
                },
            }
        )
    )
    print(
        json.dumps(
            {
                "metric": "rrt_star_time_per_segment",
                "unit": "s",
                "median": round(float(np.median(solve_times)), 4),
                "p95": round(float(np.percentile(solve_times, 95)), 4),
                "n": len(solve_times),
            }
        )
    )


if __name__ == "__main__":
    main()
