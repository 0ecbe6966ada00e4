"""The live DEM: a YADE process beside the simulation, in lockstep, digging this trench.

:class:`LiveDemModel` is the terrain-force model ``yade`` (``make_model("yade", params)``). The
simulation gives it its terrain and physics step once (:meth:`LiveDemModel.attach`); then, for
every physics step in which the scoop is in the ground, :meth:`LiveDemModel.wrench` advances the
DEM by exactly that step with the scoop's pose and twist and returns the mean wrench the particles
exerted on it over the step. The simulation waits for the answer, so the run is as deterministic
as the simulation (YADE single-threaded, seeded, the same inputs bit for bit).

* **When.** A DEM *dig* starts at the first scoop state in a dig phase (``state.digging``): a bed
  of spheres is carved to the simulation's terrain around the scoop, aligned with its heading, and
  the scoop's facets (from the URDF, :mod:`ow_dem_bridge.geometry`) are placed in it. The dig goes
  on, every state of the scoop in the ground an exchange, until the simulation's dig phase ends
  (:meth:`LiveDemModel.dig_ended`), the simulation starts a new dig (its progress starts again
  from zero) or the scoop has been out for :data:`DIG_GAP_S`; then the spheres in the scoop are
  the dig's sample (:attr:`LiveDig.sample`). The grinder and the scoop
  outside a dig phase (a guarded move touching the ground) get the *fallback* model's wrench (the
  shipped table by default).
* **Beds.** One template bed per material is settled once (YADE, seeded) and cached on disk
  (``cache_dir``); every dig loads it, removes the spheres above the terrain's heights and those
  the scoop overlaps. The loose regolith on the terrain (the grinder's cuttings in its trench,
  which the height map does not show; the simulation hands it over in :meth:`attach`) stays in
  the bed as loose spheres above the solid surface, up to the loose layer's top
  (:func:`~ow_dem_bridge.live_bed.sample_bed`). See docs/dem.md, "Live co-simulation", for the
  sizes and why.
* **Process.** :class:`~ow_dem_bridge.yade_worker.YadeWorker` runs ``yade -n -x -j1
  yade_live.py`` with two pipes and a JSON line per request and reply. It starts (and settles the
  template) when the model is made, in the background; the first dig waits for it.
* **Failures.** YADE not installed: :class:`~ow_dem_bridge.errors.DemRunError` when the model is
  made, naming the Debian package. The process dying, hanging (``reply_timeout_s``) or the DEM
  diverging (a wrench beyond ``max_force``, a sphere faster than ``max_speed``, NaN) mid-dig:
  :meth:`LiveDemModel.wrench` raises ``DemRunError`` once, with the dig's time and the log's
  tail; the rest of that dig gets the fallback's wrench and the next dig starts a new process.
"""

from __future__ import annotations

import atexit
import hashlib
import json
import logging
import math
import os
import shutil
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ow_dem_bridge.api import (
    LooseTop,
    TerrainForceModel,
    TerrainHeights,
    ToolState,
    Wrench,
)
from ow_dem_bridge.errors import ConfigError, DemRunError
from ow_dem_bridge.geometry import ToolGeometry, load_tool
from ow_dem_bridge.live_bed import BedFrame, BedGrid, DemSurface, dig_heading, sample_bed
from ow_dem_bridge.live_config import MATERIALS, LiveConfig, steps_per_exchange
from ow_dem_bridge.make_tables import ALUMINIUM, Soil
from ow_dem_bridge.yade_worker import YadeWorker
from ow_description.description import URDF_PATH

#: s of simulated time the scoop may be out of the ground before its DEM dig ends (the
#: simulation's own ``DIG_END_GAP_S``: it starts counting progress from zero after it).
DIG_GAP_S = 1.0
#: rospy's named-logger convention (``rosout.<name>``): in a node, these lines reach /rosout and
#: the node's log like ``rospy.loginfo``'s, without this module importing rospy.
LOG = logging.getLogger("rosout.ow_dem_bridge.live")


