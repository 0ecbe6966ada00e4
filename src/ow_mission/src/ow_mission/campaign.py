"""Monte-Carlo campaigns: a campaign file validated, and its N mission files sampled (no ROS).

A campaign is a base mission file, overrides for all its missions, and randomized mission keys
(ranges for numbers, choices with probabilities for the rest). Mission ``k`` draws its values
from ``numpy.random.SeedSequence(seed, spawn_key=(k,))``: the child ``k`` of the campaign seed,
so it is the same whether it is sampled alone (:func:`sample_mission`) or with the others, and
whatever ``missions`` is. Every sampled mission is validated by
:meth:`ow_mission.mission_config.MissionConfig.from_dict`, and so is every bound of every range
and every choice, before anything starts. ``rosrun ow_mission campaign`` runs them
(:mod:`ow_mission.campaign_run`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ow_mission.errors import ConfigError
from ow_mission.mission_config import DEFAULT_MISSION_FILE, MissionConfig
from ow_runtime.errors import ConfigError as AnyConfigError
from ow_runtime.params import Params, suggest

#: Mission keys that may be drawn from a range [low, high] (uniform).
RANGE_KEYS = (
    "x",
    "y",
    "expected_ground",
    "approach_height",
    "search_distance",
    "trench_depth",
    "trench_length",
    "bottom_grind_depth",
    "dig_length",
)
#: Mission keys that may be drawn from a set of choices.
CHOICE_KEYS = ("dig", "parallel", "terrain", "terrain_forces", "interface")
#: Mission keys the campaign sets itself for each mission. ``figures`` is the campaign's own
#: ``figures`` (:data:`CAMPAIGN_FIGURES`), never "after_exit": a mission's run is complete when
#: its process exits, so a worker (a Ray task) that moves on, or a node taken down after it,
#: leaves no figures half drawn.
DERIVED_KEYS = ("seed", "name", "output_dir", "figures")
#: What a campaign's missions do with their figures: "none" (the default) writes the report's
#: numbers only, and ``python -m ow_mission.figures RUN_DIR`` draws a mission's figures from its
#: bags when someone wants them; "inline" draws them in every mission (4-5 CPU-s for a small
#: mission without renders; campaigns ran ~6 % more missions an hour without them).
CAMPAIGN_FIGURES = ("none", "inline")
#: Decimal places kept of a drawn number (mission files stay readable; 1 um).
DIGITS = 6
#: Campaign engines.
ENGINES = ("local", "ray")
#: How the campaign is started.
USAGE = "usage: rosrun ow_mission campaign <campaign.yaml | campaign directory> [--missions 0,2-4]"


@dataclass(frozen=True)
class Randomized:
    """One randomized mission key.

    Attributes:
        key: the mission key.
        low: lower bound of a range (None for choices).
        high: upper bound of a range.
        choices: the values of a choice key, in the file's order.
        probabilities: the probability of each choice (they sum to 1).
    """

    key: str
    low: float | None = None
    high: float | None = None
    choices: tuple[Any, ...] = ()
    probabilities: tuple[float, ...] = ()

    def draw(self, rng: np.random.Generator) -> Any:
        """One value (a number rounded to :data:`DIGITS` places, or one of the choices)."""
        if self.low is not None and self.high is not None:
            return round(float(rng.uniform(self.low, self.high)), DIGITS)
        return self.choices[int(rng.choice(len(self.choices), p=self.probabilities))]


@dataclass(frozen=True)
class RandomFault:
    """One candidate entry of a mission's fault schedule (``ow_mission.fault_schedule``).

    Attributes:
        probability: chance that a mission gets it, in [0, 1].
        entry: the schedule entry (``at_step``/``after_s`` or ``at_time_s``, ``set``).
        ranges: entry time keys drawn uniformly from [low, high] (``after_s``, ``at_time_s``).
    """

    probability: float
    entry: dict[str, Any]
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)

    def draw(self, rng: np.random.Generator) -> dict[str, Any] | None:
        """The entry with its times drawn, or None when this mission does not get it (the
        same number of draws either way, so later draws do not depend on the outcome)."""
        included = rng.random() < self.probability
        times = {
            k: round(float(rng.uniform(lo, hi)), DIGITS) for k, (lo, hi) in self.ranges.items()
        }
        return {**self.entry, **times} if included else None


@dataclass(frozen=True)
class CampaignConfig:
    """A campaign file (see ``docs/campaigns.md``).

    Attributes:
        name: label of the campaign (mission names are ``<name> #<k>``).
        seed: campaign seed; mission k's seed is SeedSequence(seed, spawn_key=(k,)).
        missions: N, how many missions.
        base: the base mission file (absolute).
        mission: overrides of the base mission's keys, for every mission.
        randomize: the randomized keys, in key order.
        directory: the campaign directory (absolute).
        engine: "local" (subprocesses on this machine) or "ray".
        workers: missions at once on the local engine (0: one per core); with a local Ray
            instance, its CPUs.
        address: Ray address: "local" (start one here), "auto", "ray://host:10001", "host:port".
        cpus_per_mission: Ray CPUs one mission reserves.
        timeout_s: s of wall time one mission may take before it is stopped and failed.
        figures: each mission's ``figures`` (:data:`CAMPAIGN_FIGURES`).
        base_mission: the base file's mapping with the overrides on top.
        faults: candidate fault-schedule entries, each added to a mission with its probability.
    """

    name: str = "campaign"
    seed: int = 0
    missions: int = 10
    base: Path = DEFAULT_MISSION_FILE
    mission: dict[str, Any] = field(default_factory=dict)
    randomize: tuple[Randomized, ...] = ()
    directory: Path = Path("campaigns/campaign")
    engine: str = "local"
    workers: int = 0
    address: str = "local"
    cpus_per_mission: float = 1.0
    timeout_s: float = 1800.0
    figures: str = "none"
    base_mission: dict[str, Any] = field(default_factory=dict)
    faults: tuple[RandomFault, ...] = ()

    @classmethod
    def from_dict(
        cls, raw: Mapping[str, Any], here: Path, default_directory: Path
    ) -> CampaignConfig:
        """Validate a campaign mapping; every problem is reported at once.

        Args:
            raw: the campaign file's content.
            here: directory relative ``base`` paths are taken from (the campaign file's).
            default_directory: the campaign directory when the file gives none.

        Raises:
            ConfigError: naming each unknown key, bad value, range or probability.
        """
        if not isinstance(raw, Mapping):
            msg = f"a campaign file must hold a mapping of keys, got {type(raw).__name__}"
            raise ConfigError(msg)
        d = cls()
        p = Params(raw, "campaign", ConfigError)
        base = Path(p.string("base", str(DEFAULT_MISSION_FILE))).expanduser()
        base = base if base.is_absolute() else (here / base).resolve()
        base_raw = _read_yaml(base, "base mission", p) if p.has("base") else _default_base()
        overrides = p.raw("mission", {})
        if not isinstance(overrides, Mapping):
            p.problem(f"campaign/mission must map mission keys to values, got {overrides!r}")
            overrides = {}
        for key in overrides:
            if key in DERIVED_KEYS:
                p.problem(f"campaign/mission/{key}: set by the campaign for each mission")
        base_mission = {**base_raw, **overrides}
        # Randomized values are checked on the base mission when it is valid, else alone.
        checked_on = base_mission if _check_mission(base_mission, "campaign/mission", p) else {}
        directory = Path(p.string("directory", str(default_directory))).expanduser()
        workers = p.integer("workers", d.workers, low=0, high=4096)
        config = cls(
            name=p.string("name", d.name),
            seed=p.integer("seed", d.seed, low=0, high=2**63 - 1),
            missions=p.integer("missions", d.missions, low=1, high=1_000_000),
            base=base,
            mission=dict(overrides),
            randomize=_randomized(p.section("randomize"), checked_on),
            faults=_random_faults(p.raw("faults", []), checked_on, p),
            directory=directory.resolve(),
            engine=p.string("engine", d.engine, choices=ENGINES),
            workers=workers,
            address=p.string("address", d.address),
            cpus_per_mission=p.number("cpus_per_mission", 1.0, low=0.0, low_inclusive=False),
            timeout_s=p.number("timeout_s", d.timeout_s, low=1.0, high=86400.0, unit="s"),
            figures=p.string("figures", d.figures, choices=CAMPAIGN_FIGURES),
            base_mission=base_mission,
        )
        if config.engine == "ray":
            _check_address(config.address, p)
        p.finish()
        return config

    @classmethod
    def load(cls, path: Path) -> CampaignConfig:
        """Read a campaign file, or the ``campaign.yaml`` of a campaign directory.

        The directory is the file's ``directory`` key, else ``campaigns/<file stem>`` below
        the working directory; a campaign directory's own file names that directory.

        Raises:
            ConfigError: the file is missing, is not YAML, or fails validation.
        """
        path = Path(path)
        if path.is_dir():
            path = path / "campaign.yaml"
        probe = Params({}, "campaign", ConfigError)
        raw = _read_yaml(path, "campaign file", probe)
        if probe.problems:
            raise ConfigError(probe.problems[0])
        default = Path("campaigns") / path.stem
        return cls.from_dict(raw, path.resolve().parent, default)

    def mission_seed(self, k: int) -> int:
        """Mission k's seed (the mission file's ``seed``): 31 bits of the campaign seed's
        child k."""
        state = np.random.SeedSequence(self.seed, spawn_key=(k,)).generate_state(1)[0]
        return int(state) & 0x7FFFFFFF

    def mission_dir(self, k: int) -> Path:
        """Where mission k's file, log and run directory go."""
        return self.directory / "missions" / mission_label(k, self.missions)


def mission_label(k: int, n: int) -> str:
    """``007``: mission k's zero-padded number (at least three digits)."""
    return f"{k:0{max(3, len(str(n - 1)))}d}"


def sample_mission(config: CampaignConfig, k: int) -> dict[str, Any]:
    """Mission k's mapping: the base with the overrides, the drawn values, its seed, name and
    output directory. The same for k whatever else is sampled.

    Raises:
        ConfigError: k outside [0, missions), or the mission fails validation (named by k).
    """
    if not 0 <= k < config.missions:
        msg = f"mission {k} is outside [0, {config.missions - 1}] (campaign/missions)"
        raise ConfigError(msg)
    rng = np.random.default_rng(np.random.SeedSequence(config.seed, spawn_key=(k,)))
    drawn: dict[str, Any] = {r.key: r.draw(rng) for r in config.randomize}
    # Drawn after the keys: a campaign without faults samples the same missions.
    chosen = [f.draw(rng) for f in config.faults]
    if config.faults:
        drawn["faults"] = list(config.base_mission.get("faults") or []) + [
            entry for entry in chosen if entry is not None
        ]
    mission = {
        **config.base_mission,
        **drawn,
        "seed": config.mission_seed(k),
        "name": f"{config.name} #{mission_label(k, config.missions)}",
        "output_dir": str(config.mission_dir(k)),
        "figures": config.figures,
    }
    try:
        MissionConfig.from_dict(mission)
    except AnyConfigError as exc:
        msg = f"mission {k} of the campaign is not valid: {exc}"
        raise ConfigError(msg) from exc
    return mission


def mission_yaml(mission: Mapping[str, Any]) -> str:
    """A sampled mission as its file's text (keys in the mission file's order)."""
    order = list(MissionConfig.__dataclass_fields__)
    ordered = {k: mission[k] for k in sorted(mission, key=_order_key(order))}
    return yaml.safe_dump(ordered, sort_keys=False, default_flow_style=None)


def parse_selection(text: str, n: int) -> list[int]:
    """``"0,2-4"`` as the mission numbers [0, 2, 3, 4]; each within [0, n).

    Raises:
        ConfigError: a malformed item or a number outside the campaign.
    """
    chosen: set[int] = set()
    for item in text.split(","):
        match = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", item)
        if match is None:
            msg = f"--missions: {item!r} is not a number or a range a-b"
            raise ConfigError(msg)
        low = int(match.group(1))
        high = int(match.group(2) or low)
        if not 0 <= low <= high < n:
            msg = f"--missions: {item.strip()} is outside [0, {n - 1}] (campaign/missions = {n})"
            raise ConfigError(msg)
        chosen.update(range(low, high + 1))
    return sorted(chosen)


# ------------------------------------------------------------------------------------ helpers
def _order_key(order: Sequence[str]) -> Any:
    return lambda key: (order.index(key) if key in order else len(order), key)


def _default_base() -> dict[str, Any]:
    return dict(yaml.safe_load(DEFAULT_MISSION_FILE.read_text()) or {})


def _read_yaml(path: Path, what: str, p: Params) -> dict[str, Any]:
    try:
        raw = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        p.problem(f"cannot read {what} {path}: {exc.strerror}")
        return {}
    except yaml.YAMLError as exc:
        p.problem(f"{what} {path} is not valid YAML: {exc}")
        return {}
    if raw is not None and not isinstance(raw, Mapping):
        p.problem(f"{what} {path} must hold a mapping of keys, got {type(raw).__name__}")
        return {}
    return dict(raw or {})


def _check_mission(mission: Mapping[str, Any], where: str, p: Params) -> bool:
    """Validate a mission mapping with the mission's own rules; record a problem named by
    ``where`` for each of its problems. True when valid."""
    try:
        MissionConfig.from_dict(mission)
    except AnyConfigError as exc:
        lines = [ln.strip().removeprefix("- ") for ln in str(exc).splitlines()]
        for line in lines[1:] or lines:
            p.problem(f"{where}: {line}")
        return False
    return True


def _randomized(p: Params, base: Mapping[str, Any]) -> tuple[Randomized, ...]:
    """The ``randomize`` section: each key's range or choices, each value checked by the
    mission's validation."""
    keys = (*RANGE_KEYS, *CHOICE_KEYS)
    found: list[Randomized] = []
    for key in sorted(p.values, key=str):
        name = p.name(str(key))
        spec = p.raw(key)
        if key in DERIVED_KEYS:
            p.problem(f"{name}: set by the campaign for each mission (seed: from campaign/seed)")
            continue
        if key not in keys:
            p.problem(
                f"{name}: not a key a campaign can randomize (ranges: {', '.join(RANGE_KEYS)}; "
                f"choices: {', '.join(CHOICE_KEYS)}){suggest(str(key), keys)}"
            )
            continue
        item = _range(name, key, spec, p) if key in RANGE_KEYS else _choices(name, key, spec, p)
        if item is None:
            continue
        values = [item.low, item.high] if item.low is not None else list(item.choices)
        if all(_check_mission({**base, key: v}, f"{name} = {v!r}", p) for v in values):
            found.append(item)
    return tuple(found)


def _range(name: str, key: str, spec: Any, p: Params) -> Randomized | None:
    ok = isinstance(spec, list | tuple) and len(spec) == 2
    if not ok or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in spec):
        p.problem(f"{name} must be a range [low, high] of two numbers, got {spec!r}")
        return None
    low, high = float(spec[0]), float(spec[1])
    if not (math.isfinite(low) and math.isfinite(high) and low <= high):
        p.problem(f"{name} = [{low:g}, {high:g}] must be finite with low <= high")
        return None
    return Randomized(key, low=low, high=high)


