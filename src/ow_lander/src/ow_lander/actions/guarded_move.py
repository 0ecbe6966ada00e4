"""OceanWATERS' deprecated ``GuardedMove`` action (ow_lander, HEAD) on the paper's guarded move,
free of ROS.

OceanWATERS moves the scoop to the goal's ``start``, then ``search_distance`` along ``-normal``
until it detects the ground, and reports SUCCEEDED either way: "Ground detected" with ``success``
true and ``final`` the scoop tip's position (base_link) at contact, or "No ground detected" with
``success`` false and ``final`` zeros. Here the goal becomes the request of the
``guarded_move`` operation that ``/arm/guarded_move`` plans (:func:`guarded_move_request`), and
:func:`guarded_move_end` turns its execution into the goal's end. What differs from OceanWATERS:
the scoop *tip* (not the scoop link's origin) goes to ``start``, the search is a straight line,
and contact is detected as ``/arm/guarded_move`` detects it (``execution/ground_detector``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ow_lander.actions.outcomes import STOP_DURING_EXECUTION, Status
from ow_lander.execution.monitor import ExecutionResult

#: The action's name, as its server is advertised.
GUARDED_MOVE = "GuardedMove"
#: The operation (:class:`~ow_lander.operations.planner.Operations`) that carries it out.
OPERATION = "guarded_move"
#: OceanWATERS' status texts of the two successful ends.
GROUND_DETECTED = "Ground detected"
NO_GROUND_DETECTED = "No ground detected"
#: The start of the status text of a cancelled goal.
PREEMPTED = "Action was preempted"


def guarded_move_request(
    start: Sequence[float], normal: Sequence[float], search_distance: float
) -> dict[str, Any]:
    """The ``guarded_move`` request carrying out a GuardedMove goal (the planner checks it).

    Args:
        start: (3,) m, base_link: where the approach puts the scoop tip.
        normal: (3,) surface normal in base_link (any length): the search goes along -normal.
        search_distance: m, length of the search.
    """
    x, y, z = (float(v) for v in start)
    nx, ny, nz = (float(v) for v in normal)
    return {
        "use_defaults": False,
        "x": x,
        "y": y,
        "z": z,
        "direction_x": nx,
        "direction_y": ny,
        "direction_z": nz,
        "search_distance": float(search_distance),
    }


@dataclass(frozen=True)
class GuardedMoveEnd:
    """How a GuardedMove goal ends.

    Attributes:
        status: "succeeded", "aborted" or "preempted".
        text: the goal's status text.
        success: the result's ``success``: the ground was found.
        final: (3,) m, the result's ``final``: scoop tip in base_link at contact, else zeros.
    """

    status: Status
    text: str
    success: bool = False
    final: tuple[float, float, float] = (0.0, 0.0, 0.0)


def guarded_move_end(result: ExecutionResult, cancelled: bool) -> GuardedMoveEnd:
    """The end of a GuardedMove goal whose guarded move executed as ``result``; ``cancelled``:
    the goal's client cancelled it (a stop without a cancel came from ArmStop)."""
    if result.fault is not None:
        return GuardedMoveEnd("aborted", result.message)
    if result.stopped:
        if cancelled:
            return GuardedMoveEnd("preempted", f"{PREEMPTED}: {result.message}")
        return GuardedMoveEnd("aborted", STOP_DURING_EXECUTION)
    if result.ground_found:
        x, y, z = (float(v) for v in result.ground_position)
        return GuardedMoveEnd("succeeded", GROUND_DETECTED, True, (x, y, z))
    if result.reports_ground or result.success:  # the search ran to its end
        return GuardedMoveEnd("succeeded", NO_GROUND_DETECTED)
    return GuardedMoveEnd("aborted", result.message)
