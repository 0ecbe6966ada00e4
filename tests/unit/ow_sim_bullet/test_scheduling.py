"""Output rates, pacing and the terrain's republication, on a fake wall clock."""

from __future__ import annotations

import pytest

from ow_sim_bullet.scheduling import Pacer, Periodic, Throttle


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.mark.parametrize(("rate_hz", "expected"), [(100.0, 100), (30.0, 30), (50.0, 50)])
def test_periodic_fires_at_its_rate_on_100_hz_steps(rate_hz, expected):
    tick = Periodic(rate_hz)
    fired = [k for k in range(100) if tick.due(k * 0.01)]
    assert len(fired) == expected
    assert fired[0] == 0  # the first step is a tick


def test_periodic_skips_the_ticks_it_missed():
    tick = Periodic(10.0)
    assert tick.due(0.0)
    assert not tick.due(0.05)
    assert tick.due(0.37)  # ticks 0.1, 0.2, 0.3 missed: one message
    assert not tick.due(0.39) and tick.due(0.4)


def test_periodic_counts_a_step_a_rounding_short_of_the_tick():
    tick = Periodic(100.0)
    assert tick.due(0.0)
    assert tick.due(0.01 - 1e-12)


def test_pacer_waits_when_ahead_of_the_wall_clock():
    clock = FakeClock()
    pacer = Pacer(2.0, clock)
    pacer.restart(10.0)
    assert pacer.wait(11.0) == pytest.approx(0.5)  # 1 s of sim time at 2x: 0.5 s of wall time
    clock.now += 0.5
    assert pacer.wait(11.0) == 0.0


def test_pacer_gives_up_catching_up_when_far_behind():
    clock = FakeClock()
    pacer = Pacer(1.0, clock)
    pacer.restart(0.0)
    clock.now += 2.0  # 2 s of wall time for 1 s of sim time: 1 s behind
    assert pacer.wait(1.0) == 0.0
    # The pace restarted at sim 1.0 now: another 0.1 s of sim time is 0.1 s ahead.
    assert pacer.wait(1.1) == pytest.approx(0.1)


def test_pacer_at_factor_zero_never_waits():
    clock = FakeClock()
    pacer = Pacer(0.0, clock)
    assert pacer.wait(1e6) == 0.0


def test_throttle_republishes_a_new_version_at_most_every_period():
    clock = FakeClock()
    throttle = Throttle(0.5, clock)
    assert throttle.due(0)
    throttle.done(0)
    assert not throttle.due(0)
    assert not throttle.due(1)  # changed, but too soon
    assert throttle.changed(1) and not throttle.changed(0)  # whatever the period
    clock.now += 0.5
    assert throttle.due(1)
    throttle.done(1)
    clock.now += 10.0
    assert not throttle.due(1)  # unchanged
