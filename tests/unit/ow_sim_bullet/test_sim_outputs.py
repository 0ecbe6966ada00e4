"""The node's outputs and simulation thread without a master: a real simulation (pybullet DIRECT)
publishing into recorders that decode what would go on the wire."""

from __future__ import annotations

import contextlib
import dataclasses
import sys
import threading
import time
from collections.abc import Callable

import numpy as np
import pytest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from ow_description.description import DEFAULT_GROUND_Z, URDF_PATH
from ow_msgs.msg import ToolState as ToolStateMsg
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.conversions import joint_frames
from ow_sim_bullet.errors import CommandError, SimError
from ow_sim_bullet.outputs import FLUSH_STEPS, LOCKSTEP_FLUSH_STEPS, WIRE_TOPICS, SimOutputs
from ow_sim_bullet.runner import SimRunner
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import flat
from ow_sim_bullet.tool_tracking import DigPhase


class Recorder:
    """A wire publisher that keeps what it would write, in the order flushes wrote it."""

    def __init__(self, topic: str, data_class: type, log: list[str]) -> None:
        self.topic, self.data_class, self.log = topic, data_class, log
        self.seq = 0
        self.queued: list[bytes] = []
        self.written: list[bytes] = []

    def publish(self, serialize, *args) -> None:
        self.seq += 1
        self.queued.append(serialize(self.seq, *args))

    def flush(self, only=None) -> None:
        if self.queued:
            self.log.append(self.topic)
        self.written += self.queued
        self.queued.clear()

    def messages(self) -> list:
        return [self.data_class().deserialize(payload) for payload in self.written]


class Terrain:
    def __init__(self) -> None:
        self.messages: list = []

    def publish(self, msg) -> None:
        self.messages.append(msg)


class Setup:
    def __init__(self, config: SimConfig) -> None:
        self.sim = BulletSim(config, flat(DEFAULT_GROUND_Z))
        self.log: list[str] = []
        self.recorders = {topic: Recorder(topic, cls, self.log) for topic, cls in WIRE_TOPICS}
        self.terrain = Terrain()
        self.clock_times: list[float] = []
        frames = joint_frames(URDF_PATH.read_text())
        self.outputs = SimOutputs(
            self.sim, config, self.recorders, self.terrain, frames, self.clock_times.append
        )

    def steps(self, count: int, lockstep: bool = False) -> None:
        for _ in range(count):
            self.sim.step()
            self.outputs.after_step(lockstep)


@pytest.fixture()
def setup():
    config = dataclasses.replace(SimConfig(), terrain_publish_period=0.0)
    made = Setup(config)
    yield made
    made.sim.close()


def test_each_output_at_its_rate_with_stamps_of_the_sample(setup):
    setup.outputs.publish(force=True)
    setup.steps(100)
    setup.outputs.flush()
    counts = {topic: len(r.written) for topic, r in setup.recorders.items()}
    # The forced first outputs at 0, then 1 s of sim time at the configured rates: /clock at
    # the sim time (0.01 ... 1.0), the rest at the samples' (the state before each step, 0 ...
    # 0.99, the tick at 0 taken by the forced outputs).
    assert counts["/clock"] == 101
    assert counts["/joint_states"] == counts["~joint_damping"] == 100
    assert counts["/tf"] == 30
    assert counts["~scoop_wrench"] == counts["~grinder_wrench"] == 50
    assert counts["/arm_end_effector_force_torque"] == counts["~scoop_tip_ground"] == 50
    for kind in ("state", "model_state", "model_wrench"):
        assert counts[f"~scoop_{kind}"] == counts[f"~grinder_{kind}"] == 10
    clocks = setup.recorders["/clock"].messages()
    assert [c.clock.to_sec() for c in clocks[-2:]] == pytest.approx([0.99, 1.0])
    joints = setup.recorders["/joint_states"].messages()
    assert joints[-1].header.stamp.to_sec() == pytest.approx(setup.sim.sample.time)
    assert list(joints[-1].name) == list(setup.sim.names)
    assert joints[-1].position == pytest.approx(setup.sim.sample.position.tolist())
    tf = setup.recorders["/tf"].messages()[-1]
    assert {t.child_frame_id for t in tf.transforms} >= {"l_scoop", "l_grinder"}
    state = setup.recorders["~scoop_state"].messages()[-1]
    assert state.tool == "scoop" and state.header.frame_id == "base_link"
    assert clocks[0].__class__ is Clock and isinstance(tf, TFMessage)
    assert isinstance(joints[0], JointState) and isinstance(state, ToolStateMsg)


