"""Start nodes as forks of a process that has imported them already: a fork server (no ROS).

A Python node spends most of its start-up importing (numpy, rospy and the messages, pybullet,
pinocchio, OMPL, ProgPy with scipy, pandas and matplotlib), and each holds its own copy of those
modules' objects: 60 to 200 MB per process. :class:`ForkServer` starts one process that imports
every module the node scripts import at their top level, once, and forks a child per node. The
children share those pages with the server and with each other until they write to them
(copy-on-write), and start without importing. The server imports script by script and serves a
request as soon as its script's modules are in: the first nodes start up while it imports the
later ones'.

A child is the node's program as ``rosrun`` runs it: its script run as ``__main__`` with the
node's argv and environment, in a session of its own (its process group is its pid), stdin
from ``/dev/null``, stdout and stderr into its log file. Its ``comm`` (what ``ps`` and ``top``
show) is the node's name. :class:`ForkedProcess` is its handle in the caller, with the ``pid``,
``poll``, ``wait`` and ``returncode`` of a :class:`subprocess.Popen`: the server reaps its
children and reports their exit codes.

    with ForkServer([script, ...]) as server:
        proc = server.start([script, "__name:=sim"], env, log_path)

Protocol (lines on the server's stdin and stdout): the server prints ``ready`` when it runs;
each request is a JSON object (``argv``, ``env``, ``log``), answered in order by ``pid <pid>``
(or ``error <message>``); ``exit <pid> <code>`` comes
whenever a child has exited (code < 0: the signal that killed it). The server exits when its
stdin closes; its children run on.
"""

from __future__ import annotations

import ast
import atexit
import contextlib
import ctypes
import ctypes.util
import gc
import importlib
import json
import os
import runpy
import select
import signal
import subprocess
import sys
import threading
import traceback
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import IO, NoReturn

from ow_mission.errors import HarnessError

#: s between two reaps of exited children while no request comes.
_REAP_PERIOD_S = 0.02
#: s of wall time a request may wait for its answer (the script's imports included).
_START_TIMEOUT_S = 120.0
#: prctl option that sets the calling thread's name (``comm``, 15 bytes).
_PR_SET_NAME = 15


def script_imports(script: Path) -> list[str]:
    """The modules ``script`` imports at its top level (``import a.b``: ``a.b``; ``from a.b
    import c``: ``a.b``). A catkin devel-space relay (``python_script = '...'``, run with
    ``exec``) stands for the script it names. Unreadable or unparsable: none."""
    try:
        tree = ast.parse(script.read_text())
    except (OSError, SyntaxError, ValueError):
        return []
    modules: list[str] = []
    for node in tree.body:
        if isinstance(node, ast.Import):
            modules += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            modules.append(node.module)
        elif (
            isinstance(node, ast.Assign)
            and [getattr(t, "id", None) for t in node.targets] == ["python_script"]
            and isinstance(node.value, ast.Constant)
            and isinstance(node.value.value, str)
        ):
            modules += script_imports(Path(node.value.value))
    return modules


class ForkedProcess:
    """A child of the fork server, as the caller sees it (a :class:`subprocess.Popen`'s
    ``pid``, ``returncode``, ``poll`` and ``wait``). It is asked for at once and forked once
    its script's imports are in the server: :attr:`pid` waits for that."""

    def __init__(self, server: ForkServer, request: int, script: str) -> None:
        self._server = server
        self._request = request
        self._script = script

    @property
    def pid(self) -> int:
        """The child's pid, once forked.

        Raises:
            HarnessError: the server could not fork it.
        """
        return self._server.pid_of(self._request, self._script)

    @property
    def returncode(self) -> int | None:
        """Its exit code once it has exited (negative: the signal that killed it), else None."""
        return self._server.exit_code(self.pid)

    def poll(self) -> int | None:
        """:attr:`returncode`."""
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        """Wait for it to exit; its exit code.

        Raises:
            subprocess.TimeoutExpired: still running after ``timeout`` s.
        """
        return self._server.wait_exit(self.pid, timeout)


