"""One configuration path: the private parameters of each node of the stack, read from the same
YAML files the launch files load, with a caller's overrides on top.

The launch files and the mission start identically configured stacks because both take the
parameters from here, in the same namespaces:

======================  ===================================  ======================================
node (executable)       files (package ``config/``)          part loaded as the node's private ns
======================  ===================================  ======================================
``sim``                 ``ow_sim_bullet``: sim.yaml, pid.yaml  the whole of both files
``arm_services``        ``ow_lander``: arm_services.yaml     its ``arm_services:`` section
``power``               ``ow_power``: power.yaml             its ``power:`` section
``battery``             ``ow_power``: power.yaml             its ``battery:`` section
``record``              ``ow_power``: power.yaml             its ``record:`` section
``viz``                 ``ow_viz``: viz.yaml                 the whole file
``telemetry``           ``ow_lander``: telemetry.yaml        its ``telemetry:`` section
``camera``              ``ow_cameras``: camera.yaml          the whole file
``faults``              ``ow_faults``: faults.yaml           its ``faults:`` section
``detector``            (none: it has no parameters)
======================  ===================================  ======================================
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ow_bringup.errors import ConfigError
from ow_cameras.config import CONFIG_FILE as CAMERA_YAML
from ow_faults.injection import PROFILE_DIR as FAULTS_CONFIG_DIR
from ow_lander.config import CONFIG_FILE as ARM_SERVICES_YAML
from ow_lander.telemetry.config import CONFIG_FILE as TELEMETRY_YAML
from ow_power.config import CONFIG_FILE as POWER_YAML
from ow_sim_bullet.config import PID_YAML, SIM_YAML
from ow_viz.config import CONFIG_FILE as VIZ_YAML

#: The faults server's launch-time parameters (``ow_faults/config/faults.yaml``).
FAULTS_YAML = FAULTS_CONFIG_DIR / "faults.yaml"
#: Parameter of the ``monitors`` node asking it to serve ``/faults`` (the ``faults`` node as one
#: of its components, with that node's parameters in its ``~faults``).
SERVE_FAULTS = "serve_faults"
#: Parameter of the ``monitors`` node asking it to serve OceanWATERS' ``DockIngestSample`` (as
#: the ``pan_tilt`` node does in ``lander.launch``; the mission's stack has no ``pan_tilt``).
SERVE_DOCK_INGEST = "serve_dock_ingest"


@dataclass(frozen=True)
class NodeFiles:
    """Where a node's parameters come from.

    Attributes:
        package: the catkin package of the executable.
        executable: the ``rosrun`` executable, also the node name and private namespace.
        files: (YAML file, section) pairs merged in order; section "" takes the whole file.
    """

    package: str
    executable: str
    files: tuple[tuple[Path, str], ...]


#: The nodes of the stack, in start order.
STACK_NODES: tuple[NodeFiles, ...] = (
    NodeFiles("ow_power", "record", ((POWER_YAML, "record"),)),
    NodeFiles("ow_power", "power", ((POWER_YAML, "power"),)),
    NodeFiles("ow_power", "battery", ((POWER_YAML, "battery"),)),
    NodeFiles("ow_sim_bullet", "sim", ((SIM_YAML, ""), (PID_YAML, ""))),
    NodeFiles("ow_lander", "arm_services", ((ARM_SERVICES_YAML, "arm_services"),)),
    NodeFiles("ow_viz", "viz", ((VIZ_YAML, ""),)),
    NodeFiles("ow_lander", "telemetry", ((TELEMETRY_YAML, "telemetry"),)),
    NodeFiles("ow_cameras", "camera", ((CAMERA_YAML, ""),)),
    NodeFiles("ow_faults", "faults", ((FAULTS_YAML, "faults"),)),
    NodeFiles("ow_faults", "detector", ()),
)


def _read_yaml(path: Path) -> dict[str, Any]:
    try:
        content = yaml.safe_load(path.read_text())
    except OSError as exc:
        msg = f"cannot read node configuration {path}: {exc.strerror}"
        raise ConfigError(msg) from exc
    except yaml.YAMLError as exc:
        msg = f"node configuration {path} is not valid YAML: {exc}"
        raise ConfigError(msg) from exc
    if content is None:
        return {}
    if not isinstance(content, dict):
        msg = f"node configuration {path} must hold a mapping, got {type(content).__name__}"
        raise ConfigError(msg)
    return content


def merge(base: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``overrides`` on top; nested mappings are merged key by key (as a second
    ``rosparam load`` into the same namespace would), everything else is replaced."""
    merged = copy.deepcopy(dict(base))
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(merged.get(key), Mapping):
            merged[key] = merge(merged[key], value)
        else:
            merged[key] = copy.deepcopy(value)
    return merged


def shipped_parameters(node: NodeFiles) -> dict[str, Any]:
    """The private parameters the launch files give ``node``.

    Raises:
        ConfigError: a file is unreadable, not a mapping, or lacks its section.
    """
    params: dict[str, Any] = {}
    for path, section in node.files:
        content = _read_yaml(path)
        if section:
            if not isinstance(content.get(section), dict):
                msg = f"node configuration {path} has no {section!r} section"
                raise ConfigError(msg)
            content = content[section]
        params = merge(params, content)
    return params


def stack_parameters(
    *layers: Mapping[str, Mapping[str, Any]],
) -> dict[str, dict[str, Any]]:
    """Private parameters of every node of :data:`STACK_NODES`: the shipped YAML files, then
    each layer of overrides (node name -> parameters) in order.

    Raises:
        ConfigError: a layer names a node the stack does not have.
    """
    known = {n.executable for n in STACK_NODES}
    params = {n.executable: shipped_parameters(n) for n in STACK_NODES}
    for layer in layers:
        for node, overrides in layer.items():
            if node not in known:
                msg = f"no node {node!r} in the stack (nodes: {', '.join(sorted(known))})"
                raise ConfigError(msg)
            params[node] = merge(params[node], overrides)
    return params