# ------------------------------------------------------------------------------ the model
@dataclass
class LiveDig:
    """One DEM dig: its bed, every exchange and its sample.

    Attributes:
        start_time: s of sim time of the first exchange.
        material: material id.
        particles: spheres in the bed when the dig started, the loose ones included.
        loose_particles: of ``particles``, those of the loose layer (above the solid surface).
        steps_per_exchange: DEM steps per simulation step.
        dem_dt: s, the DEM time step.
        bed_origin: (3,) m, the bed frame's origin in base_link (back of the bed, on its floor).
        heading: rad, the bed's x axis (the dig's direction) from base_link x.
        truncated_m: m of terrain relief above the template that the bed could not follow.
        solid_fraction: the bed's spheres' volume over its bulk volume (the settled template's,
            measured by YADE: 1 - porosity).
        setup_wall_s: s of wall time to make the bed (after YADE was ready).
        exchange_wall_s: s of wall time spent in exchanges.
        dem_elapsed_s: s of DEM time since the bed was made, after the last exchange: the sim
            time from the dig's start to the end of that exchange's step.
        times: s of sim time of each exchange.
        depths: m, the tool state's depth at each exchange.
        progress: m, the tool state's progress at each exchange.
        wrenches: (Fx, Fy, Fz, Tx, Ty, Tz) N, N m of each exchange (l_scoop frame, about its COM).
        sample: the spheres in the scoop when the dig ended (``sample_particles``,
            ``sample_volume_m3`` the spheres' own volume, ``sample_mass_kg``, and
            ``sample_bulk_volume_m3`` the regolith's volume they make at the bed's packing,
            ``sample_volume_m3 / solid_fraction``), None before.
        error: why the DEM failed during this dig, or None.
        surface: what the dig did to its bed's surface (:class:`DemSurface`: the change of its
            bulk heights on a coarse grid, the sample left out), None before it ended or when
            it failed. Not in :meth:`summary` (the simulation's, not the reports').
    """

    start_time: float
    material: int
    particles: int
    loose_particles: int
    steps_per_exchange: int
    dem_dt: float
    bed_origin: tuple[float, float, float]
    heading: float
    truncated_m: float
    solid_fraction: float
    setup_wall_s: float
    exchange_wall_s: float = 0.0
    dem_elapsed_s: float = 0.0
    times: list[float] = field(default_factory=list)
    depths: list[float] = field(default_factory=list)
    progress: list[float] = field(default_factory=list)
    wrenches: list[list[float]] = field(default_factory=list)
    sample: dict[str, float] | None = None
    error: str | None = None
    surface: DemSurface | None = None

    def summary(self) -> dict[str, Any]:
        """The dig without its per-exchange arrays and its surface (for reports)."""
        record = asdict(replace(self, surface=None))
        for key in ("times", "depths", "progress", "wrenches", "surface"):
            record.pop(key)
        record["exchanges"] = len(self.times)
        return record


