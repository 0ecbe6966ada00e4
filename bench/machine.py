"""How fast this machine is right now, on fixed work like the stack's: a yardstick for the others.

The project's VM runs the same code 1.4x slower in one hour than in another (the default mission
took 14.0 s at 01:20 UTC and 20.5 s at 03:10 UTC on 2026-11-26, docs/performance.md). Run this
beside the other benches to tell a change from the hour. Three fixed workloads, one core each, the
median of :data:`REPEATS` runs:

* ``python_us``: the interpreter alone (a loop of float arithmetic, attribute and dict access,
  calls and a tuple built, as the nodes' callbacks do), us per iteration;
* ``numpy_small_us``: a dozen numpy operations on (9,) arrays, as the joint controller does, us
  per round;
* ``pybullet_step_us``: ``stepSimulation`` of a 10 kg box resting on a plane, us per step.

One JSON line per metric; lower is a faster machine.

    source env.sh && python bench/machine.py
"""

from __future__ import annotations

import json
import statistics
import time
from collections.abc import Callable

import numpy as np
import pybullet as pb

#: runs of each workload; the median is reported.
REPEATS = 7


class _Joint:
    def __init__(self, name: str) -> None:
        self.name = name
        self.position = 0.0


def _python(iterations: int) -> None:
    joints = [_Joint(f"j{k}") for k in range(9)]
    index = {joint.name: k for k, joint in enumerate(joints)}
    total = 0.0
    for i in range(iterations):
        joint = joints[i % 9]
        joint.position = joint.position * 0.5 + i * 1e-6
        total += joint.position * index[joint.name]
        pair = (joint.name, total)
        total -= len(pair) * 1e-9
    if not np.isfinite(total):
        raise RuntimeError(total)


def _numpy(rounds: int) -> None:
    rng = np.random.default_rng(0)
    q, v, gain = rng.standard_normal(9), rng.standard_normal(9), np.abs(rng.standard_normal(9))
    limit = np.full(9, 0.5)
    integral = np.zeros(9)
    for _ in range(rounds):
        error = 0.1 - q
        effort = gain * error + integral
        effort = effort + gain * (0.0 - v)
        saturated = np.abs(effort) > limit
        effort = np.minimum(np.maximum(effort, -limit), limit)
        integral = np.where(saturated, integral, integral + error * 1e-3)
        v = v + 1e-3 * effort
        q = q + 1e-3 * v


def _pybullet(steps: int) -> None:
    client = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0.0, 0.0, -9.81, physicsClientId=client)
        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=client)
        pb.createMultiBody(0.0, plane, physicsClientId=client)
        box = pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=[0.1, 0.1, 0.1], physicsClientId=client
        )
        pb.createMultiBody(10.0, box, basePosition=[0.0, 0.0, 0.1], physicsClientId=client)
        for _ in range(steps):
            pb.stepSimulation(physicsClientId=client)
    finally:
        pb.disconnect(physicsClientId=client)


def _median_us(work: Callable[[int], None], count: int) -> float:
    """us per unit of ``work(count)``, the median of :data:`REPEATS` runs after one warm-up."""
    work(count // 10)
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        work(count)
        times.append((time.perf_counter() - start) / count * 1e6)
    return statistics.median(times)


def main() -> None:
    for metric, work, count, note in (
        ("python_us", _python, 1_000_000, "interpreter: one iteration of a fixed loop"),
        ("numpy_small_us", _numpy, 20_000, "a dozen numpy operations on (9,) arrays"),
        ("pybullet_step_us", _pybullet, 20_000, "stepSimulation of a box resting on a plane"),
    ):
        value = _median_us(work, count)
        print(
            json.dumps(
                {
                    "bench": "machine",
                    "metric": metric,
                    "value": round(value, 3),
                    "unit": "us",
                    "note": note,
                }
            ),
            flush=True,
        )


if __name__ == "__main__":
    main()
