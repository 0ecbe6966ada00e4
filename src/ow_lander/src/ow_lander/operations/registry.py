"""Every arm operation the stack plans, in one table: its name, the paper service that serves it
(if any), its fault group, its defaults, and the planner method that plans it. No ROS.

The arm services node advertises ``/arm/<name>`` for each operation with a service, the planner
(:meth:`~ow_lander.operations.planner.Operations.plan`) dispatches on the name, ``use_defaults``
reads :attr:`OperationSpec.defaults`, and the fault reaction groups requests by
:attr:`OperationSpec.group`. Adding an operation is one entry here and its planner method
(docs/arm_services.md, "Adding an operation").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

from ow_description.description import DEFAULT_GROUND_Z


@dataclass(frozen=True)
class OperationSpec:
    """One arm operation.

    Attributes:
        name: the operation's name: ``/arm/<name>`` when it has a service, the plan's name.
        service: the ``ow_msgs`` service type serving it (``"Unstow"``), or None for an
            operation that only the OceanWATERS actions plan.
        group: ``"arm"`` (a motion of the arm) or ``"task"`` (a tool operation): which of
            OceanWATERS' goal-error faults refuses it.
        planner_method: the :class:`~ow_lander.operations.planner.Operations` method
            ``(q, terrain, request) -> OperationPlan`` that plans it.
        defaults: the values ``use_defaults: true`` puts in place of the request's (m, rad;
            OceanWATERS v6.0, spec section 2.4); empty when the request has no such flag.
    """

    name: str
    service: str | None
    group: Literal["arm", "task"]
    planner_method: str
    defaults: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))


def _spec(
    name: str,
    service: str | None,
    group: Literal["arm", "task"],
    defaults: Mapping[str, Any] | None = None,
) -> OperationSpec:
    return OperationSpec(name, service, group, f"plan_{name}", MappingProxyType(defaults or {}))


#: The operations by name, paper services first in the paper's order.
OPERATIONS: Mapping[str, OperationSpec] = MappingProxyType(
    {
        spec.name: spec
        for spec in (
            _spec("unstow", "Unstow", "arm"),
            _spec("stow", "Stow", "arm"),
            _spec(
                "guarded_move",
                "GuardedMove",
                "arm",
                {
                    "x": 2.0,
                    "y": 0.0,
                    "z": 0.3,
                    "direction_x": 0.0,
                    "direction_y": 0.0,
                    "direction_z": 1.0,
                    "search_distance": 0.5,
                },
            ),
            _spec(
                "grind",
                "Grind",
                "task",
                {
                    "x": 1.65,
                    "y": 0.0,
                    "depth": 0.05,
                    "length": 0.6,
                    "parallel": True,
                    "ground_position": DEFAULT_GROUND_Z,
                },
            ),
            _spec(
                "dig_circular",
                "DigCircular",
                "task",
                {
                    "x": 1.65,
                    "y": 0.0,
                    "depth": 0.01,
                    "parallel": True,
                    "ground_position": DEFAULT_GROUND_Z,
                },
            ),
            _spec(
                "dig_linear",
                "DigLinear",
                "task",
                {
                    "x": 1.46,
                    "y": 0.0,
                    "depth": 0.01,
                    "length": 0.1,
                    "ground_position": DEFAULT_GROUND_Z,
                },
            ),
            _spec("deliver_sample", "DeliverSample", "task"),
            _spec("discard", None, "task"),
            _spec("move_joints", None, "arm"),
            _spec("move_cartesian", None, "arm"),
        )
    }
)
#: The operations with a paper service, in the paper's order.
SERVICE_OPERATIONS: tuple[OperationSpec, ...] = tuple(
    spec for spec in OPERATIONS.values() if spec.service is not None
)
