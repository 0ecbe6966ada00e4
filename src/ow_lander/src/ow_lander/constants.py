"""OceanWATERS' ``ow_lander.constants`` names that its clients use, for those clients. No ROS.

OceanWATERS' test scripts and command-line tools (ow_sim_tests, ow_lander/scripts at HEAD) do
``from ow_lander import constants`` and read :data:`DEFAULT_GROUND_HEIGHT` and
:data:`FRAME_ID_MAP`. This module mirrors those names so that such clients run unchanged against
this stack; each value is taken from the one place the stack keeps that fact. The stack's own
code imports from those places, never from here.

:data:`DEFAULT_GROUND_HEIGHT` is this stack's default ground, -0.155 m in base_link: the paper
era's value (OceanWATERS v6.0) and the height of the simulation's default flat terrain.
OceanWATERS at HEAD (2024) says -0.172 m there, the mean of ArmFindSurface results in front of
the lander on two of its terrains. A client reading the name gets the ground this stack
simulates; a stack started on HEAD's ground (``terrain:=flat:-0.172``) has its ground 17 mm
below the name's value.
"""

from __future__ import annotations

from ow_description.description import BASE_FRAME, DEFAULT_GROUND_Z
from ow_lander.mast.pan_tilt import FRAMES

#: m, z of the default ground in base_link (see the module docstring: HEAD's is -0.172).
DEFAULT_GROUND_HEIGHT: float = DEFAULT_GROUND_Z
#: The frame goals are planned in when ``frame`` is 0.
DEFAULT_PLANNING_FRAME: str = BASE_FRAME
#: The ``frame`` values of the owl_msgs goals: 0 base_link, 1 the tool frame l_scoop_tip.
FRAME_ID_MAP: dict[int, str] = dict(FRAMES)
