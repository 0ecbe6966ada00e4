"""The lockstep protocol (ow_sim_bullet.lockstep): when the simulation may step, and when the
clients' commands take effect."""

import pytest

from ow_sim_bullet.lockstep import Lockstep

DT = 0.01
LATENCY = 0.05


def steps_allowed(lockstep: Lockstep, start: float, limit: int = 1000) -> float:
    """The sim time at which a simulation stepping from ``start`` is first blocked."""
    now = start
    for _ in range(limit):
        if lockstep.blocking(now) is not None:
            return now
        now = round(now + DT, 9)
    return now


def test_no_client_never_blocks():
    assert Lockstep(LATENCY).blocking(123.0) is None


def test_a_client_lets_the_simulation_run_one_latency_past_its_acknowledgement():
    lockstep = Lockstep(LATENCY)
    lockstep.register("arm", now=1.0, hold=False)
    # Registered at 1.0: it has seen everything up to then.
    assert steps_allowed(lockstep, 1.0) == pytest.approx(1.06)
    assert lockstep.blocking(1.06) == ("arm", "ack")
    lockstep.ack("arm", 1.03)
    assert steps_allowed(lockstep, 1.06) == pytest.approx(1.09)


def test_the_nodes_awaited_are_those_of_the_clients_whose_acknowledgement_the_step_needs():
    lockstep = Lockstep(LATENCY)
    lockstep.register("arm", 0.0, hold=False, node="/arm_services")
    lockstep.register("faults", 0.0, hold=False, node="/mission")
    lockstep.ack("faults", 10.0)  # far ahead: not waited for
    assert lockstep.awaited_nodes(0.03) == frozenset()  # within the latency: nobody
    assert lockstep.awaited_nodes(0.06) == {"/arm_services"}
    lockstep.register("expected", 0.0, hold=False)  # registered for it: its node unknown
    assert lockstep.awaited_nodes(0.06) is None  # then everyone


def test_the_slowest_client_sets_the_pace():
    lockstep = Lockstep(LATENCY)
    lockstep.register("fast", 0.0, hold=False)
    lockstep.register("slow", 0.0, hold=False)
    lockstep.ack("fast", 0.5)
    lockstep.ack("slow", 0.1)
    assert steps_allowed(lockstep, 0.0) == pytest.approx(0.16)
    assert lockstep.blocking(0.16) == ("slow", "ack")


def test_commands_take_effect_exactly_one_latency_after_the_stamp_they_were_decided_on():
    lockstep = Lockstep(LATENCY)
    lockstep.register("arm", 0.0, hold=False)
    lockstep.ack("arm", 0.02, commands=[("j_shou_yaw", 0.5)])
    assert lockstep.due(0.06) == []
    assert lockstep.due(0.07) == [("j_shou_yaw", 0.5)]
    assert lockstep.due(0.07) == []  # once


def test_commands_due_together_come_in_decision_order_then_client_order():
    lockstep = Lockstep(LATENCY)
    lockstep.register("a", 0.0, hold=False)
    lockstep.register("b", 0.0, hold=False)
    lockstep.ack("b", 0.01, commands=[("j", 2.0)])
    lockstep.ack("a", 0.02, commands=[("j", 3.0)])
    lockstep.ack("b", 0.02, commands=[("j", 4.0), ("k", 5.0)])
    lockstep.ack("a", 0.01, commands=[("j", 1.0)])  # late and stale: applied with 0.02's
    assert lockstep.due(1.0) == [("j", 2.0), ("j", 3.0), ("j", 1.0), ("j", 4.0), ("k", 5.0)]


def test_an_acknowledgement_going_back_in_time_is_reported_and_counts_as_the_newest():
    lockstep = Lockstep(LATENCY)
    lockstep.register("arm", 0.0, hold=False)
    assert lockstep.ack("arm", 0.5) is None
    problem = lockstep.ack("arm", 0.2, commands=[("j", 1.0)])
    assert "must not go back in time" in problem
    assert lockstep.clients["arm"].acked == pytest.approx(0.5)
    assert lockstep.due(0.54) == []
    assert lockstep.due(0.55) == [("j", 1.0)]


def test_an_unregistered_client_is_ignored():
    lockstep = Lockstep(LATENCY)
    assert "unregistered client 'ghost'" in lockstep.ack("ghost", 1.0, commands=[("j", 1.0)])
    assert lockstep.due(10.0) == []
    assert lockstep.blocking(10.0) is None


def test_a_hold_stops_the_simulation_at_its_time_until_released():
    lockstep = Lockstep(LATENCY)
    lockstep.register("arm", 0.0, hold=True)
    assert lockstep.blocking(0.0) == ("arm", "hold")
    lockstep.ack("arm", 0.0, hold_until=None)
    assert steps_allowed(lockstep, 0.0) == pytest.approx(0.06)
    lockstep.ack("arm", 0.05, hold_until=0.3)
    assert steps_allowed(lockstep, 0.06) == pytest.approx(0.11)  # still acknowledging
    lockstep.ack("arm", 0.4, hold_until=0.3)
    assert steps_allowed(lockstep, 0.11) == pytest.approx(0.3)
    assert lockstep.blocking(0.3) == ("arm", "hold")
    lockstep.unregister("arm")
    assert lockstep.blocking(0.3) is None


def test_every_client_holding_the_simulation_is_listed_not_only_the_first():
    """Two holds at one time (the arm services after a step, a fault schedule due then): each
    client learns that the simulation stands at its hold."""
    lockstep = Lockstep(LATENCY)
    lockstep.register("arm", 0.0, hold=False)
    lockstep.register("faults", 0.0, hold=False)
    lockstep.ack("arm", 1.0 - LATENCY, hold_until=1.0)
    lockstep.ack("faults", 1.0 - LATENCY, hold_until=1.0)  # follows no joint state
    assert lockstep.holding(0.99) == []
    assert steps_allowed(lockstep, 0.0) == pytest.approx(1.0)
    assert lockstep.holding(1.0) == ["arm", "faults"]
    lockstep.unregister("faults")
    assert lockstep.holding(1.0) == ["arm"]


def test_a_client_silent_too_long_is_named_but_a_holding_one_is_not():
    lockstep = Lockstep(LATENCY)
    lockstep.register("dead", 0.0, hold=False, wall=100.0)
    lockstep.register("holding", 0.0, hold=True, wall=100.0)
    assert lockstep.silent(0.1, wall=105.0, timeout_s=10.0) == []
    assert lockstep.silent(0.1, wall=111.0, timeout_s=10.0) == ["dead"]
    assert lockstep.silent(0.04, wall=111.0, timeout_s=10.0) == []  # not waited for yet


@pytest.mark.parametrize("latency", [0.0, -1.0, float("nan"), float("inf")])
def test_a_latency_must_be_positive_and_finite(latency):
    with pytest.raises(ValueError, match="must be > 0"):
        Lockstep(latency)
