"""Messages of the ``/faults`` server to :class:`~ow_faults.injection.FaultSet` (no rospy)."""

from __future__ import annotations

from typing import Any

from ow_faults.injection import PARAMETERS, FaultSet


def config_values(msg: Any) -> dict[str, Any]:
    """parameter -> value of a dynamic_reconfigure/Config message (every typed list)."""
    return {kv.name: kv.value for kv in (*msg.bools, *msg.ints, *msg.strs, *msg.doubles)}


def faults_from_msg(msg: Any) -> FaultSet:
    """The fault set a dynamic_reconfigure/Config of the ``/faults`` server carries;
    parameters that are not fault parameters (none from our server) are left out.

    Raises:
        FaultError: a value of the wrong type or out of range.
    """
    values = config_values(msg)
    return FaultSet.from_dict({n: v for n, v in values.items() if n in PARAMETERS})
