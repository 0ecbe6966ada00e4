"""The operating system's side of a node: its process group stopped (SIGINT, SIGTERM for a
process that ignores SIGINT, then SIGKILL), its log file and the end of it, and the memory of a
tree of processes. No ROS here: :mod:`ow_bringup.stack` starts the nodes with these."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
from collections.abc import Iterable
from pathlib import Path


def stop_process_group(proc: subprocess.Popen[bytes], timeout_s: float = 10.0) -> None:
    """SIGINT the process group (ROS nodes shut down cleanly on it), then SIGKILL it."""
    interrupt_process_group(proc)
    end_process_group(proc, timeout_s)


def interrupt_process_group(proc: subprocess.Popen[bytes]) -> None:
    """SIGINT the process group of a running process: a ROS node shuts down cleanly on it.

    A process that ignores SIGINT gets SIGTERM as well. A program inherits an ignored SIGINT
    from a parent started in the background (a shell gives its background jobs SIGINT
    ignored: ``nohup ... &``, a campaign's worker, some CI runners). rospy's nodes install a
    handler of their own whatever they inherited, but ``rosmaster`` (and a node still
    importing) would never see it: the harness waited its full timeout for the master, 10 s
    of every mission started that way, before killing it."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGINT)
            if ignores_signal(proc.pid, signal.SIGINT):
                os.killpg(proc.pid, signal.SIGTERM)


def ignores_signal(pid: int, signum: int) -> bool:
    """Whether process ``pid`` ignores signal ``signum`` (``SigIgn`` of ``/proc/<pid>/status``);
    False for a process that is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    for line in status.splitlines():
        if line.startswith("SigIgn:"):
            return bool(int(line.split()[1], 16) >> (signum - 1) & 1)
    return False


def end_process_group(proc: subprocess.Popen[bytes], timeout_s: float) -> None:
    """Wait up to ``timeout_s`` for an interrupted process to exit, then SIGKILL its group."""
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=timeout_s)
    # Children a node started (in its group) must not outlive it either.
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=timeout_s)


def new_log_path(log_dir: Path, name: str) -> Path:
    """``<log_dir>/<name>.log``, or ``<name>.<k>.log`` with the first k free: a node started
    again under its name (by a later test module on the same master, a restart) keeps the log
    of the one before."""
    path, k = log_dir / f"{name}.log", 0
    while path.exists():
        k += 1
        path = log_dir / f"{name}.{k}.log"
    return path


def log_tail(path: Path, lines: int = 40) -> str:
    """The last ``lines`` lines of a node's log, after its ``[FATAL]`` lines (a node's reason to
    stop, which what it logs while stopping may push out of the tail)."""
    try:
        text = path.read_text(errors="replace").splitlines()
    except OSError:
        return "(no log)"
    fatal = [line for line in text[:-lines] if line.startswith("[FATAL]")]
    return "\n".join([*fatal, *text[-lines:]])


def peak_memory_mb(roots: Iterable[int]) -> float:
    """MB, sum of the peak resident memory (VmHWM) of this process and of every process in the
    trees under ``roots`` (pids; a node started by rosrun is a process tree)."""
    pids = [os.getpid()]
    for root in roots:
        pids += process_tree(root)
    total_kb = 0
    for pid in pids:
        try:
            for line in Path(f"/proc/{pid}/status").read_text().splitlines():
                if line.startswith("VmHWM:"):
                    total_kb += int(line.split()[1])
        except OSError:
            continue
    return total_kb / 1024.0


def process_tree(pid: int) -> list[int]:
    out = [pid]
    try:
        children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return out
    for child in children:
        out += process_tree(int(child))
    return out
