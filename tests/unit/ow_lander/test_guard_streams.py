"""GuardStreams: a decision waits until its guard's stream reaches the joint state's stamp, and
readings wake the waiting threads only while a decision waits for a stream."""

import threading

from ow_lander.execution.guard_streams import GuardStreams
from ow_runtime.names import STAMP_SLACK_S


class CountingCondition(threading.Condition):
    def __init__(self) -> None:
        super().__init__(threading.Lock())
        self.wakeups = 0

    def notify_all(self) -> None:
        self.wakeups += 1
        super().notify_all()


def test_readings_with_no_decision_waiting_wake_nobody():
    condition = CountingCondition()
    streams = GuardStreams(condition)
    with condition:
        for k in range(50):
            streams.arrived("force", 0.02 * k)
            streams.arrived("tip", 0.033 * k)
    assert condition.wakeups == 0
    assert streams.newest == {"force": 0.98, "tip": 0.033 * 49}


def test_a_decision_waits_until_its_stream_reaches_the_stamp():
    condition = CountingCondition()
    streams = GuardStreams(condition)
    results = []

    def decide():
        with condition:
            results.append(streams.wait("force", 1.0, 30.0, lambda: False))
            results.append(streams.newest["force"])

    with condition:
        streams.arrived("force", 0.5)
    waiter = threading.Thread(target=decide)
    waiter.start()
    for k in range(1, 6):  # the tip's readings do not end the wait; 1.0 s of the wrist does
        while True:  # until the decision waits
            with condition:
                if streams.waiting:
                    break
        with condition:
            streams.arrived("tip", 2.0 * k)
            streams.arrived("force", 0.5 + 0.1 * k)
    waiter.join(timeout=30.0)
    assert results == [True, 1.0]
    assert condition.wakeups == 10  # each reading while it waited, none after


def test_a_reading_within_the_slack_or_a_stop_ends_the_wait_and_silence_times_out():
    condition = threading.Condition(threading.Lock())
    streams = GuardStreams(condition)
    with condition:
        streams.arrived("tip", 2.0 - STAMP_SLACK_S / 2)
        assert streams.wait("tip", 2.0, 0.01, lambda: False)
        assert streams.wait("force", 2.0, 0.01, lambda: True)
        assert not streams.wait("force", 2.0, 0.01, lambda: False)
        assert streams.waiting == 0
