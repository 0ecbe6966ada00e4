"""ow_faults.stream_order: an input waits until the pacing stream (the lock flags) has reached
its stamp less one period, so a status stamped later never misses a flag stamped earlier."""

import threading
import time

from ow_faults.stream_order import PacingStream


def test_nothing_paces_before_the_stream_has_arrived():
    assert PacingStream().wait_for(40.92, timeout_s=0.0)


def test_an_input_waits_for_the_flags_up_to_one_period_before_its_stamp():
    stream = PacingStream()
    stream.taken(39.0)
    stream.taken(39.01)
    assert not stream.wait_for(40.92, timeout_s=0.0)  # the flags of 39.02-40.91 still to come
    taken = []

    def flags() -> None:
        for k in range(2, 192):
            time.sleep(0.0005)
            taken.append(39.0 + k * 0.01)
            stream.taken(round(39.0 + k * 0.01, 2))

    thread = threading.Thread(target=flags)
    thread.start()
    assert stream.wait_for(40.92, timeout_s=10.0)
    assert taken[-1] >= 40.91 - 1e-9  # where a simulation standing at 40.92 has its newest
    thread.join()


def test_a_wait_that_runs_out_says_so():
    stream = PacingStream()
    stream.taken(1.0)
    stream.taken(1.01)
    assert not stream.wait_for(5.0, timeout_s=0.01)
