"""An alias of :mod:`ow_bringup.testing`, where the pytest harness lives: test suites written
with ``pytest_plugins = ["ow_mission.testing"]`` go on working unchanged."""

from ow_bringup.testing import *  # noqa: F403 (the fixtures are the plugin)
from ow_bringup.testing import __all__ as __all__
