"""The arm services through real service calls (planning only; the test feeds /joint_states)."""

import math
import threading

import numpy as np
import pytest
from sensor_msgs.msg import JointState

from ow_bringup.testing import advertise
from ow_description.description import ARM_JOINTS, DEFAULT_GROUND_Z, UNSTOWED
from ow_description.model import LanderModel
from ow_description.trajectory import read_csv
from ow_msgs.srv import (
    DeliverSample,
    DigCircular,
    DigLinear,
    Grind,
    GuardedMove,
    PublishTrajectory,
    Stow,
    Unstow,
)

UNSTOWED_STATE = {**UNSTOWED, "j_grinder": 0.0, "j_ant_pan": 0.0, "j_ant_tilt": 0.0}


@pytest.fixture(scope="module")
def stack(ros_stack, tmp_path_factory):
    directory = tmp_path_factory.mktemp("trajectories")
    publisher = advertise("/joint_states", JointState, queue_size=1)
    stop = threading.Event()

    def feed():
        while not stop.is_set():
            names = list(UNSTOWED_STATE)
            publisher.publish(JointState(name=names, position=[UNSTOWED_STATE[n] for n in names]))
            stop.wait(0.05)

    thread = threading.Thread(target=feed, daemon=True)
    thread.start()
    ros_stack.start_node(
        "ow_lander",
        "arm_services",
        params={"trajectory_dir": str(directory)},
        wait_for_services=["/arm/unstow", "/arm/publish_trajectory"],
    )
    yield ros_stack, directory
    stop.set()
    thread.join()


GOOD = [
    ("/arm/unstow", Unstow, {"delete_prev_traj": False}),
    ("/arm/stow", Stow, {"delete_prev_traj": False}),
    ("/arm/guarded_move", GuardedMove, {"use_defaults": True}),
    ("/arm/grind", Grind, {"use_defaults": True}),
    ("/arm/dig_linear", DigLinear, {"use_defaults": True}),
    ("/arm/dig_circular", DigCircular, {"use_defaults": True}),
    ("/arm/deliver_sample", DeliverSample, {"use_defaults": True}),
    (
        "/arm/grind",
        Grind,
        dict(
            x=1.7, y=0.1, depth=0.04, length=0.3, parallel=False, ground_position=DEFAULT_GROUND_Z
        ),
    ),
    (
        "/arm/dig_linear",
        DigLinear,
        dict(x=1.7, y=0.0, depth=0.02, length=0.15, ground_position=DEFAULT_GROUND_Z),
    ),
    ("/arm/deliver_sample", DeliverSample, dict(x=1.5, y=0.8, z=0.3)),
]


@pytest.mark.parametrize(
    ("name", "cls", "fields"), GOOD, ids=[g[0] + str(i) for i, g in enumerate(GOOD)]
)
def test_plan_starts_at_current_state_and_is_collision_free(stack, name, cls, fields):
    ros_stack, directory = stack
    response = ros_stack.service(name, cls)(**fields)
    assert response.success, response.message
    trajectory = read_csv(directory / response.trajectory_file.rsplit("/", 1)[1])
    assert trajectory.joints == ARM_JOINTS
    assert np.allclose(trajectory.positions[0], [UNSTOWED[j] for j in ARM_JOINTS], atol=1e-6)
    assert response.duration == pytest.approx(trajectory.duration)
    assert "flat ground" in response.message  # no /sim/terrain in this test


def test_grind_defaults_cut_at_depth_and_length(stack):
    ros_stack, directory = stack
    response = ros_stack.service("/arm/grind", Grind)(use_defaults=True)
    trajectory = read_csv(directory / response.trajectory_file.rsplit("/", 1)[1])
    model = LanderModel()
    q = model.q_from(UNSTOWED_STATE)
    rows = [i for i, s in enumerate(trajectory.segments) if s == "pass_1"]
    tips = []
    for i in rows:
        q[model.arm_idx] = trajectory.positions[i]
        tips.append(model.position(q, "l_grinder_tip"))
    tips = np.array(tips)
    assert np.allclose(tips[:, 2], DEFAULT_GROUND_Z - 0.05, atol=0.01)
    assert np.linalg.norm(tips[-1, :2] - tips[0, :2]) == pytest.approx(0.6, abs=0.01)


BAD = [
    ("/arm/grind", Grind, dict(x=float("nan"), depth=0.05, length=0.3), "x=nan"),
    ("/arm/grind", Grind, dict(x=1.6, depth=-0.01, length=0.3), "negative"),
    ("/arm/grind", Grind, dict(x=1.6, depth=0.3, length=0.3), "deeper than the grinder"),
    ("/arm/grind", Grind, dict(x=-1.0, y=0.0, depth=0.05, length=0.3), "shoulder yaw"),
    ("/arm/dig_linear", DigLinear, dict(x=1.6, depth=0.5, length=0.1), "deeper than the scoop"),
    ("/arm/dig_linear", DigLinear, dict(x=1.6, depth=0.02, length=0.0), "length"),
    ("/arm/dig_circular", DigCircular, dict(x=float("inf"), depth=0.02), "x=inf"),
    ("/arm/dig_circular", DigCircular, dict(x=1.6, depth=-0.1), "negative"),
    ("/arm/guarded_move", GuardedMove, dict(x=2.0, z=0.3, search_distance=0.5), "zero vector"),
    (
        "/arm/guarded_move",
        GuardedMove,
        dict(x=2.0, z=0.3, direction_z=1.0, search_distance=0.0),
        "search_distance",
    ),
    (
        "/arm/guarded_move",
        GuardedMove,
        dict(x=5.0, z=0.3, direction_z=1.0, search_distance=0.3),
        "reach",
    ),
    ("/arm/deliver_sample", DeliverSample, dict(x=math.nan, y=0.0, z=0.5), "x=nan"),
    ("/arm/publish_trajectory", PublishTrajectory, dict(trajectory_filename="nope.csv"), "unknown"),
    ("/arm/publish_trajectory", PublishTrajectory, dict(trajectory_filename="../x.csv"), "not in"),
]


@pytest.mark.parametrize(("name", "cls", "fields", "says"), BAD, ids=[b[3] for b in BAD])
def test_bad_input_is_refused_with_a_reason(stack, name, cls, fields, says):
    ros_stack, _ = stack
    response = ros_stack.service(name, cls)(**fields)
    assert not response.success
    assert says in response.message, response.message
    # The node keeps serving.
    assert ros_stack.service("/arm/unstow", Unstow)(delete_prev_traj=False).success


def test_delete_prev_traj_deletes_only_our_files(stack):
    ros_stack, directory = stack
    foreign = directory / "user_notes.csv"
    foreign.write_text("mine")
    response = ros_stack.service("/arm/unstow", Unstow)(delete_prev_traj=True)
    assert response.success, response.message
    remaining = sorted(p.name for p in directory.glob("*.csv"))
    assert remaining == sorted(["user_notes.csv", response.trajectory_file.rsplit("/", 1)[1]])


def test_same_request_same_plan(stack):
    ros_stack, directory = stack
    call = ros_stack.service("/arm/deliver_sample", DeliverSample)
    a, b = call(use_defaults=True), call(use_defaults=True)
    ta = read_csv(directory / a.trajectory_file.rsplit("/", 1)[1])
    tb = read_csv(directory / b.trajectory_file.rsplit("/", 1)[1])
    assert np.array_equal(ta.positions, tb.positions)
