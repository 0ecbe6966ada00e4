"""Cost of one physics step of the simulation without ROS: the core (physics, controller, contacts,
carving) and its outputs (every message built and serialised as the node does, then dropped).

Drives ``BulletSim`` and ``SimOutputs`` of the simulation node's configuration (``sim.yaml``,
``pid.yaml``) on flat ground at the stowed pose's height, (a) holding the stowed pose and (b) in
the sweep ``bench/sim_speed.py`` digs (``SCOOP_DIG_SWEEP``: the scoop lowered and dragged mouth
first through fresh terrain), with no terrain-force model and (c) with the DEM tables the mission
uses. One JSON line per metric: us a step of the core alone, of the core with its outputs, of
Bullet's ``stepSimulation`` within them and of every pybullet call within them (the part no change
of our Python can remove: the rest is our Python); the real-time factor they allow. Where
``bench/sim_speed.py`` adds the node's ROS (sockets, threads) and the machine's other processes,
this isolates the simulation's own code (docs/history/performance-journal.md, twelfth and thirteenth
rounds).

    source env.sh && python bench/sim_core.py
"""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Callable
from typing import Any

import pybullet as pb
import yaml

from ow_description.description import (
    DEFAULT_GROUND_Z,
    SCOOP_ABOVE_GROUND,
    SCOOP_DIG_SWEEP,
    URDF_PATH,
)
from ow_sim_bullet import conversions
from ow_sim_bullet.config import PID_YAML, SIM_YAML, SimConfig
from ow_sim_bullet.outputs import WIRE_TOPICS, SimOutputs
from ow_sim_bullet.sim_core import BulletSim, make_force_model
from ow_sim_bullet.terrains import parse_terrain_spec
from ow_sim_bullet.trajectory import JointTrajectory

#: physics steps measured per case (60 s of sim time at 100 Hz), after the warm-up.
STEPS = 6000
#: steps before the measurement: the arm settles (hold), or reaches the sweep (dig).
HOLD_WARMUP = 500
DIG_WARMUP = 1800


class _Serialising:
    """A wire publisher that builds every payload, as the node's, and drops it."""

    def __init__(self) -> None:
        self.seq = 0

    def publish(self, serialize: Callable[..., bytes], *args: Any) -> None:
        self.seq += 1
        serialize(self.seq, *args)

    def flush(self, only: Any = None) -> None:
        """Nothing queued."""


class _Dropping:
    """The terrain's publisher (genpy messages): the message is built by SimOutputs, dropped."""

    def publish(self, msg: Any) -> None:
        """Dropped."""


