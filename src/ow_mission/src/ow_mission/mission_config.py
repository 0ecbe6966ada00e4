"""The sample-collection mission's parameters: a YAML file validated into a frozen dataclass.

The default mission is ``src/ow_mission/config/mission.yaml``; ``rosrun ow_mission mission <file>``
runs another.
Every key of the file is optional (a missing key keeps the default below); unknown keys, values of
the wrong type or out of range raise one :class:`ConfigError` naming every bad key.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ow_bringup.node_config import STACK_NODES, merge
from ow_dem_bridge.api import LIVE_MODEL_NAME, LOCAL_MODEL_NAMES
from ow_description.description import (
    DEFAULT_GROUND_Z,
    MAX_GRIND_DEPTH,
    MAX_LENGTH,
    MAX_SCOOP_DEPTH,
)
from ow_mission.errors import ConfigError
from ow_mission.fault_schedule import MISSION_STEPS, ScheduledFault, parse_schedule
from ow_runtime.names import SIM_DEM_DIGS, SIM_SCOOP_MODEL_STATE, SIM_SCOOP_MODEL_WRENCH
from ow_runtime.params import Params, suggest

#: The default mission file shipped with the workspace.
DEFAULT_MISSION_FILE: Path = Path(__file__).resolve().parents[2] / "config" / "mission.yaml"

#: m, deepest a depth of the mission may be: each is ground by the grinder and then dug out by the
#: scoop, so the services' smaller limit holds (one source: ow_description.description).
MAX_STEP_DEPTH = min(MAX_GRIND_DEPTH, MAX_SCOOP_DEPTH)

#: The simulation's terrain-force models a mission may choose (the ``bridge`` model needs a
#: bridge node the mission does not start).
TERRAIN_FORCES = (*LOCAL_MODEL_NAMES, LIVE_MODEL_NAME)
#: s (wall), the default ``step_timeout_s`` with the live DEM: a dig costs minutes of wall time.
LIVE_DEM_STEP_TIMEOUT_S = 3600.0
#: The live DEM's defaults under the mission's ``node_params`` (the user's go on top): the arm
#: services wait for each joint state up to 10 min of wall time (not 5 s), since the simulation
#: waits for the DEM: a dig's first exchange may wait for a template bed to settle (first use);
#: the scoop's model state and wrench at every physics step (100 Hz, not 10 Hz: each a DEM
#: exchange while the scoop digs).
LIVE_DEM_NODE_PARAMS: dict[str, dict[str, Any]] = {
    "arm_services": {"execution": {"joint_state_timeout_s": 600.0}},
    "sim": {"tool_state_rate_hz": 100.0},
}
#: What a live-DEM mission records besides the others' topics, for the report's live forces
#: (:mod:`ow_mission.live_dem_report`): the scoop's model states and wrenches, each DEM dig.
LIVE_DEM_RECORD_TOPICS: tuple[str, ...] = (
    SIM_SCOOP_MODEL_STATE,
    SIM_SCOOP_MODEL_WRENCH,
    SIM_DEM_DIGS,
)

#: How the mission is started.
#: The command-line flag that makes the mission wait for its figures (``make demo``).
WAIT_FIGURES = "--wait-figures"
USAGE = (
    f"usage: rosrun ow_mission mission [mission.yaml] [{WAIT_FIGURES}]   "
    f"(default: {DEFAULT_MISSION_FILE}; {WAIT_FIGURES}: exit once the report's figures, made "
    "after the mission, are drawn)"
)


#: The choices of a mission's ``figures`` key (:class:`MissionConfig`).
FIGURES_MODES = ("after_exit", "inline", "none")


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
        trench_depth: m, depth of the first grind (the paper: 10 cm of radiation-processed ice);
            0: no first trench (no first grind, spoil dig or discard: the sample is ground and
            dug from the surface).
        trench_length: m, length of the trench.
        parallel: trench radial (True) or perpendicular to the arm (False).
        bottom_grind_depth: m, depth of the second grind below the trench bottom.
        dig: "linear" or "circular", how the scoop collects spoil and sample.
        dig_length: m, length of a linear dig.
        discard: (3,) m, where the spoil is dumped (a remote part of the workspace).
        terrain_forces: terrain-force model in the simulation ("none", "table", "balovnev",
            or "yade": the live DEM for the scoop's digs, the table for the rest; docs/dem.md).
        real_time_factor: 0 runs as fast as possible, 1 paces to the wall clock.
        step_timeout_s: s of wall time one service call may take (default 300 s; with
            ``terrain_forces: yade`` :data:`LIVE_DEM_STEP_TIMEOUT_S`, and ``node_params`` gets
            :data:`LIVE_DEM_NODE_PARAMS` under the file's own).
        output_dir: where ``<timestamp>/`` run directories go (relative to the workspace).
        renders: take headless renders of the arm at key moments.
        figures: "after_exit": the report's numbers are written before the mission exits and
            its figures by a process of their own afterwards (:mod:`ow_mission.figures`);
            "inline": all of the report before it exits; "none": the numbers only, the
            figures drawn when asked for (``python -m ow_mission.figures RUN_DIR``), as a
            campaign's missions do.
        node_params: extra private parameters per node name (sim, arm_services, power, record).
        interface: "services" (the paper's) or "actions" (OceanWATERS' owl_msgs actions,
            :mod:`ow_mission.action_steps`): how the steps are called.
        faults: fault parameter changes at a step or a simulation time
            (:mod:`ow_mission.fault_schedule`), applied through the ``/faults`` server.
    """

    name: str = "sample collection"
    terrain: str = "europa:7"
    seed: int = 7
    x: float = 1.65
    y: float = 0.0
    expected_ground: float = DEFAULT_GROUND_Z
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
    figures: str = "after_exit"
    node_params: dict[str, dict[str, Any]] = field(default_factory=dict)
    interface: str = "services"
    faults: tuple[ScheduledFault, ...] = ()

    @classmethod
    def from_dict(cls, raw: Mapping[str, Any]) -> MissionConfig:
        """Validate a mission mapping (the YAML file's content).

        Every problem is collected and reported at once; a misspelt key gets the nearest known
        key as a suggestion.

        Raises:
            ConfigError: unknown keys, wrong types or values out of range; the message names
                each key.
        """
        if not isinstance(raw, Mapping):
            msg = f"a mission file must hold a mapping of keys, got {type(raw).__name__}"
            raise ConfigError(msg)
        d = cls()
        p = Params(raw, "mission", ConfigError)
        seed = p.integer("seed", d.seed, low=0)
        discard = p.raw("discard", list(d.discard))
        if not isinstance(discard, list | tuple) or len(discard) != 3:
            p.problem(f"mission/discard must be three numbers (m), got {discard!r}")
            discard = d.discard
        discard = tuple(
            p.check_number(v, f"mission/discard[{i}]", d.discard[i], unit="m")
            for i, v in enumerate(discard)
        )
        node_params = p.raw("node_params", {})
        if not isinstance(node_params, Mapping) or not all(
            isinstance(v, Mapping) for v in node_params.values()
        ):
            p.problem("mission/node_params must map node names to parameter mappings")
            node_params = {}
        nodes = [n.executable for n in STACK_NODES]
        for node in node_params:
            if node not in nodes:
                p.problem(
                    f"mission/node_params/{node}: no such node in the stack (nodes: "
                    f"{', '.join(nodes)}){suggest(str(node), nodes)}"
                )
        terrain_forces = p.string("terrain_forces", d.terrain_forces, choices=TERRAIN_FORCES)
        step_timeout_s = d.step_timeout_s
        if terrain_forces == LIVE_MODEL_NAME:
            step_timeout_s = LIVE_DEM_STEP_TIMEOUT_S
            node_params = merge(LIVE_DEM_NODE_PARAMS, node_params)
        config = cls(
            name=p.string("name", d.name),
            terrain=p.string("terrain", d.terrain),
            seed=seed,
            x=p.number("x", d.x, low=-3.0, high=3.0, unit="m"),
            y=p.number("y", d.y, low=-3.0, high=3.0, unit="m"),
            expected_ground=p.number(
                "expected_ground", d.expected_ground, low=-1.0, high=0.5, unit="m"
            ),
            approach_height=p.number(
                "approach_height", d.approach_height, low=0.05, high=1.0, unit="m"
            ),
            search_distance=p.number(
                "search_distance", d.search_distance, low=0.01, high=2.0, unit="m"
            ),
            trench_depth=p.number(
                "trench_depth", d.trench_depth, low=0.0, high=MAX_STEP_DEPTH, unit="m"
            ),
            trench_length=p.number(
                "trench_length", d.trench_length, low=0.01, high=MAX_LENGTH, unit="m"
            ),
            parallel=p.boolean("parallel", d.parallel),
            bottom_grind_depth=p.number(
                "bottom_grind_depth", d.bottom_grind_depth, low=0.001, high=MAX_STEP_DEPTH, unit="m"
            ),
            dig=p.string("dig", d.dig, choices=("linear", "circular")),
            dig_length=p.number("dig_length", d.dig_length, low=0.01, high=MAX_LENGTH, unit="m"),
            discard=(discard[0], discard[1], discard[2]),
            terrain_forces=terrain_forces,
            real_time_factor=p.number("real_time_factor", d.real_time_factor, low=0.0, high=100.0),
            step_timeout_s=p.number(
                "step_timeout_s", step_timeout_s, low=1.0, high=3600.0, unit="s"
            ),
            output_dir=p.string("output_dir", d.output_dir),
            renders=p.boolean("renders", d.renders),
            figures=p.string("figures", d.figures, choices=FIGURES_MODES),
            node_params={str(k): dict(v) for k, v in node_params.items()},
            interface=p.string("interface", d.interface, choices=("services", "actions")),
            faults=parse_schedule(p.raw("faults", []), MISSION_STEPS, p.problem),
        )
        p.finish()
        return config

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


def config_from_argv(argv: Sequence[str]) -> MissionConfig | None:
    """The mission a command line names (the default file when none); None when it asks for
    help. ROS remapping arguments (``a:=b``, added by rosrun and roslaunch) and
    :data:`WAIT_FIGURES` are ignored.

    Raises:
        ConfigError: more than one file, or the file fails to load (see :meth:`MissionConfig.load`).
    """
    args = [a for a in argv if ":=" not in a and a != WAIT_FIGURES]
    if args and args[0] in ("-h", "--help"):
        return None
    if len(args) > 1:
        msg = f"one mission file at most, got {len(args)}: {' '.join(args)}\n{USAGE}"
        raise ConfigError(msg)
    return MissionConfig.load(Path(args[0]) if args else DEFAULT_MISSION_FILE)