class LiveDemModel:
    """The terrain-force model ``yade`` (module docstring).

    Args:
        config: validated parameters.
        fallback: the model for the grinder and for the scoop outside a dig (None: no force).
        urdf: the lander URDF (the scoop's facets).

    Raises:
        DemRunError: YADE is not installed, or its process cannot be started.
    """

    def __init__(
        self, config: LiveConfig, fallback: TerrainForceModel | None, urdf: Path = URDF_PATH
    ) -> None:
        if shutil.which(config.yade) is None:
            msg = (
                f"the live DEM needs YADE, and {config.yade!r} is not on PATH: install the "
                "Debian package 'yade' (apt-get install yade; make setup installs it unless "
                "OW_SKIP_YADE=1)"
            )
            raise DemRunError(msg)
        self.config = config
        self.fallback = fallback or _NoForce()
        self.scoop: ToolGeometry = load_tool(urdf, "l_scoop")
        self.step_s = config.step_s
        self.terrain: TerrainHeights | None = None
        self.loose_top: LooseTop | None = None
        #: the bed of the dig under way (its material's top), None between digs.
        self._grid: BedGrid | None = None
        #: every DEM dig so far, the one under way last.
        self.digs: list[LiveDig] = []
        self._dig: LiveDig | None = None
        #: digs ended or failed since the last :meth:`take_finished`.
        self._finished: list[LiveDig] = []
        #: the failed dig's last progress: its remaining states get the fallback's wrench.
        self._failed_progress: float | None = None
        self._last_time = -math.inf
        self._last_progress = 0.0
        self._exchanges = 0
        self._worker: YadeWorker | None = None
        self._template_material: int | None = None
        self._pending = 0  # replies still to read (hello, template)
        self._bed = BedFrame((0.0, 0.0, 0.0), 0.0)
        self._template_reply: dict[str, Any] = {}
        self._bed_time = 0.0  # s, the DEM's clock when the bed was made
        if config.material:
            self._start_worker(config.material)
        atexit.register(self.close)

    # ------------------------------------------------------------------ the simulation's side
    def attach(
        self, terrain: TerrainHeights, step_s: float, loose_top: LooseTop | None = None
    ) -> None:
        """The simulation's terrain and loose regolith (both read when a dig starts) and its
        physics step (s)."""
        if not step_s > 0:
            msg = f"the physics step must be > 0 s, got {step_s!r}"
            raise ConfigError(msg)
        self.terrain = terrain
        self.loose_top = loose_top
        self.step_s = step_s

    def material_top(self, x: float, y: float) -> float:
        """m, base_link z of the material's top at (x, y) m: the bed's as made (its loose layer
        included; ``-inf`` beyond it) while a dig is under way, else the terrain's with its loose
        regolith now (``-inf`` before :meth:`attach`)."""
        if self._grid is not None:
            return self._grid.top_at(x, y)
        if self.terrain is None:
            return -math.inf
        top = self.terrain.height_at(x, y)
        if self.loose_top is not None:
            top = max(top, self.loose_top(x, y))
        return top

    def wrench(self, state: ToolState) -> Wrench:
        """The scoop's wrench from the DEM over one physics step from ``state.time`` while it
        digs; the fallback's otherwise.

        Raises:
            DemRunError: the DEM process died, hung or diverged, or the terrain's material has
                no particles (once per dig; the message says when and quotes YADE's log).
            ConfigError: the scoop digs before :meth:`attach` (a programming error).
        """
        if state.tool != "scoop" or state.time is None or state.pose is None:
            return self.fallback.wrench(state)
        gap = state.time - self._last_time
        new_dig = state.progress < self._last_progress or gap > DIG_GAP_S + 1e-9
        self._last_time, self._last_progress = state.time, state.progress
        if new_dig:
            self.finish_dig()
            self._failed_progress = None
        if self._failed_progress is not None:
            return self.fallback.wrench(state)
        if self._dig is None:
            if not state.digging:
                return self.fallback.wrench(state)
            self._dig = self._start_dig(state)
        return self._exchange(self._dig, state)

    def dig_ended(self) -> dict[str, Any] | None:
        """The simulation's scoop left its dig phase: :meth:`finish_dig` (the sample counted
        now, not at the next dig's start, which the mission's last dig never has).

        Returns:
            The dig it ended (:meth:`LiveDig.summary`, and ``surface``: what it did to its
            bed's surface, :class:`~ow_dem_bridge.live_bed.DemSurface`, for the terrain to
            take; None unless ``terrain_from_dem``), None when none was under way.

        Raises:
            DemRunError: the DEM process failed while counting the sample.
        """
        dig = self.finish_dig()
        if dig is None:
            return None
        return {**dig.summary(), "surface": dig.surface if self.config.terrain_from_dem else None}

    def take_finished(self) -> list[dict[str, Any]]:
        """The digs that ended (their sample counted) or failed since the last call, oldest
        first, each as :meth:`LiveDig.summary`."""
        done, self._finished = self._finished, []
        return [dig.summary() for dig in done]

    def finish_dig(self) -> LiveDig | None:
        """End the DEM dig under way (its sample: the spheres in the scoop); the dig, or None.

        Raises:
            DemRunError: the DEM process failed while counting the sample.
        """
        dig, self._dig = self._dig, None
        self._grid = None
        if dig is None:
            return None
        worker = self._require_worker()
        try:
            reply = worker.call({"op": "finish"}, self.config.reply_timeout_s)
        except DemRunError as error:
            self._fail(dig, error)
            raise
        dig.sample = {
            k: float(reply[k]) for k in ("sample_particles", "sample_volume_m3", "sample_mass_kg")
        }
        dig.sample["sample_bulk_volume_m3"] = dig.sample["sample_volume_m3"] / dig.solid_fraction
        dig.surface = DemSurface.from_reply(reply["surface"], self._bed)
        self._finished.append(dig)
        LOG.info(
            "live DEM: the dig that started at t=%.3f s ended after %d exchanges (%.1f s of "
            "wall time); %d spheres in the scoop, %.3g m3",
            dig.start_time,
            len(dig.times),
            dig.exchange_wall_s,
            dig.sample["sample_particles"],
            dig.sample["sample_volume_m3"],
        )
        return dig

    def wait_ready(self, material: int | None = None) -> dict[str, Any]:
        """Wait until YADE runs and holds the template bed of ``material`` (default: the
        configured one), settling and caching it on first use; the template's reply.

        Raises:
            DemRunError: YADE failed to start or to settle the bed within ``start_timeout_s``.
        """
        return self._ready(material or self.config.material or 1)

    def close(self) -> None:
        """Stop the YADE process (idempotent; also at exit)."""
        if self._worker is not None:
            self._worker.close()
            self._worker = None

    @property
    def worker_pid(self) -> int | None:
        """The YADE process id, None when none runs."""
        return None if self._worker is None else self._worker.pid

    # ------------------------------------------------------------------ digs
    def _start_worker(self, material: int) -> None:
        """Start YADE and ask for the material's template bed (answered later)."""
        cache = self.config.cache_path
        logs = cache / "logs"
        self._worker = YadeWorker(self.config.yade, logs / f"yade_live_{os.getpid()}.log")
        self._pending = 1  # hello
        self._request_template(material)

    def _request_template(self, material: int) -> None:
        soil = self._soil(material)
        worker = self._require_worker()
        c = self.config
        spec = {
            "soil": asdict(soil),
            "tool_material": asdict(ALUMINIUM),
            "particle_radius": c.particle_radius,
            "radius_fuzz": c.radius_fuzz,
            "dt_safety": c.dt_safety,
            "bed": {"length": c.bed_length, "width": c.bed_width, "depth": c.bed_height},
            "seed": c.seed,
            "settle_time_max": c.settle_time_max,
        }
        digest = hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:16]
        path = c.cache_path / f"live_bed_{soil.name}_{digest}.yade.gz"
        worker.send({"op": "template", "job": {**spec, "bed_file": str(path)}})
        self._pending += 1
        self._template_material = material

    def _soil(self, material: int) -> Soil:
        if material not in MATERIALS:
            msg = (
                f"the live DEM has no particles for terrain material {material}; "
                f"it has {', '.join(f'{m} ({s.name})' for m, s in MATERIALS.items())}"
            )
            raise ConfigError(msg)
        return MATERIALS[material]

    def _require_worker(self) -> YadeWorker:
        if self._worker is None:
            msg = "the live DEM has no YADE process"
            raise DemRunError(msg)
        return self._worker

    def _ready(self, material: int) -> dict[str, Any]:
        """Start the worker if needed and wait until it holds the material's template; the
        template's reply."""
        if self._worker is None:
            self._start_worker(material)
        elif self._template_material != material:
            self._request_template(material)
        worker = self._require_worker()
        while self._pending:
            self._template_reply = worker.receive(self.config.start_timeout_s)
            self._pending -= 1
        return self._template_reply

    def _start_dig(self, state: ToolState) -> LiveDig:
        """Carve a bed to the terrain around the scoop and place the scoop in it."""
        if self.terrain is None:
            msg = "the live DEM was asked for a dig before the simulation attached its terrain"
            raise ConfigError(msg)
        assert state.pose is not None and state.time is not None
        c = self.config
        if state.material not in MATERIALS:
            self._failed_progress = state.progress
            msg = (
                f"the live DEM cannot dig at t={state.time:.3f} s: it has no particles for "
                f"terrain material {state.material} (it has {sorted(MATERIALS)})"
            )
            raise DemRunError(msg)
        soil = MATERIALS[state.material]
        try:
            self._ready(state.material)
            worker = self._require_worker()
        except DemRunError as error:
            self._failed_progress = state.progress
            self.close()
            msg = f"the live DEM could not start a dig at t={state.time:.3f} s: {error}"
            raise DemRunError(msg) from error
        started = time.monotonic()
        pose = np.asarray(state.pose, dtype=np.float64)
        rotation, origin = pose[:3, :3], pose[:3, 3]
        tip = rotation @ self.scoop.tip + origin
        heading = dig_heading(rotation, rotation @ np.asarray(state.velocity), tip)
        cos_h, sin_h = math.cos(heading), math.sin(heading)
        us = np.linspace(0.0, c.bed_length, max(2, round(c.bed_length / c.grid_step) + 1))
        vs = np.linspace(
            -c.bed_width / 2, c.bed_width / 2, max(2, round(c.bed_width / c.grid_step) + 1)
        )
        back = tip[:2] - c.bed_behind * np.array([cos_h, sin_h])
        grid = sample_bed(
            self.terrain, self.loose_top, (float(back[0]), float(back[1])), heading, us, vs
        )
        floor = float(grid.solid.min()) - c.floor_depth
        bed_origin = (float(back[0]), float(back[1]), floor)
        count, dem_dt = steps_per_exchange(self.step_s, c, soil)
        self._bed = BedFrame(bed_origin, heading)
        pos, quat = self._bed.pose(rotation, origin)
        request = {
            "op": "bed",
            "u": us.tolist(),
            "v": vs.tolist(),
            "h": (grid.solid - floor).tolist(),
            "top": (grid.top - floor).tolist(),
            "gravity": c.gravity,
            "dt": dem_dt,
            "read_steps": min(c.read_steps, count),
            "pos": pos,
            "quat": quat,
            "tool": {
                "facets": [list(map(list, tri)) for tri in self.scoop.facets],
                "com": self.scoop.com.tolist(),
            },
        }
        try:
            reply = worker.call(request, c.reply_timeout_s)
        except DemRunError as error:
            self._failed_progress = state.progress
            self.close()
            msg = f"the live DEM could not make its bed at t={state.time:.3f} s: {error}"
            raise DemRunError(msg) from error
        dig = LiveDig(
            start_time=state.time,
            material=state.material,
            particles=int(reply["particles"]),
            loose_particles=int(reply["loose_particles"]),
            steps_per_exchange=count,
            dem_dt=dem_dt,
            bed_origin=bed_origin,
            heading=heading,
            truncated_m=float(reply["truncated_m"]),
            solid_fraction=float(self._template_reply["solid_fraction"]),
            setup_wall_s=time.monotonic() - started,
        )
        self._bed_time = float(reply["time"])
        self._grid = grid
        self.digs.append(dig)
        self._exchanges = 0
        LOG.info(
            "live DEM: dig at t=%.3f s, bed of %d spheres (%d of them loose regolith; %d DEM "
            "steps of %.3g s per %.3g s step) made in %.1f s",
            state.time,
            dig.particles,
            dig.loose_particles,
            count,
            dem_dt,
            self.step_s,
            dig.setup_wall_s,
        )
        return dig

    def _exchange(self, dig: LiveDig, state: ToolState) -> Wrench:
        """Advance the DEM by one physics step with the scoop at ``state``'s pose and twist."""
        assert state.pose is not None and state.time is not None
        c = self.config
        worker = self._require_worker()
        pose = np.asarray(state.pose, dtype=np.float64)
        rotation, origin = pose[:3, :3], pose[:3, 3]
        # The DEM moves the link origin: its velocity from the tip's (link frame).
        omega = np.asarray(state.angular_velocity, dtype=np.float64)
        v_origin = np.asarray(state.velocity, dtype=np.float64) - np.cross(omega, self.scoop.tip)
        pos, quat = self._bed.pose(rotation, origin)
        to_bed = self._bed.rotation.T @ rotation
        request = {
            "op": "step",
            "pos": pos,
            "quat": quat,
            "v": (to_bed @ v_origin).tolist(),
            "w": (to_bed @ omega).tolist(),
            "steps": dig.steps_per_exchange,
        }
        # Steps in which the scoop was out of the ground (no call) still pass in the DEM: the
        # scoop glides from where it was to where it is now, so the two clocks stay together.
        due = round((state.time - dig.start_time) / self.step_s)
        started = time.monotonic()
        try:
            if due > self._exchanges:
                steps = (due - self._exchanges) * dig.steps_per_exchange
                glide = {"op": "glide", "pos": pos, "quat": quat, "steps": steps}
                worker.call(glide, c.reply_timeout_s)
            reply = worker.call(request, c.reply_timeout_s)
            values = [float(v) for v in reply["wrench"]]
            _check_divergence(values, float(reply["max_speed"]), c)
        except DemRunError as error:
            self._fail(dig, error)
            msg = (
                f"the live DEM failed at t={state.time:.3f} s of the dig that started at "
                f"t={dig.start_time:.3f} s (exchange {len(dig.times) + 1}): {error}"
            )
            raise DemRunError(msg) from error
        dig.exchange_wall_s += time.monotonic() - started
        dig.dem_elapsed_s = float(reply["time"]) - self._bed_time
        self._exchanges = due + 1
        dig.times.append(state.time)
        dig.depths.append(state.depth)
        dig.progress.append(state.progress)
        dig.wrenches.append(values)
        return Wrench(np.array(values[:3]), np.array(values[3:]))

    def _fail(self, dig: LiveDig, error: DemRunError) -> None:
        """Record the failure; the process is stopped, the rest of the dig gets the fallback."""
        LOG.error(
            "live DEM: the dig that started at t=%.3f s failed; the rest of it gets the %r "
            "model's wrench, the next dig a new YADE process: %s",
            dig.start_time,
            self.config.fallback,
            error,
        )
        dig.error = str(error)
        self._finished.append(dig)
        self._dig = None
        self._grid = None
        self._failed_progress = self._last_progress
        self.close()