def test_messages_are_written_every_few_steps_clock_first(setup):
    setup.steps(FLUSH_STEPS - 1)
    assert not setup.log and not setup.clock_times
    setup.steps(1)
    assert setup.log[0] == "/clock"
    assert setup.clock_times == [pytest.approx(FLUSH_STEPS * setup.sim.dt)]
    assert len(setup.recorders["/joint_states"].written) == FLUSH_STEPS


def test_in_the_lockstep_everyone_gets_the_messages_every_lockstep_flush_steps(setup):
    """The nodes a step waits for get theirs each time it waits (the runner's partial
    flushes); the rest are written for everyone only this often."""
    setup.steps(LOCKSTEP_FLUSH_STEPS - 1, lockstep=True)
    assert not setup.log
    setup.steps(1, lockstep=True)
    assert setup.log[0] == "/clock"
    assert len(setup.recorders["/joint_states"].written) == LOCKSTEP_FLUSH_STEPS


def test_the_terrain_is_republished_after_it_changed(setup):
    setup.outputs.publish_terrain()
    assert len(setup.terrain.messages) == 1
    setup.steps(10)
    assert len(setup.terrain.messages) == 1  # nothing carved
    setup.sim.set_terrain(flat(DEFAULT_GROUND_Z - 0.1))
    setup.steps(1)
    assert len(setup.terrain.messages) == 2
    assert setup.terrain.messages[-1].heights[0] == pytest.approx(DEFAULT_GROUND_Z - 0.1)


def test_the_dig_phase_is_told_at_start_and_at_each_change(setup):
    """OceanWATERS' latched scoop_dig_phase: NOT_DIGGING from the start, then one message per
    change, stamped with the sim time of the step it changed in."""
    told: list[tuple[float, DigPhase]] = []
    frames = joint_frames(URDF_PATH.read_text())
    outputs = SimOutputs(
        setup.sim,
        setup.sim.config,
        setup.recorders,
        setup.terrain,
        frames,
        on_dig_phase=lambda t, phase: told.append((t, phase)),
    )
    outputs.publish_dig_phase()
    assert told == [(0.0, DigPhase.NOT_DIGGING)]
    for _ in range(5):
        setup.sim.step()
        outputs.after_step()
    assert len(told) == 1  # no change, no message
    setup.sim.tracker.dig.phase = DigPhase.SINKING  # as a dig's start would
    setup.sim.step()
    outputs.after_step()
    setup.sim.step()
    outputs.after_step()
    assert told[1:] == [(pytest.approx(0.06), DigPhase.SINKING)]
    setup.sim.reset()  # forgets the dig
    setup.sim.step()
    outputs.after_step()
    assert told[2:] == [(pytest.approx(0.08), DigPhase.NOT_DIGGING)]


@pytest.fixture()
def running(setup):
    """A paused simulation thread as fast as possible."""
    runner = SimRunner(setup.sim, setup.outputs, 0.0, True, lambda: False)
    thread = threading.Thread(target=runner.run, daemon=True)
    thread.start()
    yield runner
    runner.stop()
    thread.join(timeout=5.0)
    assert not thread.is_alive()


def test_a_paused_simulation_steps_on_request(running, setup):
    assert running.step_paused(5) == pytest.approx(0.05)
    assert setup.sim.steps == 5
    assert setup.recorders["/clock"].written  # flushed with the reply
    with pytest.raises(CommandError, match="steps must be > 0"):
        running.step_paused(0)
    assert running.call(lambda: setup.sim.steps) == 5


def test_commands_run_on_the_simulation_thread_and_their_errors_come_back(running, setup):
    with pytest.raises(CommandError, match="unknown joint"):
        running.call(lambda: setup.sim.set_setpoint("j_elbow", 0.0))
    names: list[str] = []
    running.enqueue(lambda: names.append(threading.current_thread().name))
    running.call(lambda: None)
    assert names and names[0] != threading.current_thread().name


