"""Planning benchmark: wall time of every planning service from the states a mission calls it in.

The start states are those of the default mission (``src/ow_mission/config/mission.yaml``, its
terrain): stowed, then the end of each of its nine steps, planned here with the pure core
(:class:`~ow_lander.operations.planner.Operations`) in the mission's order with the mission's
requests. The guarded move's state is where its descent meets the terrain (the execution stops
there); the terrain is carved under the digging segments as the simulation carves it. Every service
is planned with each request the mission (or its circular-dig variant) sends it, from the state the
mission sends it in and from every later one (a request for the trench's bottom, planned before
the trench is dug, is rightly refused: the scoop would cut into the terrain), for a few
planner seeds, each seed's planner prepared
(:meth:`~ow_lander.operations.planner.Operations.prepare`, untimed in the calls: the node does it at
start-up) and reused across calls as the node does. One JSON line per metric: per service the
median, p95 and largest wall time (ms), the calls and failures, and the median path length (rad) and
work (J) of its plans; the preparation's median wall time; the whole mission's plans' path length
and work; RRT*'s work with our objective vs path length.

    source env.sh && python bench/planning.py
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_description.description import (
    DEFAULT_GROUND_Z,
    SCOOP_TIP_FRAME,
    STOWED,
    UNSTOWED,
    URDF_PATH,
)
from ow_description.model import LanderModel
from ow_description.terrain import HeightMap
from ow_description.trajectory import Speed
from ow_lander.config import PlannerConfig
from ow_lander.errors import PlanningError
from ow_lander.operations.operation_plan import OperationPlan
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner, CheckContext
from ow_lander.planning.validity import densify
from ow_mission.mission import STEPS
from ow_mission.mission_config import DEFAULT_MISSION_FILE, MissionConfig
from ow_sim_bullet.carving import TerrainCarver, collision_surface_points
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.terrains import parse_terrain_spec
from ow_sim_bullet.tool_tracking import TOOLS

FloatArray = npt.NDArray[np.float64]

SERVICES = (
    "unstow",
    "stow",
    "guarded_move",
    "grind",
    "dig_linear",
    "dig_circular",
    "deliver_sample",
)
#: Planner seeds (one planner each, as one node run); the default seed first.
SEEDS = (42, 1, 2)


@dataclass(frozen=True)
class Call:
    """One planning call of the benchmark."""

    service: str
    state: str
    q: FloatArray
    terrain: HeightMap
    request: Mapping[str, Any]


class _NoSurface:
    """A simulator surface that is not there (the carver's heights are all we need)."""

    def __init__(self, heightmap: HeightMap) -> None:
        self.floor = float(heightmap.heights.min()) - 0.5

    def refresh(self, heights: FloatArray, rows: tuple[int, int], cols: tuple[int, int]) -> int:
        return 0

    def remove(self) -> None:
        pass


def carve(ops: Operations, plan: OperationPlan, q: FloatArray, terrain: HeightMap) -> HeightMap:
    """The terrain after ``plan``'s digging segments, carved as the simulation does under a tool
    pressing hard (every 0.01 rad of the segments)."""
    config = SimConfig()
    text = URDF_PATH.read_text()
    spacing = terrain.resolution / 4
    cutters = {
        tool: np.ascontiguousarray(collision_surface_points(text, link, spacing).T)
        for tool, (link, _) in TOOLS.items()
    }
    carver = TerrainCarver(terrain, config, cutters, _NoSurface)
    for segment in plan.segments:
        if segment.speed is not Speed.DIG:
            continue
        for arm in densify(segment.waypoints, 0.01):
            for tool, (link, _) in TOOLS.items():
                X = ops.model.fk(ops.planner.full(arm, q), link)
                carver.cut(tool, X[:3, :3], X[:3, 3], config.carve_full_force, digging=True)
    return carver.heightmap


def emit(metric: str, value: float, unit: str) -> None:
    """One JSON line of this benchmark."""
    print(json.dumps({"bench": "planning", "metric": metric, "value": value, "unit": unit}))


def plan_length(plan: OperationPlan) -> float:
    """rad, joint-space length of all the plan's segments."""
    return float(
        sum(np.linalg.norm(np.diff(s.waypoints, axis=0), axis=1).sum() for s in plan.segments)
    )


def plan_work(planner: ArmPlanner, plan: OperationPlan, q: FloatArray) -> float:
    """J, work against gravity along all the plan's segments."""
    return float(sum(planner.work(s.waypoints, q) for s in plan.segments))


def contact_state(
    ops: Operations, plan: OperationPlan, q: FloatArray, terrain: HeightMap
) -> tuple[FloatArray, float]:
    """Where a guarded move's execution stops: the first descent waypoint whose scoop tip is at
    or below the terrain, and the ground height found there (m)."""
    model, planner = ops.model, ops.planner
    descent = plan.segments[-1].waypoints
    for arm in descent:
        tip = model.fk(planner.full(arm, q), SCOOP_TIP_FRAME)[:3, 3]
        ground = float(terrain.height_at(tip[0], tip[1]))
        if tip[2] <= ground:
            return planner.full(arm, q), ground
    msg = "the guarded descent never reaches the terrain"
    raise PlanningError(msg)


def mission_states(
    config: MissionConfig, terrain: HeightMap
) -> tuple[
    dict[str, tuple[FloatArray, HeightMap]],
    dict[str, list[tuple[int, Mapping[str, Any]]]],
    float,
    float,
]:
    """The default mission planned step by step: the start states (stowed, then after each step)
    with the terrain then, the requests each service gets (with the index of the state the
    mission sends each in), and the mission plans' total path length (rad) and work (J)."""
    ops = Operations(ArmPlanner(LanderModel(), PlannerConfig()))
    q = ops.model.q_from(STOWED)
    states = {"stowed": (q, terrain)}
    requests: dict[str, list[tuple[int, Mapping[str, Any]]]] = {name: [] for name in SERVICES}
    ground = config.expected_ground
    length = work = 0.0
    for step in STEPS:
        service = step.service.format(dig=config.dig).removeprefix("/arm/")
        request = step.request(config, ground)
        sent_in = len(states) - 1
        requests[service].append((sent_in, request))
        if service.startswith("dig_"):
            other = "dig_circular" if service == "dig_linear" else "dig_linear"
            variant = {**request, "parallel": config.parallel, "length": config.dig_length}
            requests[other].append(
                (
                    sent_in,
                    {k: v for k, v in variant.items() if other == "dig_linear" or k != "length"},
                )
            )
        plan = ops.plan(service, q, terrain, request)
        length += plan_length(plan)
        work += plan_work(ops.planner, plan, q)
        if service == "guarded_move":
            q_next, ground = contact_state(ops, plan, q, terrain)
        else:
            q_next = ops.planner.full(plan.end, q)
        terrain = carve(ops, plan, q, terrain)
        q = q_next
        states[f"after_{step.name}"] = (q, terrain)
    return states, requests, length, work


def main() -> None:
    config = MissionConfig.load(DEFAULT_MISSION_FILE)
    terrain = parse_terrain_spec(config.terrain_spec)
    states, requests, mission_length, mission_work = mission_states(config, terrain)
    requests["unstow"] = requests["stow"] = [(0, {})]
    calls = [
        Call(service, state, q, terrain, request)
        for service in SERVICES
        for index, (state, (q, terrain)) in enumerate(states.items())
        for sent_in, request in requests[service]
        if index >= sent_in
    ]
    times: dict[str, list[float]] = {name: [] for name in SERVICES}
    lengths: dict[str, list[float]] = {name: [] for name in SERVICES}
    works: dict[str, list[float]] = {name: [] for name in SERVICES}
    failures = dict.fromkeys(SERVICES, 0)
    slowest: dict[str, tuple[float, str]] = dict.fromkeys(SERVICES, (0.0, ""))
    prepare_times = []
    for seed in SEEDS:
        ops = Operations(ArmPlanner(LanderModel(), PlannerConfig(seed=seed)))
        # What the arm services node does at start-up.
        began = time.perf_counter()
        ops.prepare(states["stowed"][0])
        prepare_times.append(time.perf_counter() - began)
        for call in calls:
            # A fresh map each call: the node gets a new one whenever the simulation carves.
            t = call.terrain
            fresh = HeightMap(t.heights.copy(), t.resolution, t.origin_x, t.origin_y)
            began = time.perf_counter()
            try:
                plan = ops.plan(call.service, call.q, fresh, dict(call.request))
            except PlanningError:
                plan = None
            elapsed = time.perf_counter() - began
            times[call.service].append(elapsed)
            slowest[call.service] = max(slowest[call.service], (elapsed, call.state))
            if plan is None:
                failures[call.service] += 1
                continue
            if seed == SEEDS[0]:
                lengths[call.service].append(plan_length(plan))
                works[call.service].append(plan_work(ops.planner, plan, call.q))
    for name in SERVICES:
        t = np.array(times[name]) * 1000
        emit(f"{name}_median_ms", round(float(np.median(t)), 1), "ms")
        emit(f"{name}_p95_ms", round(float(np.percentile(t, 95)), 1), "ms")
        emit(f"{name}_max_ms", round(float(t.max()), 1), "ms")
        emit(f"{name}_calls", len(t), "1")
        emit(f"{name}_failures", failures[name], "1")
        emit(f"{name}_path_length_median_rad", round(float(np.median(lengths[name])), 3), "rad")
        emit(f"{name}_work_median_j", round(float(np.median(works[name])), 2), "J")
        print(json.dumps({"bench": "planning", "note": f"{name} slowest from {slowest[name][1]}"}))
    emit("prepare_median_ms", round(float(np.median(prepare_times)) * 1000, 1), "ms")
    emit("mission_path_length_rad", round(mission_length, 3), "rad")
    emit("mission_work_j", round(mission_work, 2), "J")
    rrt_star_comparison()


def rrt_star_comparison() -> None:
    """Work of RRT* with our objective vs with path length, on free segments that neither the
    direct segment nor the staged moves can make (random goals from the unstowed pose, flat
    ground), same seeds; and the wall time of those RRT* solves (the fallback the services
    rarely need)."""
    model = LanderModel()
    config = PlannerConfig()
    planner = ArmPlanner(model, config)
    ctx = CheckContext(model.q_from(UNSTOWED), HeightMap.flat(DEFAULT_GROUND_Z))
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
    ratio = float(np.median(np.array(ours) / np.array(length_only)))
    emit("rrt_star_work_ours_median_j", round(float(np.median(ours)), 2), "J")
    emit("rrt_star_work_path_length_median_j", round(float(np.median(length_only)), 2), "J")
    emit("rrt_star_work_ratio_median", round(ratio, 3), "1")
    t = np.array(solve_times) * 1000
    emit("rrt_star_segment_median_ms", round(float(np.median(t)), 1), "ms")
    emit("rrt_star_segment_p95_ms", round(float(np.percentile(t, 95)), 1), "ms")


if __name__ == "__main__":
    main()
