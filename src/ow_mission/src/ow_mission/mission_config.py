"""The sample-collection mission's parameters: a YAML file validated into a frozen dataclass.

The default mission is ``config/mission.yaml``; ``rosrun ow_mission mission <file>`` runs another.
Every key of the file is optional (a missing key keeps the default below); an unknown key, a value
of the wrong type or out of range raises :class:`ConfigError` naming the key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import yaml

from ow_mission.errors import ConfigError

#: The default mission file shipped with the workspace.
DEFAULT_MISSION_FILE: Path = Path(__file__).resolve().parents[2] / "config" / "mission.yaml"


def _number(raw: Mapping[str, Any], key: str, default: float, low: float, high: float) -> float:
    value = raw.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        msg = f"mission key {key!r} must be a finite number, got {value!r}"
        raise ConfigError(msg)
    if not low <= value <= high:
        msg = f"mission key {key!r} = {value} is outside [{low}, {high}]"
        raise ConfigError(msg)
    return float(value)


@dataclass(frozen=True)
class MissionConfig:
    """One run of the paper's digging procedure (section 3). Units: m, s; frame base_link.

    Attributes:
        name: label of the run in the report.
        terrain: terrain spec of the simulation (``flat:<z>``, ``europa:<seed>``, ``file:<path>``),
            or plain ``europa`` for the procedural terrain of ``seed``.
        seed: seed of the procedural terrain when ``terrain`` is plain ``europa``.
        x: m, trench start (the selected location).
        y: m.
        expected_ground: m, ground z expected at (x, y); only sets the guarded move's start height.
        approach_height: m, start of the guarded move above expected_ground.
        search_distance: m, how far the guarded move searches down.
        trench_depth: m, depth of the first grind (the paper: 10 cm of radiation-processed ice).
        trench_length: m, length of the trench.
        parallel: trench radial (True) or perpendicular to the arm (False).
        bottom_grind_depth: m, depth of the second grind below the trench bottom.
        dig: "linear" or "circular", how the scoop collects spoil and sample.
        dig_length: m, length of a linear dig.
        discard: (3,) m, where the spoil is dumped (a remote part of the workspace).
        terrain_forces: terrain-force model in the simulation ("none", "table", "balovnev").
        real_time_factor: 0 runs as fast as possible, 1 paces to the wall clock.
        step_timeout_s: s of wall time one service call may take.
        output_dir: where ``<timestamp>/`` run directories go (relative to the workspace).
        renders: take headless renders of the arm at key moments.
        node_params: extra private parameters per node name (sim, arm_services, power, record).
    """

    name: str = "sample collection"
    terrain: str = "europa:7"
    seed: int = 7
    x: float = 1.65
    y: float = 0.0
    expected_ground: float = -0.155
    approach_height: float = 0.25
    search_distance: float = 0.5
    trench_depth: float = 0.10
    trench_length: float = 0.3
    parallel: bool = True
    bottom_grind_depth: float = 0.05
    dig: str = "linear"
    dig_length: float = 0.2
    discard: tuple[float, float, float] = (1.3, 0.9, 0.4)
    terrain_forces: str = "table"
    real_time_factor: float = 0.0
    step_timeout_s: float = 300.0
    output_dir: str = "runs"
    renders: bool = True
    node_params: dict[str, dict[str, Any]] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, raw: Mapping[str, Any]) -> MissionConfig:
        """Validate a mission mapping (the YAML file's content).

        Raises:
            ConfigError: unknown key, wrong type or value out of range; the message names the key.
        """
        if not isinstance(raw, Mapping):
            msg = f"a mission file must hold a mapping of keys, got {type(raw).__name__}"
            raise ConfigError(msg)
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(raw) - known)
        if unknown:
            msg = f"unknown mission keys {unknown}; known keys: {sorted(known)}"
            raise ConfigError(msg)
        d = cls()
        for key in ("name", "terrain", "dig", "terrain_forces", "output_dir"):
            if not isinstance(raw.get(key, getattr(d, key)), str):
                msg = f"mission key {key!r} must be a string, got {raw[key]!r}"
                raise ConfigError(msg)
        for key in ("parallel", "renders"):
            if not isinstance(raw.get(key, getattr(d, key)), bool):
                msg = f"mission key {key!r} must be true or false, got {raw[key]!r}"
                raise ConfigError(msg)
        seed = raw.get("seed", d.seed)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            msg = f"mission key 'seed' must be a non-negative integer, got {seed!r}"
            raise ConfigError(msg)
        dig = raw.get("dig", d.dig)
        if dig not in ("linear", "circular"):
            msg = f"mission key 'dig' must be 'linear' or 'circular', got {dig!r}"
            raise ConfigError(msg)
        discard = raw.get("discard", list(d.discard))
        if (
            not isinstance(discard, list | tuple)
            or len(discard) != 3
            or not all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in discard
            )
        ):
            msg = f"mission key 'discard' must be three finite numbers (m), got {discard!r}"
            raise ConfigError(msg)
        node_params = raw.get("node_params", {})
        if not isinstance(node_params, Mapping) or not all(
            isinstance(v, Mapping) for v in node_params.values()
        ):
            msg = "mission key 'node_params' must map node names to parameter mappings"
            raise ConfigError(msg)
        return cls(
            name=raw.get("name", d.name),
            terrain=raw.get("terrain", d.terrain),
            seed=seed,
            x=_number(raw, "x", d.x, -3.0, 3.0),
            y=_number(raw, "y", d.y, -3.0, 3.0),
            expected_ground=_number(raw, "expected_ground", d.expected_ground, -1.0, 0.5),
            approach_height=_number(raw, "approach_height", d.approach_height, 0.05, 1.0),
            search_distance=_number(raw, "search_distance", d.search_distance, 0.01, 2.0),
            trench_depth=_number(raw, "trench_depth", d.trench_depth, 0.001, 0.3),
            trench_length=_number(raw, "trench_length", d.trench_length, 0.01, 1.0),
            parallel=raw.get("parallel", d.parallel),
            bottom_grind_depth=_number(raw, "bottom_grind_depth", d.bottom_grind_depth, 0.001, 0.3),
            dig=dig,
            dig_length=_number(raw, "dig_length", d.dig_length, 0.01, 1.0),
            discard=(float(discard[0]), float(discard[1]), float(discard[2])),
            terrain_forces=raw.get("terrain_forces", d.terrain_forces),
            real_time_factor=_number(raw, "real_time_factor", d.real_time_factor, 0.0, 100.0),
            step_timeout_s=_number(raw, "step_timeout_s", d.step_timeout_s, 1.0, 3600.0),
            output_dir=raw.get("output_dir", d.output_dir),
            renders=raw.get("renders", d.renders),
            node_params={str(k): dict(v) for k, v in node_params.items()},
        )

    @property
    def terrain_spec(self) -> str:
        """The simulation's terrain spec, with ``seed`` filled in for plain ``europa``."""
        return f"europa:{self.seed}" if self.terrain == "europa" else self.terrain

    @classmethod
    def load(cls, path: Path) -> MissionConfig:
        """Read and validate a mission YAML file.

        Raises:
            ConfigError: the file is missing, is not YAML, or fails validation.
        """
        try:
            text = Path(path).read_text()
        except OSError as exc:
            msg = f"cannot read mission file {path}: {exc.strerror}"
            raise ConfigError(msg) from exc
        try:
            raw = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            msg = f"mission file {path} is not valid YAML: {exc}"
            raise ConfigError(msg) from exc
        return cls.from_dict(raw or {})