class _NoForce:
    """The fallback when there is none: no terrain force."""

    def wrench(self, state: ToolState) -> Wrench:
        """A zero wrench."""
        return Wrench(np.zeros(3), np.zeros(3))


def _check_divergence(wrench: list[float], max_speed: float, config: LiveConfig) -> None:
    """Raise DemRunError when an exchange's results mean the DEM diverged."""
    if not all(math.isfinite(v) for v in wrench) or not math.isfinite(max_speed):
        msg = f"the DEM diverged: non-finite wrench {wrench} or sphere speed {max_speed}"
        raise DemRunError(msg)
    force = math.sqrt(sum(v * v for v in wrench[:3]))
    if force > config.max_force:
        msg = (
            f"the DEM diverged: a force of {force:.3g} N on the scoop "
            f"(max_force {config.max_force:g} N)"
        )
        raise DemRunError(msg)
    if max_speed > config.max_speed:
        msg = (
            f"the DEM diverged: a sphere moves at {max_speed:.3g} m/s "
            f"(max_speed {config.max_speed:g} m/s)"
        )
        raise DemRunError(msg)


def main(argv: list[str] | None = None) -> int:
    """``python -m ow_dem_bridge.live --prepare``: settle and cache the template beds, so that
    no dig of a mission waits for one (the first settle takes minutes)."""
    import argparse

    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--prepare", action="store_true", help="settle the template beds")
    parser.add_argument("--materials", type=int, nargs="*", default=sorted(MATERIALS))
    parser.add_argument("--cache-dir", default="", help="default $ROS_HOME/ow_dem_bridge")
    args = parser.parse_args(argv)
    if not args.prepare:
        parser.print_help()
        return 0
    try:
        model = LiveDemModel(LiveConfig(cache_dir=args.cache_dir, material=0), None)
        for material in args.materials:
            started = time.monotonic()
            reply = model.wait_ready(material)
            print(
                f"material {material} ({MATERIALS[material].name}): template of "
                f"{reply['template_spheres']} spheres "
                f"{'found in' if reply['cached'] else 'settled into'} "
                f"{model.config.cache_path} ({time.monotonic() - started:.0f} s)"
            )
        model.close()
    except (DemRunError, ConfigError) as error:
        print(f"live DEM: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
