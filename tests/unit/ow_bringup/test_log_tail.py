"""What the harness reports of a node's log when the node stops or is late."""

from ow_bringup.processes import log_tail


def test_the_reason_to_stop_leads_however_much_the_node_logged_after(tmp_path):
    log = tmp_path / "node.log"
    noise = [f"[ERROR] bad callback {k}" for k in range(100)]
    log.write_text("\n".join(["[INFO] ready", "[FATAL] battery: the reason", *noise]) + "\n")
    lines = log_tail(log, lines=40).splitlines()
    assert lines == ["[FATAL] battery: the reason", *noise[-40:]]


def test_a_short_log_is_given_whole_and_once(tmp_path):
    log = tmp_path / "node.log"
    text = ["[INFO] ready", "[FATAL] monitors: motor_efficiency = 2.0 is above 1", "done"]
    log.write_text("\n".join(text))
    assert log_tail(log, lines=40).splitlines() == text


def test_a_missing_log_says_so(tmp_path):
    assert log_tail(tmp_path / "absent.log") == "(no log)"
