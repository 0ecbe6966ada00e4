"""``ow_lander.constants``: the names OceanWATERS' clients import, with this stack's values taken
from where the stack keeps each fact (no ROS)."""

from __future__ import annotations

import subprocess
import sys

from ow_description import description
from ow_lander import constants
from ow_lander.mast import pan_tilt


def test_the_clients_names_are_there_with_the_stacks_values():
    assert constants.DEFAULT_GROUND_HEIGHT == description.DEFAULT_GROUND_Z
    assert constants.DEFAULT_PLANNING_FRAME == description.BASE_FRAME == "base_link"
    assert constants.FRAME_ID_MAP == pan_tilt.FRAMES
    assert constants.FRAME_ID_MAP == {0: "base_link", 1: description.SCOOP_TIP_FRAME}


def test_the_default_ground_is_the_papers_not_heads():
    # OceanWATERS at HEAD says -0.172 m; the stack's default terrain has its ground at -0.155 m.
    assert constants.DEFAULT_GROUND_HEIGHT == -0.155


def test_a_client_changing_the_frame_map_does_not_change_the_stacks():
    frames = constants.FRAME_ID_MAP
    frames[2] = "l_grinder_tip"
    try:
        assert 2 not in pan_tilt.FRAMES
    finally:
        del frames[2]


def test_the_module_imports_without_ros():
    code = (
        "import sys; from ow_lander import constants; "
        "assert 'rospy' not in sys.modules, sorted(m for m in sys.modules if 'ros' in m)"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