def test_pause_and_resume(running, setup):
    assert running.pause() is True  # started paused
    assert running.resume() is True
    with pytest.raises(CommandError, match="the simulation is running; call ~pause first"):
        running.step_paused(1)
    assert running.resume() is False
    while running.call(lambda: setup.sim.steps) < 10:
        pass
    assert running.pause() is False
    steps = running.call(lambda: setup.sim.steps)
    assert running.call(lambda: setup.sim.steps) == steps  # paused: no more steps


def test_a_stopped_runner_answers_no_more(setup):
    runner = SimRunner(setup.sim, setup.outputs, 0.0, True, lambda: False)
    runner.stop()
    with pytest.raises(SimError, match="did not answer"):
        runner.call(lambda: None, timeout_s=0.3)


def _eventually(condition, timeout_s: float = 30.0) -> bool:
    """Whether ``condition()`` holds within ``timeout_s`` of wall time (the simulation thread
    publishes when it next runs its loop). The bound is only against a hang: what is tested is
    that it happens at all (here, without waiting out an hour's throttle), and a loaded VM has
    held both threads still for seconds."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


@contextlib.contextmanager
def _threaded(config: SimConfig, lock: Callable[[SimRunner], threading.Condition] | None = None):
    """A simulation recorded as in :class:`Setup`, on a runner thread of its own (started
    paused, as fast as possible), with the runner's lock made by ``lock``; stopped after."""
    made = Setup(config)
    runner = SimRunner(made.sim, made.outputs, 0.0, True, lambda: False)
    if lock is not None:
        runner._wake = lock(runner)
    thread = threading.Thread(target=runner.run, daemon=True)
    thread.start()
    try:
        yield made, runner
    finally:
        runner.stop()
        thread.join(timeout=5.0)
        made.sim.close()


def _run_to_step(made: Setup, runner: SimRunner, steps: int) -> None:
    """Resume the runner and return once the simulation took ``steps`` steps (it runs on)."""
    runner.resume()
    while runner.call(lambda: made.sim.steps) < steps:
        pass


def test_a_slow_clock_still_reaches_where_the_simulation_stops():
    """/clock at 10 Hz: between ticks it lags, but after ``~step``, on a pause and at a lockstep
    hold it is written at the time the simulation stands at (nodes' clocks reach it)."""
    config = dataclasses.replace(SimConfig(), clock_rate_hz=10.0, terrain_publish_period=0.0)
    with _threaded(config) as (made, runner):

        def last_clock() -> float:
            return runner.call(lambda: made.recorders["/clock"].messages()[-1].clock.to_sec())

        assert runner.step_paused(13) == pytest.approx(0.13)
        ticks = [m.clock.to_sec() for m in made.recorders["/clock"].messages()]
        assert ticks == pytest.approx([0.01, 0.1, 0.13])  # the 10 Hz ticks, then where it stopped
        _run_to_step(made, runner, 27)
        runner.pause()
        assert _eventually(lambda: last_clock() == pytest.approx(made.sim.time))
        runner.lockstep_register("arm", enable=True, hold=True)
        runner.lockstep_ack("arm", made.sim.time, made.sim.time + 0.04, [])
        held = runner.step_paused(50)
        assert held == pytest.approx(made.sim.time) and last_clock() == pytest.approx(held)


