"""The camera trigger fault without a master: the camera node's name for it is the ``/faults``
server's (OceanWATERS' cam_faults group), its topics are the ones the fault detector watches, and
a capture of a failing left camera makes the right image alone, the same right image as a
capture without the fault (the right camera is not gated, as in OceanWATERS)."""

from __future__ import annotations

import numpy as np
import pytest

from ow_cameras import protocol
from ow_cameras.capture import Shot, StereoCamera
from ow_cameras.config import CameraConfig
from ow_description.description import STOWED
from ow_description.terrain import HeightMap
from ow_faults.injection import PARAMETERS, FaultSet
from ow_runtime.names import CAMERA_ACTIONS, STEREO_LEFT_IMAGE_RAW, STEREO_LEFT_TRIGGER

#: A small capture (a quarter of the default's side): the fault's logic, not the picture.
SMALL = CameraConfig.from_dict({"width": 200, "height": 150, "stereo": {"num_disparities": 96}})
#: The mast looks back over the lander's +y side at bare ground (as the stereo test).
GROUND_VIEW = {"j_ant_pan": 3.1, "j_ant_tilt": 0.9}


def test_the_fault_is_the_faults_servers_parameter_of_the_cam_faults_group():
    parameter = PARAMETERS[protocol.LEFT_TRIGGER_FAILURE]
    assert (parameter.group, parameter.kind, parameter.default) == ("cam_faults", bool, False)
    assert FaultSet.from_dict({protocol.LEFT_TRIGGER_FAILURE: True}).camera_left_trigger_failure


def test_the_detector_watches_the_camera_nodes_topics_and_actions():
    assert (protocol.LEFT_TRIGGER, protocol.LEFT_IMAGE_RAW) == (
        STEREO_LEFT_TRIGGER,
        STEREO_LEFT_IMAGE_RAW,
    )
    assert (protocol.CAMERA_CAPTURE, protocol.CAMERA_SET_EXPOSURE) == CAMERA_ACTIONS
    assert protocol.LIGHT_SET_INTENSITY not in CAMERA_ACTIONS  # no fault group (OceanWATERS)


@pytest.fixture(scope="module")
def captures():
    """The same shot with and without the left camera's trigger failure."""
    camera = StereoCamera(SMALL)
    try:
        shots = {
            left_fails: Shot(
                {**STOWED, **GROUND_VIEW},
                1_500_000_000,
                HeightMap.flat(-0.155, half_extent=4.0, resolution=0.1),
                SMALL.exposure_s,
                {"left": 1.0, "right": 1.0},
                left_fails=left_fails,
            )
            for left_fails in (False, True)
        }
        return {left_fails: camera.capture(shot) for left_fails, shot in shots.items()}
    finally:
        camera.close()


def test_a_failing_left_trigger_gives_the_right_image_alone(captures):
    failed, nominal = captures[True], captures[False]
    assert failed.left is None and failed.cloud is None
    assert nominal.left is not None and nominal.cloud is not None
    assert failed.stamp_ns == nominal.stamp_ns == 1_500_000_000
    assert failed.right.shape == (150, 200, 3)
    assert np.array_equal(failed.right, nominal.right)
    assert np.array_equal(failed.X_base_left, nominal.X_base_left)
    assert set(failed.timings_s) == {"render"}  # nothing matched