class ForkServer:
    """A process that imports what ``scripts`` import, then forks a child per :meth:`start`.

    Args:
        scripts: node programs (a catkin relay or the script itself) whose imports to preload,
            in this order.
        env: the server's environment (default: this process's).
        timeout_s: s of wall time to wait for it to run.

    Raises:
        HarnessError: the server exited or did not answer within ``timeout_s``.
    """

    def __init__(
        self,
        scripts: Iterable[Path],
        env: Mapping[str, str] | None = None,
        timeout_s: float = 120.0,
    ) -> None:
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "ow_mission.forkserver", *map(str, scripts)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env={**(env if env is not None else os.environ), "PYTHONUNBUFFERED": "1"},
            text=True,
            bufsize=1,
        )
        self._lock = threading.Condition()
        self._replies: list[str] = []
        self._requests = 0  # sent
        self._answers: list[str] = []  # of the requests, in their order
        self._exits: dict[int, int] = {}
        self._closed = False
        self._reader = threading.Thread(target=self._read, name="forkserver", daemon=True)
        self._reader.start()
        reply = self._reply(timeout_s)
        if reply != "ready":
            self.close()
            msg = f"the fork server did not start: {reply}"
            raise HarnessError(msg)

    def __enter__(self) -> ForkServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _read(self) -> None:
        stdout = self._proc.stdout
        assert stdout is not None
        for line in stdout:
            kind, _, rest = line.strip().partition(" ")
            with self._lock:
                if kind == "exit":
                    pid, code = rest.split()
                    self._exits[int(pid)] = int(code)
                elif kind in ("pid", "error"):
                    self._answers.append(line.strip())
                else:
                    self._replies.append(line.strip())
                self._lock.notify_all()
        with self._lock:
            self._closed = True
            self._lock.notify_all()

    def _reply(self, timeout_s: float) -> str:
        with self._lock:
            if not self._lock.wait_for(lambda: self._replies or self._closed, timeout_s):
                return f"no answer within {timeout_s} s"
            if not self._replies:
                return f"it exited with {self._proc.wait()}"
            return self._replies.pop(0)

    def start(self, argv: Sequence[str], env: Mapping[str, str], log: Path) -> ForkedProcess:
        """Ask for a child that runs ``argv[0]`` (a Python script) as ``__main__`` with
        ``argv`` and ``env``, its output into ``log``. Returns at once: the server forks it
        once its script's imports are in (requests are served in order).

        Raises:
            HarnessError: the server is not running.
        """
        request = {"argv": list(argv), "env": dict(env), "log": str(log)}
        stdin = self._proc.stdin
        with self._lock:
            if stdin is None or self._closed:
                msg = "the fork server is not running"
                raise HarnessError(msg)
            stdin.write(json.dumps(request) + "\n")
            stdin.flush()
            self._requests += 1
            return ForkedProcess(self, self._requests - 1, str(argv[0]))

    def pid_of(self, request: int, script: str) -> int:
        """The pid of the child of request number ``request``, once the server has forked it.

        Raises:
            HarnessError: the server could not fork it, exited, or did not answer in time.
        """
        with self._lock:
            answered = self._lock.wait_for(
                lambda: len(self._answers) > request or self._closed, _START_TIMEOUT_S
            )
            answer = self._answers[request] if len(self._answers) > request else ""
        kind, _, value = answer.partition(" ")
        if kind != "pid":
            why = value or ("it exited" if answered else f"no answer in {_START_TIMEOUT_S} s")
            msg = f"the fork server could not start {script}: {why}"
            raise HarnessError(msg)
        return int(value)

    def exit_code(self, pid: int) -> int | None:
        """The exit code of child ``pid``, None while it runs."""
        with self._lock:
            return self._exits.get(pid)

    def wait_exit(self, pid: int, timeout: float | None) -> int:
        """Wait for child ``pid`` to exit; its exit code.

        Raises:
            subprocess.TimeoutExpired: still running after ``timeout`` s.
            HarnessError: the server exited first (nothing reports the child's end any more).
        """
        with self._lock:
            if not self._lock.wait_for(lambda: pid in self._exits or self._closed, timeout):
                raise subprocess.TimeoutExpired(f"fork server child {pid}", timeout or 0.0)
            if pid not in self._exits:
                msg = f"the fork server exited before its child {pid}"
                raise HarnessError(msg)
            return self._exits[pid]

    def close(self) -> None:
        """Close the server's stdin and wait for it to exit (its children run on)."""
        if self._proc.stdin is not None and not self._proc.stdin.closed:
            with contextlib.suppress(OSError):
                self._proc.stdin.close()
        try:
            self._proc.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        self._reader.join(timeout=10.0)


