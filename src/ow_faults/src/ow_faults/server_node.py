"""A dynamic_reconfigure server that refuses bad changes (rospy wiring only)."""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from typing import Any

import rospy
from dynamic_reconfigure.server import Server

from ow_faults.errors import OwFaultsError

#: ``check(changes)`` raises an error naming the bad value to refuse a change.
Check = Callable[[Mapping[str, Any]], None]
#: ``apply(config, changed)`` carries out an accepted change (``changed``: the names whose
#: values changed); it may raise to refuse it after all.
Apply = Callable[[Mapping[str, Any], list[str]], None]


class CheckedServer(Server):
    """dynamic_reconfigure's Python server, refusing a bad change where the stock one clamps it.

    A change naming an unknown parameter, of the wrong type, outside the parameter's range or
    refused by ``check`` or ``apply`` raises an error whose message names the value and the
    limit: the ``set_parameters`` call fails with it (``dynparam set`` prints it, the Python
    client raises it as ``rospy.ServiceException``), the change is logged as refused, and the
    configuration stays as it was.

    Args:
        config_type: the generated ``<Name>Config`` class.
        check: extra checks of a change (besides names, types and ranges).
        apply: carries out an accepted change (not called for the initial configuration).
        namespace: the server's namespace (default ``~``).
        label: how log messages name the server.
    """

    def __init__(
        self, config_type: Any, check: Check, apply: Apply, namespace: str = "", label: str = ""
    ) -> None:
        self._check_change = check
        self._apply = apply
        self._label = label or namespace or rospy.get_name()
        self._changes = threading.Lock()
        super().__init__(config_type, self._on_change, namespace)

    def update_configuration(self, changes: dict[str, Any]) -> Any:
        """Check ``changes`` then apply them.

        Raises:
            OwFaultsError: a bad change (the configuration is unchanged).
        """
        with self._changes:
            try:
                self._check(changes)
                return super().update_configuration(changes)
            except Exception as error:
                rospy.logerr(f"{self._label}: change refused: {error}")
                raise

    def _check(self, changes: Mapping[str, Any]) -> None:
        self._check_change(changes)
        config_type = self.type
        for name, value in changes.items():
            if name == "groups":
                continue
            if name not in config_type.defaults:
                known = ", ".join(config_type.defaults)
                msg = f"unknown parameter {name!r}; known: {known}"
                raise OwFaultsError(msg)
            low, high = config_type.min[name], config_type.max[name]
            number = isinstance(value, int | float) and not isinstance(value, bool)
            if number and low != "" and not low <= value <= high:
                msg = f"{name} = {value!r} is outside [{low:g}, {high:g}]"
                raise OwFaultsError(msg)

    def _on_change(self, config: Any, level: int) -> Any:
        if level != ~0:
            old = self.config
            changed = [n for n in self.type.defaults if config[n] != old[n]]
            self._apply(config, changed)
            for name in changed:
                rospy.loginfo(f"{self._label}: {name} = {config[name]!r} (was {old[name]!r})")
        return config
