"""The arm's and the mast's reaction to faults (issue 15, item 4) on the real nodes: the faults
server, the detector, the simulation, the arm services and the pan/tilt node on one master.

* a joint locked half-way through a grind: the arm stops, HARDWARE and ARM_EXECUTION_ERROR are
  set, the goal fails naming the joint; goals are refused while the lock stands; once it is
  released the next goal succeeds;
* a goal error with ``auto_clear_goal_errors`` false refuses goals and requests until FaultClear;
* an F/T zero signal during ArmFindSurface never gives a surface;
* a locked antenna joint fails pan/tilt goals, at once or in the middle of a move.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from actionlib_msgs.msg import GoalStatus
from dynamic_reconfigure.client import Client
from geometry_msgs.msg import Point, Vector3
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from test_actions import JointLog, client, forget_clients, run
from test_faults_injection import Latest

import owl_msgs.msg as owl
from ow_bringup.testing import action_client, set_terrain, subscribe
from ow_description.description import DEFAULT_GROUND_Z, GRINDER_TIP_FRAME
from ow_description.model import LanderModel
from ow_msgs.msg import JointStatesFlag
from ow_msgs.srv import StepSimulation, Stow, Unstow
from owl_msgs.msg import ArmFaultsStatus, PanTiltFaultsStatus, SystemFaultsStatus

GROUND = DEFAULT_GROUND_Z
#: s of simulation time within which the arm must be at rest after a joint locks (the issue).
STOP_WITHIN_S = 0.5
#: rad/s, an arm joint slower than this is at rest.
REST_SPEED = 0.01
#: s, the simulation's default physics step.
PHYSICS_STEP_S = 0.01
#: s of wall time the reacting nodes get, the clock stopped, to receive an injected fault.
REACT_WALL_S = 1.0
NO_FAULTS = {
    "shou_pitch_joint_locked_failure": False,
    "ant_pan_joint_locked_failure": False,
    "enable": False,
    "zero_signal_failure": False,
    "arm_motion_continues_in_fault": False,
    "auto_clear_goal_errors": True,
}


@pytest.fixture(scope="module")
def stack(ros_stack, start_lander):
    forget_clients()
    ros_stack.start_node("ow_faults", "faults", wait_for_services=["/faults/set_parameters"])
    ros_stack.start_node("ow_faults", "detector", wait_for_topics=["/system_faults_status"])
    start_lander(sim_topics=["/joint_states", "/arm_end_effector_force_torque"])
    ros_stack.start_node("ow_lander", "pan_tilt", wait_for_topics=["/PanTiltMoveJoints/status"])
    ros_stack.faults = Client("/faults", timeout=30)
    ros_stack.flags = Latest("/flags/joint_states", JointStatesFlag)
    ros_stack.arm = Latest("/arm_faults_status", ArmFaultsStatus)
    ros_stack.pan_tilt = Latest("/pan_tilt_faults_status", PanTiltFaultsStatus)
    ros_stack.system = Latest("/system_faults_status", SystemFaultsStatus)
    ros_stack.joints = JointLog()
    ros_stack.latest_joints = Latest("/joint_states", JointState)
    return ros_stack


def inject(stack, **changes) -> None:
    stack.faults.update_configuration(changes)


def inject_paused(stack, latest: Latest, seen, what: str, **changes):
    """Inject ``changes`` with the simulation's clock stopped, so that they take effect at the
    simulation time the test chose however loaded the machine: pause, inject, take one physics
    step (the simulation flags a locked joint with the joint states it publishes after a step),
    wait until a message of ``latest`` satisfies ``seen`` (on this test's connection; it is
    returned), then give the nodes that react to it on their own connections (arm services,
    pan/tilt) ``REACT_WALL_S`` before resuming."""
    pause, resume = stack.service("/sim/pause", Trigger), stack.service("/sim/resume", Trigger)
    assert pause().success
    try:
        inject(stack, **changes)
        assert stack.service("/sim/step", StepSimulation)(steps=1).success
        msg = latest.wait_for(seen, what)
        time.sleep(REACT_WALL_S)
    finally:
        assert resume().success
    return msg


def step_until(stack, done, what: str, chunk: int = 5, max_steps: int = 30000) -> None:
    """With the clock stopped, step the simulation ``chunk`` physics steps at a time until
    ``done()``, each time waiting until this test's /joint_states has reached the new sim time
    (the nodes under test get them as fast): the test acts at a simulation time of its choosing
    (to a few chunks) whatever the machine's load."""
    step = stack.service("/sim/step", StepSimulation)
    for _ in range(max_steps // chunk):
        response = step(steps=chunk)
        assert response.success, response.message
        reached = response.sim_time - PHYSICS_STEP_S - 1e-6  # a sample is its step's start
        latest = stack.latest_joints
        latest.wait_for(
            lambda m, t=reached: m.header.stamp.to_sec() >= t,
            f"a joint state at {reached:.3f} s (newest: {latest.msg and latest.msg.header.stamp})",
        )
        if done():
            return
    pytest.fail(f"{what} not within {max_steps} steps")


def clear_faults(stack) -> None:
    assert stack.service("/sim/resume", Trigger)().success  # if a test left it paused
    inject(stack, **NO_FAULTS)
    stack.system.wait_for(lambda m: m.value & ~_GOAL_ERRORS == 0, "no execution error")
    _arm_services_see_goal_error(False)  # and the arm services have the news too


_GOAL_ERRORS = (
    SystemFaultsStatus.ARM_GOAL_ERROR
    | SystemFaultsStatus.TASK_GOAL_ERROR
    | SystemFaultsStatus.PAN_TILT_GOAL_ERROR
)


def at_rest_after(samples, t0: float, t1: float) -> float:
    """s (sim): the end of the last motion faster than ``REST_SPEED`` between t0 and t1.
    ``samples`` may still grow (a subscriber's thread appends to it): one copy is read."""
    samples = list(samples)  # make test: t and q of two readings, 4788 against 4780 samples
    t = np.array([s for s, _ in samples])
    q = np.array([v for _, v in samples])
    keep = (t >= t0 - 0.1) & (t <= t1)
    t, q = t[keep], q[keep]
    dt = np.diff(t)
    fast = np.max(np.abs(np.diff(q, axis=0)), axis=1) > REST_SPEED * np.where(dt > 0, dt, np.inf)
    moving = np.flatnonzero(fast & (t[1:] > t0))
    return float(t[1:][moving[-1]]) if moving.size else t0


def test_lock_half_way_through_a_grind_stops_the_arm_and_fails_naming_the_joint(stack):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    grind = client("TaskGrind")
    model = LanderModel()
    in_trench = threading.Event()

    def on_joints(msg: JointState) -> None:
        q = model.q_from(dict(zip(msg.name, msg.position, strict=False)))
        if model.position(q, GRINDER_TIP_FRAME)[2] < GROUND - 0.02:
            in_trench.set()

    grind.send_goal(owl.TaskGrindGoal(1.65, 0.0, 0.05, 0.4, 1.0, GROUND))
    watch = subscribe("/joint_states", JointState, on_joints)
    try:
        assert in_trench.wait(300), "the grinder never went into the ground"
        watch.unregister()
        flag = inject_paused(
            stack,
            stack.flags,
            lambda m: any(m.flags),
            "the lock's flag",
            shou_pitch_joint_locked_failure=True,
        )
        t_lock = flag.header.stamp.to_sec()
        assert grind.wait_for_end(120), "TaskGrind did not end"
        text = grind.get_goal_status_text()
        assert grind.get_state() == GoalStatus.ABORTED, text
        assert "arm execution error: j_shou_pitch locked (HARDWARE)" in text
        arm = stack.arm.wait_for(lambda m: m.value & ArmFaultsStatus.HARDWARE, "HARDWARE")
        assert arm.value == ArmFaultsStatus.HARDWARE
        stack.system.wait_for(
            lambda m: m.value & SystemFaultsStatus.ARM_EXECUTION_ERROR, "ARM_EXECUTION_ERROR"
        )
        stack.joints.wait_sim(1.0)  # the hold, after the result
        t_end = stack.joints.samples[-1][0]
        latency = at_rest_after(stack.joints.samples, t_lock, t_end) - t_lock
        print(f"stop latency: {latency:.3f} s of simulation time")
        assert latency <= STOP_WITHIN_S

        # refused while the lock stands, goals and requests alike, naming the joint
        state, _, text = run("ArmUnstow", owl.ArmUnstowGoal())
        assert state == GoalStatus.ABORTED
        assert "j_shou_pitch locked (HARDWARE)" in text
        response = stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
        assert not response.success
        assert "j_shou_pitch locked (HARDWARE)" in response.message
    finally:
        clear_faults(stack)
    state, _, text = run("ArmUnstow", owl.ArmUnstowGoal())  # lifts the grinder out first
    assert state == GoalStatus.SUCCEEDED, text


def _arm_services_see_goal_error(standing: bool, timeout_s: float = 30.0) -> None:
    """Wait until the arm services act on the arm's fault state: a goal error (or an execution
    error) ``standing`` or not. They learn it from the detector's topics on connections of their
    own, which under load can deliver it later than this test's (as in OceanWATERS, the refusal
    follows the detector's topics). The probe is an ArmMoveJoints goal of no motion (relative,
    zeros): aborted at once naming the fault while an error stands, a success that moves
    nothing otherwise."""
    still = owl.ArmMoveJointsGoal(True, [0.0] * 6)
    deadline = time.monotonic() + timeout_s
    while True:
        state, _, text = run("ArmMoveJoints", still)
        refused = state == GoalStatus.ABORTED and ("is faulted" in text or "error" in text)
        if refused if standing else state == GoalStatus.SUCCEEDED:
            return
        assert time.monotonic() < deadline, f"arm services still answer {state} ({text})"
        time.sleep(0.05)


def test_goal_error_refuses_goals_until_fault_clear(stack):
    inject(stack, auto_clear_goal_errors=False)
    try:
        out_of_limits = owl.ArmMoveJointsGoal(False, [0.0, 3.0, 0.0, 0.0, 0.0, 0.0])
        state, _, text = run("ArmMoveJoints", out_of_limits)
        assert state == GoalStatus.ABORTED, text
        stack.system.wait_for(
            lambda m: m.value & SystemFaultsStatus.ARM_GOAL_ERROR, "ARM_GOAL_ERROR"
        )
        _arm_services_see_goal_error(True)
        state, _, text = run("ArmUnstow", owl.ArmUnstowGoal())
        assert state == GoalStatus.ABORTED
        assert text.startswith("Action group, ARM, is faulted. Use the FaultClear action")
        assert "ARM_GOAL_ERROR stands" in text
        response = stack.service("/arm/stow", Stow)(delete_prev_traj=False)
        assert not response.success and "ARM_GOAL_ERROR stands" in response.message
        clear = action_client("FaultClear", owl.FaultClearAction)
        clear.send_goal(owl.FaultClearGoal(fault=SystemFaultsStatus.ARM_GOAL_ERROR))
        assert clear.wait_for_end(30)
        assert clear.get_state() == GoalStatus.SUCCEEDED
        stack.system.wait_for(
            lambda m: not m.value & SystemFaultsStatus.ARM_GOAL_ERROR, "ARM_GOAL_ERROR cleared"
        )
        _arm_services_see_goal_error(False)
        state, _, text = run("ArmUnstow", owl.ArmUnstowGoal())
        assert state == GoalStatus.SUCCEEDED, text
    finally:
        clear_faults(stack)


@pytest.mark.parametrize("continues", [False, True])
def test_ft_zero_signal_during_find_surface_never_gives_a_surface(stack, continues):
    set_terrain(stack, f"flat:{GROUND}", lift_arm=True)
    inject(stack, arm_motion_continues_in_fault=continues)
    find = client("ArmFindSurface")
    descending: list[float] = []

    def on_feedback(fb) -> None:
        if fb.pose.position.z < GROUND + 0.12 and not descending:
            descending.append(fb.pose.position.z)

    goal = owl.ArmFindSurfaceGoal(
        frame=0, relative=False, position=Point(1.7, 0.0, GROUND), normal=Vector3(0, 0, 1),
        distance=0.2, overdrive=0.05, force_threshold=10.0, torque_threshold=10.0,
    )  # fmt: skip
    # The clock stands still but for the test's steps until the fault: the scoop is 12 cm
    # above the ground then, however loaded the machine (a free-running sim reached it first).
    assert stack.service("/sim/pause", Trigger)().success
    find.send_goal(goal, feedback_cb=on_feedback)
    try:
        step_until(stack, lambda: bool(descending), "the scoop coming down towards the surface")
        inject_paused(
            stack,
            stack.arm,
            lambda m: m.value & ArmFaultsStatus.NO_FORCE_DATA,
            "NO_FORCE_DATA",
            enable=True,
            zero_signal_failure=True,
        )
        assert find.wait_for_end(120), "ArmFindSurface did not end"
        text = find.get_goal_status_text()
        assert find.get_state() == GoalStatus.ABORTED, text
        assert "no force data from the wrist F/T sensor (NO_FORCE_DATA)" in text
        assert "ground found" not in text
        stack.arm.wait_for(lambda m: m.value & ArmFaultsStatus.NO_FORCE_DATA, "NO_FORCE_DATA")
    finally:
        clear_faults(stack)
    state, _, text = run("ArmUnstow", owl.ArmUnstowGoal())
    assert state == GoalStatus.SUCCEEDED, text


def test_locked_antenna_fails_pan_tilt_goals(stack):
    pan_tilt = client("PanTiltMoveJoints")
    state, _, text = run("PanTiltMoveJoints", owl.PanTiltMoveJointsGoal(0.0, 0.0))
    assert state == GoalStatus.SUCCEEDED, text
    try:
        # locked in the middle of a move: the mast stops, the goal fails naming the joint. The
        # clock stands still from the goal until the lock but for steps taken here: the mast
        # is half-way whatever the machine's load (a free-running sim finished the move).
        assert stack.service("/sim/pause", Trigger)().success
        pan_tilt.send_goal(owl.PanTiltMoveJointsGoal(2.5, 0.0))

        def half_way() -> bool:
            msg = stack.latest_joints.msg
            return msg.position[msg.name.index("j_ant_pan")] > 1.0

        step_until(stack, half_way, "the mast half-way")
        inject_paused(
            stack,
            stack.pan_tilt,
            lambda m: m.value & PanTiltFaultsStatus.PAN_JOINT_LOCKED,
            "PAN_JOINT_LOCKED",
            ant_pan_joint_locked_failure=True,
        )
        assert pan_tilt.wait_for_end(60)
        text = pan_tilt.get_goal_status_text()
        assert pan_tilt.get_state() == GoalStatus.ABORTED, text
        assert "j_ant_pan locked (PAN_JOINT_LOCKED)" in text
        result = pan_tilt.get_result()
        assert abs(result.pan_position) < 2.4  # stopped short of the goal
        stack.pan_tilt.wait_for(
            lambda m: m.value == PanTiltFaultsStatus.PAN_JOINT_LOCKED, "PAN_JOINT_LOCKED"
        )
        system = stack.system.wait_for(
            lambda m: m.value & SystemFaultsStatus.PAN_TILT_GOAL_ERROR, "PAN_TILT_GOAL_ERROR"
        )
        assert system.value & SystemFaultsStatus.PAN_TILT_EXECUTION_ERROR
        # a goal while the lock stands fails at once
        state, _, text = run("PanTiltMoveJoints", owl.PanTiltMoveJointsGoal(0.5, 0.2))
        assert state == GoalStatus.ABORTED
        assert "j_ant_pan locked (PAN_JOINT_LOCKED)" in text
    finally:
        clear_faults(stack)
    state, _, text = run("PanTiltMoveJoints", owl.PanTiltMoveJointsGoal(0.0, 0.0))
    assert state == GoalStatus.SUCCEEDED, text