# ----------------------------------------------------------------------------- the server
def _serve(scripts: Sequence[str]) -> int | None:
    """The server's loop: returns None in the server when its stdin closes, and the exit code
    of the node in each child (which then exits as a Python program does).

    It answers ``ready`` at once. Requests are served in order, each as soon as its own
    script's modules are imported (now, if they were not); while none waits, the server
    imports the next of ``scripts``' modules. The first nodes start while the server imports
    the later ones'.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a terminal's Ctrl-C is the caller's to handle
    out = sys.stdout
    _say(out, "ready")
    todo = list(dict.fromkeys(scripts))
    imported: set[str] = set()
    lines = _Lines(sys.stdin.fileno())
    while True:
        _reap(out)
        waiting = lines.read(0.0 if todo else _REAP_PERIOD_S)
        if waiting is None:
            return None
        if not waiting:
            if todo:
                _import_script(todo.pop(0), imported)
            continue
        for line in waiting:
            code = _fork(line, imported, out)
            if code is not None:  # in the child
                return code


class _Lines:
    """Complete lines from a file descriptor, read without blocking beyond a timeout (a
    buffered reader would keep lines that select then never reports)."""

    def __init__(self, fd: int) -> None:
        self._fd = fd
        self._partial = b""

    def read(self, timeout_s: float) -> list[bytes] | None:
        """The lines complete within ``timeout_s`` (maybe none); None at end of file."""
        readable, _, _ = select.select([self._fd], [], [], timeout_s)
        if not readable:
            return []
        data = os.read(self._fd, 1 << 16)
        if not data:
            return None
        *complete, self._partial = (self._partial + data).split(b"\n")
        return complete


def _fork(line: bytes, imported: set[str], out: IO[str]) -> int | None:
    """Serve one request: None in the server, the node's exit code in the child."""
    try:
        request = json.loads(line)
        argv, env, log = list(request["argv"]), dict(request["env"]), str(request["log"])
        log_fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        script = argv[0]
    except (ValueError, KeyError, TypeError, OSError, IndexError) as error:
        _say(out, f"error {error!r}")
        return None
    _import_script(script, imported)
    gc.collect()
    gc.freeze()  # the collector of a child must not write to every page it shares
    # The child says when it leads its own process group: a caller signalling the group
    # (os.killpg(pid)) as soon as it has the pid must reach it.
    started_r, started_w = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(started_r)
        return _run_child(argv, env, log_fd, started_w)
    os.close(log_fd)
    os.close(started_w)
    os.read(started_r, 1)  # b"" if it died first
    os.close(started_r)
    _say(out, f"pid {pid}")
    return None


def _import_script(script: str, imported: set[str]) -> None:
    """Import what ``script`` imports at its top level, once."""
    if script in imported:
        return
    imported.add(script)
    for module in script_imports(Path(script)):
        with contextlib.suppress(Exception):  # the node reports its own import error
            importlib.import_module(module)


def _say(out: IO[str], line: str) -> None:
    out.write(line + "\n")
    out.flush()


def _reap(out: IO[str]) -> None:
    while True:
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return
        _say(out, f"exit {pid} {os.waitstatus_to_exitcode(status)}")


def _run_child(argv: list[str], env: dict[str, str], log_fd: int, started_fd: int) -> int:
    """In the forked child: become the node's process and run its script."""
    os.setsid()
    os.write(started_fd, b"s")
    os.close(started_fd)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.dup2(log_fd, 1)
    os.dup2(log_fd, 2)
    os.close(devnull)
    os.close(log_fd)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    os.environ.clear()
    os.environ.update(env)
    sys.argv = list(argv)
    name = next((a.split(":=", 1)[1] for a in argv if a.startswith("__name:=")), "")
    _set_comm(name or Path(argv[0]).name)
    try:
        runpy.run_path(argv[0], run_name="__main__")
    except SystemExit as done:
        code = done.code
        if code is None or isinstance(code, int):
            return code or 0
        print(code, file=sys.stderr)
        return 1
    except BaseException:
        traceback.print_exc()
        return 1
    return 0


def _set_comm(name: str) -> None:
    """Name the calling process (``/proc/<pid>/comm``: 15 bytes) where libc allows it."""
    with contextlib.suppress(OSError, AttributeError, TypeError):
        libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
        libc.prctl(_PR_SET_NAME, name.encode()[:15], 0, 0, 0)


def main(argv: Sequence[str] | None = None) -> NoReturn:
    """``python -m ow_mission.forkserver <module>...``: serve on stdin and stdout."""
    code = _serve(list(sys.argv[1:] if argv is None else argv))
    _exit(0 if code is None else code)


def _exit(code: int) -> NoReturn:
    """Leave as a Python program does (its non-daemon threads joined, then its ``atexit``
    functions, rospy's shutdown among them), but without the interpreter's teardown: freeing
    every object would write to every page a child shares with the server and the other
    children (in one default mission the stack's memory rose by 280 MB while it stopped), and
    extension modules count the frozen objects left then as leaked (OMPL's bindings print a
    page of it)."""
    current = threading.current_thread()
    for thread in threading.enumerate():
        if thread is not current and not thread.daemon:
            thread.join()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)


if __name__ == "__main__":
    main()
