"""The simulation thread in lockstep (no ROS): it steps only as far as its clients allow, applies
their commands at the step they were decided for, stops at a hold, and gives the same joint
trajectory however late the acknowledgements come."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from ow_description.description import DEFAULT_GROUND_Z
from ow_sim_bullet.config import SimConfig
from ow_sim_bullet.outputs import SimOutputs
from ow_sim_bullet.runner import SimRunner
from ow_sim_bullet.sim_core import BulletSim
from ow_sim_bullet.terrains import flat

LATENCY = 0.05


class _Recorder(SimOutputs):
    """Outputs that keep each step's (stamp, positions) instead of publishing them."""

    def __init__(self, sim: BulletSim) -> None:  # nothing to publish to
        self.sim = sim
        self.joint_stamp = self.terrain_stamp = -1.0
        self.states: list[tuple[float, np.ndarray]] = []
        #: s (sim) of each standing written with its terrain, and how long one takes (wall s)
        self.stood: list[float] = []
        self.standing_s = 0.0
        #: (sim time s, the nodes written to: None for everyone) of every flush
        self.flushes: list[tuple[float, frozenset[str] | None]] = []

    def publish(self, force: bool = False) -> None:
        sample = self.sim.sample
        self.joint_stamp = sample.time
        self.states.append((sample.time, sample.position.copy()))

    def after_step(self, lockstep: bool = False) -> None:
        self.publish()

    def publish_standing(self, terrain: bool = True) -> None:
        if terrain:
            time.sleep(self.standing_s)  # a terrain's serialisation, on a loaded machine
            self.stood.append(self.sim.time)

    def flush(self, only=None) -> None:
        self.flushes.append((self.sim.time, None if only is None else frozenset(only)))

    def publish_terrain_if_due(self) -> None:
        pass


@pytest.fixture()
def runner():
    sim = BulletSim(SimConfig(lockstep_latency_s=LATENCY), flat(DEFAULT_GROUND_Z))
    run = SimRunner(sim, _Recorder(sim), 0.0, True, lambda: False, log=lambda _: None)
    thread = threading.Thread(target=run.run, daemon=True)
    thread.start()
    yield run
    run.stop()
    thread.join(timeout=5.0)
    sim.close()


def test_stepping_stops_at_a_hold_and_goes_on_once_released(runner):
    runner.lockstep_register("arm", enable=True, hold=True)
    assert runner.step_paused(10) == pytest.approx(0.0)  # held where it registered
    runner.lockstep_ack("arm", 0.0, 0.03, [])
    assert runner.step_paused(10) == pytest.approx(0.03)
    _, stamp, clients, blocked, holding, _ = runner.lockstep_status()
    assert (clients, blocked, holding) == (["arm"], ("arm", "hold"), ["arm"])
    assert stamp == pytest.approx(0.02)  # the last state published, of the step from 0.02


def test_a_hold_shows_only_once_the_simulation_stands_with_its_terrain_written(runner):
    """A client that plans on the terrain the simulation stands on reads the terrain's stamp
    once the status shows the hold: the hold must not show while the standing outputs (the
    terrain) are still being written (two equal missions once planned a grind on different
    terrains)."""
    outputs = runner.outputs
    outputs.standing_s = 0.2
    runner.lockstep_register("arm", enable=True, hold=True)
    runner.lockstep_ack("arm", 0.1, 0.1, [])  # decided up to 0.1 s, and holding there
    runner.resume()
    seen_holding = []
    deadline = time.monotonic() + 10.0
    while not seen_holding and time.monotonic() < deadline:
        now, _, _, _, holding, _ = runner.lockstep_status()
        if holding:
            seen_holding.append(now)
            assert now in outputs.stood, (now, outputs.stood)  # written before it shows
        time.sleep(0.001)
    assert seen_holding == [pytest.approx(0.1)]


