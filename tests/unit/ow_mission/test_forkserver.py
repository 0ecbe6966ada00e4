"""The fork server on its own (no ROS): what it preloads, and its children as a program's
process (argv, environment, output, process group, name, exit codes)."""

from __future__ import annotations

import os
import signal
import subprocess
import textwrap
from pathlib import Path

import pytest

from ow_mission.errors import HarnessError
from ow_mission.forkserver import ForkServer, script_imports

CHILD = textwrap.dedent(
    """\
    import sys
    print("preloaded", "wave" in sys.modules)
    import os
    import wave
    print("argv", " ".join(sys.argv[1:]))
    print("env", os.environ.get("FORKSERVER_TEST"), os.environ.get("ONLY_IN_SERVER"))
    print("group", os.getpgid(0) == os.getpid())
    print("comm", open("/proc/self/comm").read().strip())
    print("stdin", sys.stdin.read() == "")
    sys.stdout.flush()
    if "sleep" in sys.argv:
        import time
        time.sleep(60)
    sys.exit(int(sys.argv[1]))
    """
)


def _lines(path: Path) -> dict[str, str]:
    return dict(line.split(" ", 1) for line in path.read_text().splitlines() if " " in line)


@pytest.fixture
def script(tmp_path: Path) -> Path:
    path = tmp_path / "child"
    path.write_text(CHILD)
    return path


def test_the_top_level_imports_of_a_script_and_of_the_one_a_catkin_relay_names(tmp_path):
    script = tmp_path / "node"
    script.write_text("import sys, os.path\nfrom ow_x.y_node import main\nfrom . import z\n")
    relay = tmp_path / "relay"
    relay.write_text(f"python_script = '{script}'\nexec(compile('', 'x', 'exec'))\n")
    broken = tmp_path / "broken"
    broken.write_text("import (\n")
    assert script_imports(script) == ["sys", "os.path", "ow_x.y_node"]
    assert script_imports(relay) == ["sys", "os.path", "ow_x.y_node"]
    assert script_imports(broken) == []
    assert script_imports(tmp_path / "missing") == []


def test_a_child_runs_the_script_as_its_own_program(script, tmp_path):
    env = dict(os.environ, FORKSERVER_TEST="child's")
    log = tmp_path / "child.log"
    with ForkServer([script], env=dict(os.environ, ONLY_IN_SERVER="x")) as server:
        proc = server.start([str(script), "3", "__name:=forked_node"], env, log)
        assert proc.wait(timeout=30) == 3
        assert proc.poll() == proc.returncode == 3
    lines = _lines(log)
    assert lines["preloaded"] == "True"  # imported by the server before the fork
    assert lines["argv"] == "3 __name:=forked_node"
    assert lines["env"] == "child's None"  # the request's environment, not the server's
    assert lines["group"] == "True"  # a session of its own: the stack signals its group
    assert lines["comm"] == "forked_node"
    assert lines["stdin"] == "True"


def test_children_run_side_by_side_and_a_signal_ends_one_with_its_number(script, tmp_path):
    with ForkServer([script]) as server:
        slow = server.start([str(script), "0", "sleep"], dict(os.environ), tmp_path / "slow.log")
        quick = server.start([str(script), "0"], dict(os.environ), tmp_path / "quick.log")
        assert quick.wait(timeout=30) == 0
        assert slow.poll() is None
        with pytest.raises(subprocess.TimeoutExpired):
            slow.wait(timeout=0.2)
        os.killpg(slow.pid, signal.SIGTERM)
        assert slow.wait(timeout=30) == -signal.SIGTERM


def test_a_script_that_raises_exits_1_with_its_traceback_in_its_log(tmp_path):
    script = tmp_path / "raises"
    script.write_text("raise RuntimeError('the node failed')\n")
    log = tmp_path / "raises.log"
    with ForkServer([script]) as server:
        assert server.start([str(script)], dict(os.environ), log).wait(timeout=30) == 1
    assert "RuntimeError: the node failed" in log.read_text()


def test_a_log_that_cannot_be_opened_is_an_error_and_the_server_goes_on(script, tmp_path):
    with ForkServer([script]) as server:
        failed = server.start([str(script), "0"], dict(os.environ), tmp_path / "no" / "dir.log")
        after = server.start([str(script), "5"], dict(os.environ), tmp_path / "ok.log")
        with pytest.raises(HarnessError, match=r"could not start .*child.*No such file"):
            failed.poll()
        assert after.wait(30) == 5


def test_requests_sent_together_are_served_in_order(script, tmp_path):
    """The caller does not wait for one child before asking for the next."""
    with ForkServer([script]) as server:
        children = [
            server.start([str(script), str(code)], dict(os.environ), tmp_path / f"{code}.log")
            for code in range(6)
        ]
        assert [child.wait(30) for child in children] == list(range(6))
        assert len({child.pid for child in children}) == 6


def test_children_outlive_a_closed_server(script, tmp_path):
    server = ForkServer([script])
    child = server.start([str(script), "0", "sleep"], dict(os.environ), tmp_path / "c.log")
    server.close()
    os.kill(child.pid, 0)  # still running
    os.killpg(child.pid, signal.SIGKILL)
    with pytest.raises(HarnessError, match="not running"):
        server.start([str(script), "0"], dict(os.environ), tmp_path / "d.log")


def test_a_server_that_cannot_start_says_so(tmp_path):
    with pytest.raises(HarnessError, match="did not start"):
        ForkServer([], env={"PATH": "", "PYTHONPATH": str(tmp_path)}, timeout_s=30)