def test_a_terrain_changed_within_the_throttle_goes_out_where_the_simulation_stops():
    """The terrain is republished at most every ``terrain_publish_period`` s of simulation time
    while the simulation runs, but the one it stands on when paused or held goes out at once:
    the last terrain of a run is recorded however soon the run ends."""
    config = dataclasses.replace(SimConfig(), terrain_publish_period=3600.0)
    with _threaded(config) as (made, runner):
        _run_to_step(made, runner, 5)
        published = len(made.terrain.messages)  # the first, on the first step
        runner.call(lambda: made.sim.set_terrain(flat(DEFAULT_GROUND_Z - 0.1)))
        while runner.call(lambda: made.sim.steps) < 10:
            pass
        assert len(made.terrain.messages) == published  # changed, but within the hour
        runner.pause()
        went_out = _eventually(lambda: len(made.terrain.messages) == published + 1)
        sent = [(m.header.stamp.to_sec(), m.heights[0]) for m in made.terrain.messages]
        assert went_out, (
            f"{published + 1} terrains expected after the pause; (stamp, first height) "
            f"of those sent: {sent}; terrain version {made.sim.terrain_version}, "
            f"{made.sim.steps} steps"
        )
        assert made.terrain.messages[-1].heights[0] == pytest.approx(DEFAULT_GROUND_Z - 0.1)
        assert made.terrain.messages[-1].header.stamp.to_sec() == pytest.approx(made.sim.time)
        # The lockstep status names the newest terrain's stamp: a client planning on the terrain
        # waits until it has that one.
        assert runner.lockstep_status()[5] == made.terrain.messages[-1].header.stamp.to_sec()
        runner.call(lambda: made.sim.set_terrain(flat(DEFAULT_GROUND_Z - 0.2)))
        runner.lockstep_register("arm", enable=True, hold=True)
        runner.step_paused(3)  # held where it registered: it stands, the terrain goes out
        assert made.terrain.messages[-1].heights[0] == pytest.approx(DEFAULT_GROUND_Z - 0.2)
        assert runner.lockstep_status()[5] == pytest.approx(
            made.terrain.messages[-1].header.stamp.to_sec(), abs=1e-9
        )


class _PausingLock(threading.Condition):
    """A runner's lock that, once armed, pauses the runner as its loop next takes the lock to
    wait for commands: after the loop looked at the pause, before it waits (the order a loaded
    machine once gave a pause from another thread, in CI)."""

    def __init__(self, runner: SimRunner) -> None:
        super().__init__(threading.Lock())
        self.runner = runner
        self.armed = False

    def __enter__(self) -> bool:
        if self.armed and sys._getframe(1).f_code.co_name == "run":
            self.armed = False
            self.runner.pause()  # takes this lock too, disarmed
        return super().__enter__()


def test_a_pause_between_the_loops_look_and_its_wait_is_stood_at():
    """Whenever a pause comes, the simulation stands before it waits: what it stands at (a
    terrain changed within the throttle, /clock at its time) goes out, not at the next command."""
    config = dataclasses.replace(SimConfig(), terrain_publish_period=3600.0)
    with _threaded(config, _PausingLock) as (made, runner):
        _run_to_step(made, runner, 5)
        runner.call(lambda: made.sim.set_terrain(flat(DEFAULT_GROUND_Z - 0.1)))
        assert len(made.terrain.messages) == 1  # the first; the change is within the hour
        lock = runner._wake
        lock.armed = True
        assert _eventually(lambda: not lock.armed)  # paused by the loop's own thread
        assert _eventually(lambda: len(made.terrain.messages) == 2)
        stands_at = made.sim.time  # the runner is paused: it steps no more
        assert made.terrain.messages[-1].heights[0] == pytest.approx(DEFAULT_GROUND_Z - 0.1)
        assert made.terrain.messages[-1].header.stamp.to_sec() == pytest.approx(stands_at)
        clock = made.recorders["/clock"].messages()[-1].clock.to_sec()
        assert clock == pytest.approx(stands_at)


def _carved_terrain_stamps(slow_steps: bool) -> list[float]:
    """Stamps of the terrains published over 50 steps that each change the terrain."""
    made = Setup(dataclasses.replace(SimConfig(), terrain_publish_period=0.1))
    try:
        for k in range(50):
            made.sim.set_terrain(flat(DEFAULT_GROUND_Z - 0.001 * k))
            made.steps(1)
            if slow_steps and k % 7 == 0:
                time.sleep(0.02)
        return [m.header.stamp.to_sec() for m in made.terrain.messages]
    finally:
        made.sim.close()


def test_a_terrain_carved_all_the_time_goes_out_every_period_of_simulation_time():
    # Changed at every step, the terrain is published once terrain_publish_period of sim time
    # has passed since the last, however long the steps take in wall time: the bags of equal
    # runs hold the same terrains (throttled in wall time, a replay of the same run differed).
    stamps = _carved_terrain_stamps(slow_steps=False)
    assert stamps == _carved_terrain_stamps(slow_steps=True)
    assert len(stamps) == 5
    step = SimConfig().dt
    for gap in np.diff(stamps):
        assert 0.1 - 1e-9 <= gap <= 0.1 + step + 1e-9