def _waiting_for_ack(runner, node: str | None = None) -> float:
    """Register client "arm" (of ``node``) without a hold, run, and return the sim time (s)
    where the simulation waits for its acknowledgement."""
    runner.lockstep_register("arm", enable=True, hold=False, node=node)
    runner.resume()
    deadline = time.monotonic() + 5.0
    while runner.lockstep_status()[3] is None and time.monotonic() < deadline:
        time.sleep(0.01)
    return runner.lockstep_status()[0]


def test_a_late_acknowledgement_holds_the_simulation_back_until_it_comes(runner):
    _waiting_for_ack(runner)
    deadline = time.monotonic() + 5.0
    now, _, _, blocked, holding, _ = runner.lockstep_status()
    assert (blocked, holding) == (("arm", "ack"), [])
    assert now == pytest.approx(LATENCY + 0.01)  # registered at 0: one latency and a step on
    runner.lockstep_ack("arm", 0.5, None, [])
    # Until it stands waiting again (not merely past 0.55 s: it may be about to step on).
    while time.monotonic() < deadline:
        now, _, _, blocked, _, _ = runner.lockstep_status()
        if now >= 0.55 and blocked is not None:
            break
        time.sleep(0.01)
    assert runner.lockstep_status()[0] == pytest.approx(0.5 + LATENCY + 0.01)


def test_waiting_for_an_acknowledgement_writes_to_the_clients_node_and_a_hold_to_everyone(runner):
    """What a client decides on must reach it before the simulation can go on; the other
    subscribers (recorder, monitors) get the same messages later, in bigger batches. Where the
    simulation stands held, everything goes out to everyone."""
    waiting_at = _waiting_for_ack(runner, node="/arm_services")
    deadline = time.monotonic() + 5.0
    assert (waiting_at, frozenset({"/arm_services"})) in runner.outputs.flushes
    runner.lockstep_ack("arm", waiting_at, waiting_at, [])  # holds right where it waits
    while runner.lockstep_status()[4] != ["arm"] and time.monotonic() < deadline:
        time.sleep(0.01)
    assert runner.outputs.flushes[-1] == (pytest.approx(waiting_at), None)


def test_an_acknowledgement_long_in_coming_gets_everyone_their_messages(runner):
    """A client whose decisions come from another node's subscriptions would wait for ever
    for messages written to its own node only: after 0.1 s of wall time without an
    acknowledgement, everyone gets everything (the same messages: nothing else changes)."""
    waiting_at = _waiting_for_ack(runner, node="/elsewhere")
    deadline = time.monotonic() + 5.0
    while (waiting_at, None) not in runner.outputs.flushes and time.monotonic() < deadline:
        time.sleep(0.01)
    assert (waiting_at, frozenset({"/elsewhere"})) in runner.outputs.flushes
    assert (waiting_at, None) in runner.outputs.flushes


def test_a_simulation_paused_at_a_hold_takes_no_step_when_its_client_leaves(runner):
    """A mission pauses the simulation where the lockstep holds it, then stops its nodes: the
    arm services leaving the lockstep must not let it take a step (a replay recorded one more
    joint state than its original)."""
    runner.lockstep_register("arm", enable=True, hold=True)
    runner.lockstep_ack("arm", 0.0, 0.03, [])
    runner.resume()
    deadline = time.monotonic() + 5.0
    while runner.lockstep_status()[4] != ["arm"] and time.monotonic() < deadline:
        time.sleep(0.01)
    assert runner.lockstep_status()[0] == pytest.approx(0.03)  # held there
    runner.pause()
    published = len(runner.outputs.states)
    runner.lockstep_register("arm", enable=False, hold=False)
    time.sleep(0.3)  # wall: the thread would have stepped many times by now
    assert runner.lockstep_status()[0] == pytest.approx(0.03)
    assert len(runner.outputs.states) == published
    runner.resume()
    while runner.lockstep_status()[0] < 0.1 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert runner.lockstep_status()[0] >= 0.1  # and runs on once resumed


