"""The live DEM (YADE in lockstep, ``terrain_forces: yade``) on one linear dig, against the
shipped table and Balovnev for the same dig (the paper's Table 6 metric and Figure 19).

Runs the simulation in process (no ROS) on flat ground at the default ground height and follows
a ``dig_linear`` planned by ``ow_lander.operations`` (x 1.65 m, depth 5 cm, length 20 cm) with
the ``yade`` model. At every exchange the same tool state is also given to the ``table`` and
``balovnev`` models (what they would have applied), so the three series share their states.
Prints one JSON line per metric:

* ``sim_s_per_wall_s``: simulated seconds per wall second while the scoop digs live, from the
  first exchange to the last (simulation steps and DEM exchanges); ``sim_s_per_dem_cpu_s`` the
  same per CPU second of the YADE process (less sensitive to the machine's load);
* ``particles``, ``dem_steps_per_exchange``, ``exchanges``, ``bed_setup_wall_s``;
* ``nrmsd_<model>_<F>``: the normalized RMS deviation of the model's Fx, Fy, Fz from the live
  DEM's over the dig, RMS(model - live) / (max(live) - min(live)) (l_scoop frame);
* ``mean_<model>_<F>`` (N): the mean over the dig, the live DEM's as ``mean_live_<F>``;
* ``sample_volume_m3``, ``sample_particles``: the spheres in the scoop at the end.

The plot (``--plot``, default ``bench/out/cosim.png``) shows the three models' force components
along the dig, like the paper's Figure 19. ``--quick`` stops after 200 exchanges (a smoke run).

    source env.sh && python bench/cosim.py [--quick] [--plot PATH]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from ow_dem_bridge.api import ToolState, Wrench
from ow_dem_bridge.comparison import COMPONENTS, nrmsd
from ow_dem_bridge.live import LiveDemModel
from ow_dem_bridge.models import make_model
from ow_description.description import DEFAULT_GROUND_Z, UNSTOWED
from ow_description.model import LanderModel
from ow_lander.config import PlannerConfig, TimingConfig
from ow_lander.operations.planner import Operations
from ow_lander.planning.planner import ArmPlanner
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import flat
from ow_sim_bullet.trajectory import JointTrajectory

ROOT = Path(__file__).resolve().parents[1]
DIG = {"x": 1.65, "y": 0.0, "depth": 0.05, "length": 0.2, "ground_position": DEFAULT_GROUND_Z}
COMPARED = ("table", "balovnev")


def emit(metric: str, value: float, unit: str, **extra: Any) -> None:
    record = {"bench": "cosim", "metric": metric, "value": value, "unit": unit, **extra}
    print(json.dumps(record), flush=True)


def cpu_seconds(pid: int | None) -> float:
    """s of CPU time (user + system) of a process so far; 0 when it is gone."""
    if pid is None:
        return 0.0
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class Shadowed:
    """The live model, with the compared models asked about the same states while it digs."""

    def __init__(self, live: LiveDemModel) -> None:
        self.live = live
        self.others = {name: make_model(name) for name in COMPARED}
        self.shadow: dict[str, list[list[float]]] = {name: [] for name in COMPARED}

    def attach(self, terrain: Any, step_s: float, loose_top: Any = None) -> None:
        self.live.attach(terrain, step_s, loose_top)

    def material_top(self, x: float, y: float) -> float:
        return self.live.material_top(x, y)

    def close(self) -> None:
        self.live.close()

    def dig_ended(self) -> dict[str, Any] | None:
        return self.live.dig_ended()

    def take_finished(self) -> list[dict[str, Any]]:
        return self.live.take_finished()

    def wrench(self, state: ToolState) -> Wrench:
        dig = self.live.digs[-1] if self.live.digs else None
        before = len(dig.times) if dig is not None else 0
        wrench = self.live.wrench(state)
        now = self.live.digs[-1] if self.live.digs else None
        if now is not None and (now is not dig or len(now.times) > before):
            if now is not dig:  # a new dig: its series start again
                self.shadow = {name: [] for name in COMPARED}
            for name, model in self.others.items():
                w = model.wrench(state)
                self.shadow[name].append([*map(float, w.force), *map(float, w.torque)])
        return wrench


def run(quick: bool) -> tuple[Shadowed, float, float, float]:
    """Follow the dig; (the models, sim s and wall s and YADE CPU s while digging live)."""
    config = SimConfig(initial_positions={**SimConfig().initial_positions, **UNSTOWED})
    live = make_model("yade")
    assert isinstance(live, LiveDemModel)
    live.wait_ready()  # the template bed settled (or found cached) before the clock starts
    model = Shadowed(live)
    sim = BulletSim(config, flat(DEFAULT_GROUND_Z), model)
    ops = Operations(ArmPlanner(LanderModel(), PlannerConfig()))
    q = ops.model.q_from(dict(zip(sim.names, sim.sample.position.tolist(), strict=True)))
    plan = ops.plan("dig_linear", q, sim.heightmap, DIG)
    timed = plan.timed(TimingConfig(), ops.planner.velocity_limits)
    sim.set_trajectory(JointTrajectory.from_plan(timed, sim.time, sim.names))
    # From the end of the first exchange (the bed made) to the end of the last one, the steps in
    # between (the scoop out of the ground for a step, the DEM gliding through it) included.
    first: tuple[float, float, float] | None = None
    last = (0.0, 0.0, 0.0)
    try:
        for _ in range(round((timed.duration + 1.0) / sim.dt)):
            exchanges = sum(len(d.times) for d in live.digs)
            sim.step()
            if sum(len(d.times) for d in live.digs) > exchanges:
                last = (sim.time, time.perf_counter(), cpu_seconds(live.worker_pid))
                first = first or last
            if quick and live.digs and len(live.digs[-1].times) >= 200:
                break
        live.finish_dig()
    finally:
        sim.close()
        model.close()
    if first is None:
        return model, 0.0, 0.0, 0.0
    return model, last[0] - first[0], last[1] - first[1], last[2] - first[2]


def plot(model: Shadowed, path: Path) -> None:
    """The three models' Fx, Fy, Fz along the dig (paper Figure 19)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dig = model.live.digs[-1]
    progress = np.asarray(dig.progress)
    live = np.asarray(dig.wrenches)
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for row, component in enumerate(COMPONENTS):
        ax = axes[row]
        ax.plot(progress, live[:, row], lw=0.6, color="0.6", label="live DEM (each exchange)")
        window = 25
        if live.shape[0] > window:
            smooth = np.convolve(live[:, row], np.ones(window) / window, mode="same")
            ax.plot(progress, smooth, lw=1.5, color="k", label=f"live DEM ({window}-step mean)")
        for name, style in zip(COMPARED, ("C0", "C3"), strict=True):
            ax.plot(progress, np.asarray(model.shadow[name])[:, row], color=style, label=name)
        ax.set_ylabel(f"{component} (N, l_scoop)")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[2].set_xlabel("progress: scoop tip path below the surface (m)")
    fig.suptitle(
        f"dig_linear x {DIG['x']} m, depth {DIG['depth']} m, length {DIG['length']} m, sand, "
        f"Europa gravity: {dig.particles} spheres"
    )
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="stop after 200 exchanges")
    parser.add_argument("--plot", type=Path, default=ROOT / "bench" / "out" / "cosim.png")
    args = parser.parse_args()
    model, live_sim, live_wall, live_cpu = run(args.quick)
    digs = model.live.digs
    if not digs:
        emit("exchanges", 0, "", note="the scoop never dug live")
        return
    dig = digs[-1]
    if dig.error:
        emit("error", 1, "", message=dig.error)
    emit("sim_s_per_wall_s", round(live_sim / live_wall, 4), "x", sim_s=round(live_sim, 2))
    if live_cpu > 0:
        emit("sim_s_per_dem_cpu_s", round(live_sim / live_cpu, 4), "x")
    emit("particles", dig.particles, "")
    emit("dem_steps_per_exchange", dig.steps_per_exchange, "", dem_dt_s=dig.dem_dt)
    emit("exchanges", len(dig.times), "")
    emit("bed_setup_wall_s", round(dig.setup_wall_s, 2), "s")
    emit("dem_exchange_wall_s", round(dig.exchange_wall_s, 1), "s")
    live = np.asarray(dig.wrenches)
    for row, component in enumerate(COMPONENTS):
        emit(f"mean_live_{component}", round(float(live[:, row].mean()), 3), "N")
        for name in COMPARED:
            other = np.asarray(model.shadow[name])
            emit(f"nrmsd_{name}_{component}", round(nrmsd(other[:, row], live[:, row]), 3), "")
            emit(f"mean_{name}_{component}", round(float(other[:, row].mean()), 3), "N")
    if dig.sample is not None:
        emit("sample_volume_m3", dig.sample["sample_volume_m3"], "m3")
        emit("sample_particles", dig.sample["sample_particles"], "")
    plot(model, args.plot)


if __name__ == "__main__":
    main()