def _choices(name: str, key: str, spec: Any, p: Params) -> Randomized | None:
    if isinstance(spec, list | tuple) and spec:
        return Randomized(key, choices=tuple(spec), probabilities=(1.0 / len(spec),) * len(spec))
    if not isinstance(spec, Mapping) or not spec:
        p.problem(
            f"{name} must be a list of choices or a mapping of choices to probabilities, "
            f"got {spec!r}"
        )
        return None
    before = len(p.problems)
    probabilities = [
        p.check_number(value, f"{name}/{choice}", 0.0, low=0.0, high=1.0)
        for choice, value in spec.items()
    ]
    if len(p.problems) > before:
        return None
    total = sum(probabilities)
    if not math.isclose(total, 1.0, abs_tol=1e-9):
        p.problem(f"{name}: the probabilities sum to {total:g}, not 1")
        return None
    return Randomized(key, choices=tuple(spec), probabilities=tuple(probabilities))


def _random_faults(raw: Any, base: Mapping[str, Any], p: Params) -> tuple[RandomFault, ...]:
    """The ``faults`` list: each entry a mission fault-schedule entry plus its ``probability``;
    ``after_s`` / ``at_time_s`` may be ranges. Each is checked by the mission's own schedule
    validation with both ends of its ranges."""
    if not isinstance(raw, list):
        p.problem(f"campaign/faults must be a list of schedule entries, got {raw!r}")
        return ()
    found = []
    for i, item in enumerate(raw):
        name = f"campaign/faults[{i}]"
        if not isinstance(item, Mapping) or "probability" not in item:
            p.problem(f"{name} must be a mapping with a probability and a schedule entry")
            continue
        before = len(p.problems)
        probability = p.check_number(
            item["probability"], f"{name}/probability", 0.0, low=0.0, high=1.0
        )
        if len(p.problems) > before:
            continue
        entry = {k: v for k, v in item.items() if k != "probability"}
        ranges = {}
        for key in ("after_s", "at_time_s"):
            spec = entry.get(key)
            if isinstance(spec, list | tuple):
                window = _range(f"{name}/{key}", key, spec, p)
                if window is None or window.low is None or window.high is None:
                    continue
                ranges[key] = (window.low, window.high)
        ends = [{**entry, **{k: v[end] for k, v in ranges.items()}} for end in (0, 1)]
        if all(_check_mission({**base, "faults": [e]}, name, p) for e in ends):
            found.append(RandomFault(probability, ends[0], ranges))
    return tuple(found)


def _check_address(address: str, p: Params) -> None:
    """The Ray address's form (whether it answers is checked when the campaign connects)."""
    if address in ("local", "auto"):
        return
    host_port = address.removeprefix("ray://")
    match = re.fullmatch(r"([A-Za-z0-9_.\-]+|\[[0-9a-fA-F:]+\]):(\d{1,5})", host_port)
    if match is None or not 0 < int(match.group(2)) < 65536:
        p.problem(
            f"campaign/address = {address!r} is not local, auto, ray://<host>:<port> or "
            "<host>:<port>"
        )
