"""Parameters of the live DEM (:mod:`ow_dem_bridge.live`) and the time step they give.

docs/dem.md, "Live co-simulation", says why each default.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ow_dem_bridge.errors import ConfigError
from ow_dem_bridge.make_tables import SAND, SNOW, Soil
from ow_description.description import EUROPA_GRAVITY
from ow_runtime.params import Params

#: Materials of the live DEM by the simulation's material id (the shipped table's).
MATERIALS: dict[int, Soil] = {1: SAND, 2: SNOW}


def default_cache_dir() -> Path:
    """Where settled template beds are kept: ``$ROS_HOME/ow_dem_bridge`` (``~/.ros`` without)."""
    ros_home = os.environ.get("ROS_HOME") or str(Path.home() / ".ros")
    return Path(ros_home) / "ow_dem_bridge"


@dataclass(frozen=True)
class LiveConfig:
    """Parameters of the live DEM (SI units; docs/dem.md says why each default).

    Attributes:
        particle_radius: m, mean sphere radius (the shipped table's: 5.7x the paper's grains).
        radius_fuzz: relative spread of the radii (uniform).
        dt_safety: DEM time step as a fraction of the Rayleigh step of the smallest sphere.
        read_steps: DEM steps between two reads of the wrench (an exchange answers the mean of
            its reads; a read costs a Python call, ~15 % of a step of a thousand spheres).
        bed_length: m, bed extent along the dig.
        bed_behind: m, of ``bed_length``, behind the scoop tip where the dig starts.
        bed_width: m, bed extent across the dig.
        bed_height: m, thickness of the settled template: the floor depth plus the terrain's
            relief the bed can follow.
        floor_depth: m, the bed's floor below the lowest terrain height in its footprint.
        grid_step: m, spacing of the terrain heights sampled over the bed.
        gravity: m/s2 during digs (Europa's).
        material: material id whose template is settled when the model starts (the
            simulation's ``terrain_material`` default).
        seed: seed of the template's sphere cloud.
        settle_time_max: s of simulated settling of a template at most.
        step_s: s, the simulation's physics step when the model is not attached to one.
        start_timeout_s: s of wall time for YADE to start and settle a template.
        reply_timeout_s: s of wall time for one exchange (or a bed) before the DEM counts as hung.
        max_speed: m/s, a sphere faster than this means the DEM diverged.
        max_force: N, a force on the tool beyond this means the DEM diverged.
        cache_dir: directory of the settled templates and YADE logs ("": the default,
            :func:`default_cache_dir`).
        yade: the YADE launcher (a name on PATH or a path).
        fallback: model for everything but the scoop in a dig ("none", "table", "balovnev").
        fallback_params: that model's parameters.
        terrain_from_dem: when a dig ends, the terrain takes the DEM's surface (docs/dem.md, *The
            terrain takes the DEM's surface*); off, the terrain keeps the geometric carving (the
            scoop's content is the DEM's sample either way). Off by default: in the default
            mission the trench floor it raises blocks the planned approach of the next dig.
    """

    particle_radius: float = 0.01
    radius_fuzz: float = 0.15
    dt_safety: float = 0.3
    read_steps: int = 5
    bed_length: float = 0.5
    bed_behind: float = 0.08
    bed_width: float = 0.2
    bed_height: float = 0.26
    floor_depth: float = 0.1
    grid_step: float = 0.01
    gravity: float = EUROPA_GRAVITY
    material: int = 1
    seed: int = 1
    settle_time_max: float = 1.5
    step_s: float = 0.01
    start_timeout_s: float = 1800.0
    reply_timeout_s: float = 300.0
    max_speed: float = 10.0
    max_force: float = 1.0e4
    cache_dir: str = ""
    yade: str = "yade"
    fallback: str = "table"
    fallback_params: Mapping[str, Any] = field(default_factory=dict)
    terrain_from_dem: bool = False

    @classmethod
    def from_dict(cls, params: Mapping[str, Any]) -> LiveConfig:
        """Validate the model's parameters (every problem reported at once).

        Raises:
            ConfigError: a bad value or an unknown key, named (``yade/bed_width = -1 m ...``).
        """
        d = cls()
        p = Params(params, where="yade", error=ConfigError)
        config = cls(
            particle_radius=p.number(
                "particle_radius", d.particle_radius, low=1e-3, high=0.05, unit="m"
            ),
            radius_fuzz=p.number("radius_fuzz", d.radius_fuzz, low=0.0, high=0.5),
            dt_safety=p.number("dt_safety", d.dt_safety, low=0.0, high=1.0, low_inclusive=False),
            read_steps=p.integer("read_steps", d.read_steps, low=1, high=1000),
            bed_length=p.positive("bed_length", d.bed_length, "m"),
            bed_behind=p.non_negative("bed_behind", d.bed_behind, "m"),
            bed_width=p.positive("bed_width", d.bed_width, "m"),
            bed_height=p.positive("bed_height", d.bed_height, "m"),
            floor_depth=p.positive("floor_depth", d.floor_depth, "m"),
            grid_step=p.positive("grid_step", d.grid_step, "m"),
            gravity=p.positive("gravity", d.gravity, "m/s2"),
            material=p.integer("material", d.material, low=0, high=255),
            seed=p.integer("seed", d.seed, low=0, high=2**31 - 1),
            settle_time_max=p.positive("settle_time_max", d.settle_time_max, "s"),
            step_s=p.positive("step_s", d.step_s, "s"),
            start_timeout_s=p.positive("start_timeout_s", d.start_timeout_s, "s"),
            reply_timeout_s=p.positive("reply_timeout_s", d.reply_timeout_s, "s"),
            max_speed=p.positive("max_speed", d.max_speed, "m/s"),
            max_force=p.positive("max_force", d.max_force, "N"),
            cache_dir=p.string("cache_dir", d.cache_dir),
            yade=p.string("yade", d.yade),
            fallback=p.string("fallback", d.fallback, choices=("none", "table", "balovnev")),
            fallback_params=dict(p.section("fallback_params").values),
            terrain_from_dem=p.boolean("terrain_from_dem", d.terrain_from_dem),
        )
        if config.material and config.material not in MATERIALS:
            p.problem(f"yade/material = {config.material} is not one of {sorted(MATERIALS)}")
        if config.bed_behind >= config.bed_length:
            p.problem(
                f"yade/bed_behind = {config.bed_behind:g} m must be less than "
                f"yade/bed_length = {config.bed_length:g} m"
            )
        if config.floor_depth >= config.bed_height:
            p.problem(
                f"yade/floor_depth = {config.floor_depth:g} m must be less than "
                f"yade/bed_height = {config.bed_height:g} m"
            )
        p.finish()
        return config

    @property
    def cache_path(self) -> Path:
        """The cache directory to use."""
        return Path(self.cache_dir) if self.cache_dir else default_cache_dir()


def rayleigh_time_step(radius: float, soil: Soil) -> float:
    """s, Rayleigh time step of a sphere of ``radius`` m (the Hertz-Mindlin stability bound)."""
    return (
        math.pi
        * radius
        * math.sqrt(soil.density / soil.shear_modulus)
        / (0.1631 * soil.poisson + 0.8766)
    )


def steps_per_exchange(step_s: float, config: LiveConfig, soil: Soil) -> tuple[int, float]:
    """DEM steps per simulation step and the DEM time step (s): the simulation's step divided
    into the fewest equal DEM steps within ``dt_safety`` of the smallest sphere's Rayleigh step.
    """
    bound = config.dt_safety * rayleigh_time_step(
        config.particle_radius * (1.0 - config.radius_fuzz), soil
    )
    count = max(1, math.ceil(step_s / bound - 1e-9))
    return count, step_s / count
