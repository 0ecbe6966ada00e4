"""The YADE process of the live DEM: ``yade -n -x -j1 yade_live.py`` and its two pipes.

:class:`YadeWorker` starts the worker script (:mod:`ow_dem_bridge.yade_live`, which runs inside
YADE) with a request pipe and a reply pipe, one JSON object per line each way (YADE's own output
goes to a log file). A reply that does not come within its timeout, a closed pipe or a refused
request raise :class:`~ow_dem_bridge.errors.DemRunError` naming the process, how it ended and
the tail of its log.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import subprocess
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ow_dem_bridge.errors import DemRunError

#: The worker script, run by YADE.
WORKER_SCRIPT = Path(__file__).with_name("yade_live.py")
#: Lines of the YADE log quoted in an error.
LOG_TAIL_LINES = 12


class YadeWorker:
    """One ``yade_live.py`` process and its two pipes (JSON lines).

    Args:
        executable: the YADE launcher.
        log_path: file for YADE's stdout and stderr.

    Raises:
        DemRunError: the process cannot be started.
    """

    def __init__(self, executable: str, log_path: Path) -> None:
        self.log_path = log_path
        log_path.parent.mkdir(parents=True, exist_ok=True)
        request_read, self._request_fd = os.pipe()
        self._reply_fd, reply_write = os.pipe()
        # YADE runs on the system Python; the venv's variables only make it warn.
        env = {k: v for k, v in os.environ.items() if k != "VIRTUAL_ENV"}
        env["OMP_NUM_THREADS"] = "1"
        cmd = [
            executable,
            "-n",
            "-x",
            "-j1",
            str(WORKER_SCRIPT),
            str(request_read),
            str(reply_write),
        ]
        try:
            with log_path.open("wb") as log:
                self.process = subprocess.Popen(
                    cmd,
                    stdin=subprocess.DEVNULL,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    pass_fds=(request_read, reply_write),
                    env=env,
                )
        except OSError as error:
            os.close(self._request_fd)
            os.close(self._reply_fd)
            msg = f"cannot start YADE ({' '.join(cmd)}): {error}"
            raise DemRunError(msg) from error
        finally:
            os.close(request_read)
            os.close(reply_write)
        self._buffer = b""
        self.closed = False

    @property
    def pid(self) -> int:
        """The YADE process id."""
        return int(self.process.pid)

    def log_tail(self) -> str:
        """The last lines of YADE's log."""
        try:
            lines = self.log_path.read_text(errors="replace").splitlines()
        except OSError:
            return "(no log)"
        return "\n".join(lines[-LOG_TAIL_LINES:])

    def _died(self, what: str) -> DemRunError:
        code = self.process.poll()
        if code is None:
            detail = "it stopped answering"
        elif code < 0:
            detail = f"it was killed by signal {-code}"
        else:
            detail = f"it exited with code {code}"
        msg = f"the YADE process (pid {self.pid}) {what}: {detail}; its log {self.log_path}:\n"
        return DemRunError(msg + self.log_tail())

    def send(self, request: Mapping[str, Any]) -> None:
        """Write one request (a JSON line).

        Raises:
            DemRunError: the process is gone.
        """
        data = (json.dumps(request, allow_nan=False) + "\n").encode()
        try:
            while data:
                written = os.write(self._request_fd, data)
                data = data[written:]
        except OSError as error:
            raise self._died(f"took no request ({error.strerror})") from error

    def receive(self, timeout_s: float) -> dict[str, Any]:
        """Read one reply.

        Raises:
            DemRunError: the process exited or did not answer within ``timeout_s`` (wall), or
                the reply says the request failed.
        """
        deadline = time.monotonic() + timeout_s
        while b"\n" not in self._buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                msg = f"did not answer within {timeout_s:g} s"
                raise self._died(msg)
            ready, _, _ = select.select([self._reply_fd], [], [], min(remaining, 1.0))
            if not ready:
                continue
            chunk = os.read(self._reply_fd, 1 << 16)
            if not chunk:
                self.process.wait(timeout=10.0)
                raise self._died("closed its pipe")
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\n", 1)
        reply = json.loads(line)
        if not reply.get("ok"):
            msg = f"YADE (pid {self.pid}) refused a request: {reply.get('error', reply)}"
            raise DemRunError(msg)
        return dict(reply)

    def call(self, request: Mapping[str, Any], timeout_s: float) -> dict[str, Any]:
        """Send one request and read its reply."""
        self.send(request)
        return self.receive(timeout_s)

    def close(self) -> None:
        """Ask the process to quit; kill it if it does not within 10 s (idempotent)."""
        if self.closed:
            return
        self.closed = True
        try:
            if self.process.poll() is None:
                self.send({"op": "quit"})
        except DemRunError:
            pass
        for fd in (self._request_fd, self._reply_fd):
            with contextlib.suppress(OSError):
                os.close(fd)
        try:
            self.process.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