class _TimedPybullet:
    """Every function of the pybullet module, timed while installed (``stepSimulation`` apart)."""

    def __init__(self) -> None:
        self.step_seconds = 0.0
        self.seconds = 0.0
        self._originals = {
            name: getattr(pb, name)
            for name in dir(pb)
            if not name.startswith("_") and callable(getattr(pb, name))
        }

    def _timed(self, name: str, function: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            result = function(*args, **kwargs)
            elapsed = time.perf_counter() - start
            self.seconds += elapsed
            if name == "stepSimulation":
                self.step_seconds += elapsed
            return result

        return call

    def __enter__(self) -> _TimedPybullet:
        """Install the timed functions; the clocks start at 0."""
        self.seconds = self.step_seconds = 0.0
        for name, function in self._originals.items():
            setattr(pb, name, self._timed(name, function))
        return self

    def __exit__(self, *exc: object) -> None:
        """Put pybullet's own functions back."""
        for name, function in self._originals.items():
            setattr(pb, name, function)


def _simulation(forces: str) -> tuple[BulletSim, SimOutputs]:
    raw = {**yaml.safe_load(SIM_YAML.read_text()), **yaml.safe_load(PID_YAML.read_text())}
    raw.update(terrain=f"flat:{DEFAULT_GROUND_Z}", terrain_forces=forces)
    config = SimConfig.from_dict(raw)
    model = make_force_model(config.terrain_forces, config.terrain_force_params)
    sim = BulletSim(config, parse_terrain_spec(config.terrain), model)
    publishers = {topic: _Serialising() for topic, _ in WIRE_TOPICS}
    frames = conversions.joint_frames(URDF_PATH.read_text())
    return sim, SimOutputs(sim, config, publishers, _Dropping(), frames)


def _sweep(sim: BulletSim) -> JointTrajectory:
    """bench/sim_speed.py's dig (SCOOP_DIG_SWEEP) from where the arm is."""
    joints = list(SCOOP_ABOVE_GROUND)
    start = [sim.position(j) for j in joints]
    return JointTrajectory.build(
        joints,
        sim.time,
        [0.0, *(t for t, _ in SCOOP_DIG_SWEEP)],
        [start, *([pose[j] for j in joints] for _, pose in SCOOP_DIG_SWEEP)],
        None,
        sim.names,
    )


def _run(
    case: str, forces: str, outputs_on: bool, timed: _TimedPybullet | None
) -> tuple[float, float]:
    """s of wall time of :data:`STEPS` steps after the case's warm-up, and the step (s); with
    ``timed``, their pybullet calls are timed (the wrappers cost ~10 %: the total is measured
    without them)."""
    sim, outputs = _simulation(forces)
    try:
        warmup = HOLD_WARMUP
        if case == "dig":
            for _ in range(HOLD_WARMUP):
                sim.step()
            sim.set_trajectory(_sweep(sim))
            warmup = DIG_WARMUP
        for _ in range(warmup):
            sim.step()
            if outputs_on:
                outputs.after_step()
        with timed if timed is not None else contextlib.nullcontext():
            start = time.perf_counter()
            for _ in range(STEPS):
                sim.step()
                if outputs_on:
                    outputs.after_step()
            elapsed = time.perf_counter() - start
        return elapsed, sim.dt
    finally:
        sim.close()


def _measure(case: str, forces: str) -> dict[str, float]:
    """us a step of the core and of the core with its outputs; of stepSimulation and of every
    pybullet call within each (from a second, instrumented run)."""
    result: dict[str, float] = {}
    for outputs_on in (False, True):
        kind = "outputs" if outputs_on else "core"
        elapsed, dt = _run(case, forces, outputs_on, None)
        timed = _TimedPybullet()
        _run(case, forces, outputs_on, timed)
        result[f"{kind}_us"] = elapsed / STEPS * 1e6
        result[f"{kind}_rtf"] = STEPS * dt / elapsed
        result[f"{kind}_step_simulation_us"] = timed.step_seconds / STEPS * 1e6
        result[f"{kind}_pybullet_us"] = timed.seconds / STEPS * 1e6
    return result


def line(metric: str, value: float, unit: str, **extra: object) -> None:
    print(
        json.dumps(
            {"bench": "sim_core", "metric": metric, "value": round(value, 1), "unit": unit, **extra}
        ),
        flush=True,
    )


def main() -> None:
    for case, forces, label in (
        ("hold", "none", "holding"),
        ("dig", "none", "digging"),
        ("dig", "table", "digging_dem_table"),
    ):
        r = _measure(case, forces)
        line(f"core_us_per_step_{label}", r["core_us"], "us", rtf=round(r["core_rtf"], 1))
        line(
            f"core_step_simulation_us_{label}",
            r["core_step_simulation_us"],
            "us",
            note="pybullet stepSimulation, within the core's",
        )
        line(
            f"core_pybullet_us_{label}",
            r["core_pybullet_us"],
            "us",
            note="every pybullet call within the core's (the rest is our Python)",
        )
        line(
            f"core_outputs_us_per_step_{label}",
            r["outputs_us"],
            "us",
            rtf=round(r["outputs_rtf"], 1),
            note="core and every output serialised, no ROS",
        )
        line(
            f"core_outputs_pybullet_us_{label}",
            r["outputs_pybullet_us"],
            "us",
            note="every pybullet call within the core's with outputs",
        )


if __name__ == "__main__":
    main()