def test_a_pause_answers_once_the_simulation_stands_with_its_outputs_written(runner):
    """``/sim/pause`` answers once the thread stands with everything up to its time written: a
    stop stamps its request and brakes where the simulation stands, once it has received that
    (a cancel once braked 0.35 s of sim time after its request on a loaded machine)."""
    runner.outputs.standing_s = 0.2  # the standing's writes are slow
    runner.resume()
    deadline = time.monotonic() + 5.0
    while runner.lockstep_status()[0] < 0.5 and time.monotonic() < deadline:
        time.sleep(0.001)
    assert runner.pause_standing() is False  # it was running
    now = runner.lockstep_status()[0]
    assert runner.outputs.stood[-1] == now  # written before the answer
    time.sleep(0.05)
    assert runner.lockstep_status()[0] == now
    assert runner.pause_standing() is True


def _run_with_acks(runner: SimRunner, delay_s: float) -> list[tuple[float, np.ndarray]]:
    """Acknowledge every state (``delay_s`` of wall time late), commanding the shoulder yaw to
    0.3 rad on the state of 0.1 s; the recorded joint states up to 1 s."""
    outputs = runner.outputs
    assert isinstance(outputs, _Recorder)
    runner.lockstep_register("arm", enable=True, hold=False)
    runner.resume()
    acked = 0
    while True:
        states = list(outputs.states)
        if acked < len(states):
            stamp = states[acked][0]
            time.sleep(delay_s)
            commands = [("j_shou_yaw", 0.3)] if abs(stamp - 0.1) < 1e-6 else []
            runner.lockstep_ack("arm", stamp, None, commands)
            acked += 1
            if stamp >= 1.0:
                break
        else:
            time.sleep(0.0005)
    runner.pause()
    return [(t, q) for t, q in outputs.states if t <= 1.0]


def test_the_same_acknowledgements_give_the_same_motion_however_late_they_come():
    trajectories = []
    for delay_s in (0.0, 0.003):
        sim = BulletSim(SimConfig(lockstep_latency_s=LATENCY), flat(DEFAULT_GROUND_Z))
        run = SimRunner(sim, _Recorder(sim), 0.0, True, lambda: False, log=lambda _: None)
        thread = threading.Thread(target=run.run, daemon=True)
        thread.start()
        try:
            trajectories.append(_run_with_acks(run, delay_s))
        finally:
            run.stop()
            thread.join(timeout=5.0)
            sim.close()
    fast, slow = trajectories
    assert [t for t, _ in fast] == [t for t, _ in slow]
    for (t, q_fast), (_, q_slow) in zip(fast, slow, strict=True):
        assert np.array_equal(q_fast, q_slow), f"joint states differ at t={t:.2f} s"
    # The command took effect at the step from 0.1 + latency: the yaw moves from there on.
    yaw = sim.names.index("j_shou_yaw")
    moved = [t for t, q in fast if abs(q[yaw] - fast[0][1][yaw]) > 1e-6]
    assert moved[0] == pytest.approx(0.1 + LATENCY + 0.01)


def test_a_nan_set_point_holds_the_joint_where_it_is_when_applied(runner):
    sim = runner.sim
    runner.lockstep_register("arm", enable=True, hold=False)
    sim_yaw = sim.names.index("j_shou_yaw")
    runner.lockstep_ack("arm", 0.0, None, [("j_shou_yaw", -1.0)])  # starts moving at 0.05
    runner.lockstep_ack("arm", 0.2, None, [("j_shou_yaw", float("nan"))])  # stop at 0.25
    runner.step_paused(25)  # to 0.25: the hold is applied before the step from 0.25
    there = sim.position("j_shou_yaw")
    runner.step_paused(1)
    assert sim.controller.setpoint[sim_yaw] == there  # exactly where it was, not -1
    assert -1.49 < there < -1.01  # it was still on its way from -1.5 (stowed) to -1
