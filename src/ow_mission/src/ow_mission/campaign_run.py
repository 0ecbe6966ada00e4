"""``rosrun ow_mission campaign <campaign.yaml | directory>``: run a campaign's missions (no rospy).

Each mission is ``rosrun ow_mission mission <dir>/missions/<k>/mission.yaml`` in a subprocess
(each starts its own private master on a free port). The local engine runs ``workers`` of them at
once with a thread pool; the Ray engine makes each a Ray task, run by whichever node takes it.
Each result is summarised where the mission ran (:func:`run_mission`: the run's ``report.json``,
the tool's final position per step and the ground-detection error, from the bags) and appended to
``results.jsonl`` as soon as it arrives; a mission with a line there is done, so running the
campaign again runs only the missing ones, and an interrupt loses no finished result.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from pathlib import Path
from typing import Any

import yaml

from ow_mission.campaign import (
    USAGE,
    CampaignConfig,
    mission_label,
    mission_yaml,
    parse_selection,
    sample_mission,
)
from ow_mission.errors import ConfigError
from ow_runtime.errors import ConfigError as AnyConfigError

RESULTS = "results.jsonl"
#: s of wall time an interrupted campaign waits for its Ray tasks to stop their missions.
STOP_WAIT_S = 30.0
#: A running mission's pid, in its directory (gone once it has stopped).
PID_FILE = "mission.pid"
_RUNNING: set[subprocess.Popen[bytes]] = set()
_RUNNING_LOCK = threading.Lock()


# ------------------------------------------------------------------------- campaign directory
def replay_command(mission_file: Path | str) -> str:
    """The one command that runs a campaign's mission again, alone."""
    return f"rosrun ow_mission mission {mission_file}"


def read_results(directory: Path) -> dict[int, dict[str, Any]]:
    """Mission number -> its result line in ``results.jsonl`` (the last one if repeated; a line
    cut short by a crash is ignored)."""
    results: dict[int, dict[str, Any]] = {}
    with contextlib.suppress(FileNotFoundError):
        for line in (Path(directory) / RESULTS).read_text().splitlines():
            with contextlib.suppress(ValueError, TypeError, KeyError):
                record = json.loads(line)
                results[int(record["index"])] = record
    return results


def missing(done: Mapping[int, Any], wanted: Iterable[int]) -> list[int]:
    """The missions of ``wanted`` without a result: what running the campaign again runs. A
    mission that failed has a result; one that crashed, timed out or was stopped before writing
    its report (``crashed``) has none."""
    return [k for k in wanted if k not in done or done[k].get("crashed")]


def append_result(directory: Path, record: dict[str, Any]) -> None:
    """Append one result line to ``results.jsonl`` in a single write, flushed to disk (after a
    newline if a crash left the last line unfinished)."""
    path = Path(directory) / RESULTS
    line = (json.dumps(record, sort_keys=True) + "\n").encode()
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        size = os.fstat(fd).st_size
        if size:
            with path.open("rb") as f:
                f.seek(size - 1)
                if f.read(1) != b"\n":
                    line = b"\n" + line
        os.write(fd, line)
        os.fsync(fd)
    finally:
        os.close(fd)


def prepare(config: CampaignConfig, raw_text: str) -> list[Path]:
    """Sample and validate every mission, then write the campaign directory: its
    ``campaign.yaml`` and each ``missions/<k>/mission.yaml``.

    Raises:
        ConfigError: a mission is not valid, or the directory holds a mission file sampled
            from another campaign (which would mix two campaigns' results).
    """
    texts = [mission_yaml(sample_mission(config, k)) for k in range(config.missions)]
    files = [config.mission_dir(k) / "mission.yaml" for k in range(config.missions)]
    for k, (text, path) in enumerate(zip(texts, files, strict=True)):
        if path.exists() and path.read_text() != text:
            msg = (
                f"{config.directory} holds mission {k} of another campaign ({path} differs): "
                "set campaign/directory to a new directory"
            )
            raise ConfigError(msg)
    config.directory.mkdir(parents=True, exist_ok=True)
    own = config.directory / "campaign.yaml"
    if not own.exists():
        own.write_text(raw_text)
    for text, path in zip(texts, files, strict=True):
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists():
            path.write_text(text)
    return files


# ------------------------------------------------------------------------------ one mission
def run_mission(task: dict[str, Any]) -> dict[str, Any]:
    """Run one mission in a subprocess and summarise it; what a worker (thread or Ray task)
    does. Never raises for a failed mission: the record says what failed.

    Args:
        task: ``index``, ``seed``, ``file`` (the mission file's path), ``text`` (its content,
            written there when missing: a Ray node without the campaign directory),
            ``timeout_s``.
    """
    path = Path(task["file"])
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists():
        path.write_text(task["text"])
    before = {p.name for p in path.parent.iterdir()}
    record: dict[str, Any] = {
        "index": task["index"],
        "seed": task["seed"],
        "mission_file": str(path),
        "command": replay_command(path),
        "host": socket.gethostname(),
        "success": False,
        "faults": len((yaml.safe_load(task["text"]) or {}).get("faults") or []),
    }
    started = time.monotonic()
    with (path.parent / "mission.log").open("ab") as log:
        proc = subprocess.Popen(
            ["rosrun", "ow_mission", "mission", str(path)],
            cwd=path.parent,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            preexec_fn=_default_signals,
        )
        with _RUNNING_LOCK:
            _RUNNING.add(proc)
        pid_file = path.parent / PID_FILE
        pid_file.write_text(f"{proc.pid}\n")
        try:
            record["exit_code"] = proc.wait(timeout=float(task["timeout_s"]))
        except subprocess.TimeoutExpired:
            record["exit_code"] = None
            record["error"] = f"no result within timeout_s = {task['timeout_s']:g} s (wall)"
        finally:
            stop(proc)
            pid_file.unlink(missing_ok=True)
    record["wall_time_s"] = time.monotonic() - started
    runs = [
        p for p in path.parent.iterdir() if p.name not in before and (p / "report.json").exists()
    ]
    if not runs:
        record.setdefault("error", f"the mission wrote no report.json; see {path.parent}")
        record["crashed"] = True
        return record
    record["run_dir"] = str(runs[-1])
    record.update(summarise_run(runs[-1]))
    return record


def _default_signals() -> None:
    """In the mission's process before it starts: no blocked or ignored stop signals (a Ray
    worker blocks some, and a mask or an ignored signal is inherited), so SIGTERM stops it."""
    signal.pthread_sigmask(signal.SIG_SETMASK, [])
    for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(number, signal.SIG_DFL)


def stop(proc: subprocess.Popen[bytes]) -> None:
    """Stop a mission subprocess: SIGTERM to its session (its harness then stops its nodes),
    SIGKILL after 20 s."""
    with _RUNNING_LOCK:
        _RUNNING.discard(proc)
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=20.0)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def summarise_run(run_dir: Path) -> dict[str, Any]:
    """What the campaign report needs of one run: its ``report.json`` numbers, and from its bags
    the tool's final position after each step and the ground-detection error (ground found
    minus the first terrain's height at the contact)."""
    from ow_description.description import GRINDER_TIP_FRAME, SCOOP_TIP_FRAME
    from ow_description.model import LanderModel
    from ow_mission.errors import ReplayError
    from ow_mission.mission import load_report
    from ow_mission.recording import read_recording

    report = load_report(run_dir)
    steps = [
        {
            "step": s["step"],
            "service": s["service"],
            "success": bool(s["success"]),
            "message": s["message"],
            "sim_time_s": float(s["sim_time_s"]),
            "sim_end_s": float(s["sim_end_s"]),
            "energy_wh": float(s["energy_wh"]),
            "mechanical_energy_j": float(s["mechanical_energy_j"]),
            "tool_frame": GRINDER_TIP_FRAME if "grind" in s["service"] else SCOOP_TIP_FRAME,
        }
        for s in report["steps"]
    ]
    summary: dict[str, Any] = {
        "success": bool(report["success"]),
        "failed_step": report["failed_step"],
        "error": report["error"],
        "sim_time_s": report["sim_time_s"],
        "ground_z": report["ground_z"],
        "steps": steps,
        "sample": report.get("sample"),
    }
    try:
        recording = read_recording(sorted((Path(run_dir) / "bags").glob("*.bag")))
    except ReplayError as exc:
        summary["summary_error"] = str(exc)
        return summary
    model = LanderModel()
    for step in steps:
        q = model.q_from(recording.joints_at(step["sim_end_s"]))
        step["final_tool_position"] = [float(v) for v in model.position(q, step["tool_frame"])]
    contact = next((s for s in report["steps"] if s.get("ground_position")), None)
    if contact is not None and recording.terrains:
        x, y, z = contact["ground_position"]
        truth = float(recording.terrains[0][1].height_at(x, y))
        summary["ground_truth_z"] = truth
        summary["ground_error_m"] = float(z) - truth
    return summary


# -------------------------------------------------------------------------------- engines
Sink = Callable[[dict[str, Any]], None]


def run_local(tasks: Sequence[dict[str, Any]], workers: int, sink: Sink) -> None:
    """Run the tasks ``workers`` at once in this machine's subprocesses; ``sink`` gets each
    record as it finishes. On an interrupt the running missions are stopped."""
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="mission")
    pending: set[Future[dict[str, Any]]] = {pool.submit(run_mission, t) for t in tasks}
    try:
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                sink(future.result())
    except BaseException:
        for future in pending:
            future.cancel()
        with _RUNNING_LOCK:
            running = list(_RUNNING)
        for proc in running:
            stop(proc)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def connect_ray(config: CampaignConfig) -> Any:
    """Import Ray and connect to ``config.address`` (``local`` starts an instance here with
    ``workers`` CPUs) before any mission starts.

    Raises:
        ConfigError: Ray is not installed, or the address does not answer (named).
    """
    try:
        import ray
    except ImportError as exc:
        msg = "campaign/engine = 'ray' needs the ray package (pip install -r requirements.txt)"
        raise ConfigError(msg) from exc
    address = config.address
    if address.startswith("ray://") or address not in ("local", "auto"):
        host, _, port = address.removeprefix("ray://").rpartition(":")
        try:
            socket.create_connection((host.strip("[]"), int(port)), timeout=5.0).close()
        except OSError as exc:
            msg = f"campaign/address = {address!r}: cannot connect to {host}:{port}: {exc}"
            raise ConfigError(msg) from exc
    try:
        if address == "local":
            cpus = config.workers or os.cpu_count() or 1
            ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        msg = f"campaign/address = {address!r}: no Ray cluster answers there: {exc}"
        raise ConfigError(msg) from exc
    return ray


def run_ray(ray: Any, tasks: Sequence[dict[str, Any]], cpus: float, sink: Sink) -> None:
    """Run each task as a Ray task (whichever node takes it); ``sink`` gets each record as
    ``ray.wait`` returns it. On an interrupt the unfinished tasks are cancelled (each stops
    its mission)."""
    remote = ray.remote(num_cpus=cpus, max_retries=0)(run_mission)
    pending = [remote.remote(t) for t in tasks]
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                sink(ray.get(ref))
    except BaseException:
        for ref in pending:
            with contextlib.suppress(Exception):
                ray.cancel(ref)
        # Each cancelled task stops its mission's stack (its pid file goes) before Ray's
        # workers go away: a worker killed first would leave the stack's nodes running.
        pid_files = [Path(t["file"]).parent / PID_FILE for t in tasks]
        deadline = time.monotonic() + STOP_WAIT_S
        while any(p.exists() for p in pid_files) and time.monotonic() < deadline:
            time.sleep(0.2)
        raise


# -------------------------------------------------------------------------------- progress
class Progress:
    """The progress line: counts and an ETA from the mean wall time of the missions finished
    in this run and the number running at once."""

    def __init__(self, total: int, done: int, to_run: int, parallel: int) -> None:
        self.total, self.done, self.to_run, self.parallel = total, done, to_run, max(parallel, 1)
        self.finished = 0
        self.failed = 0
        self.started = time.monotonic()

    def line(self) -> str:
        """``[campaign] 5/20 done (1 failed), 2 running, 13 waiting, ETA 3 min 10 s``."""
        left = self.to_run - self.finished
        running = min(left, self.parallel)
        eta = "?"
        if self.finished:
            per_mission = (time.monotonic() - self.started) / self.finished
            seconds = per_mission * left
            eta = f"{int(seconds // 60)} min {int(seconds % 60)} s"
        return (
            f"[campaign] {self.done + self.finished}/{self.total} done ({self.failed} failed "
            f"this run), {running} running, {left - running} waiting, ETA {eta}"
        )

    def update(self, record: dict[str, Any]) -> str:
        """Count one finished mission; the new line."""
        self.finished += 1
        self.failed += 0 if record.get("success") else 1
        return self.line()


# ------------------------------------------------------------------------------------- main
def run_campaign(
    config: CampaignConfig, raw_text: str, only: Iterable[int] | None = None
) -> dict[str, Any]:
    """Prepare the directory, run the missing missions (of ``only`` when given), write the
    report; the report's summary.

    Raises:
        ConfigError: bad missions, a foreign directory, an unreachable Ray address: before
            any mission starts.
        KeyboardInterrupt: passed on after the running missions are stopped.
    """
    from ow_mission.campaign_report import write_campaign_report

    files = prepare(config, raw_text)
    results = read_results(config.directory)
    wanted = range(config.missions) if only is None else only
    todo = missing(results, wanted)
    workers = config.workers or os.cpu_count() or 1
    ray = connect_ray(config) if config.engine == "ray" and todo else None
    tasks = [
        {
            "index": k,
            "seed": config.mission_seed(k),
            "file": str(files[k]),
            "text": files[k].read_text(),
            "timeout_s": config.timeout_s,
        }
        for k in todo
    ]
    done = len(results) - len(missing(results, results))  # crashed ones are not done
    progress = Progress(config.missions, done, len(todo), workers)
    print(
        f"[campaign] {config.name}: {done} of {config.missions} missions done, "
        f"{len(todo)} to run ({config.engine} engine) in {config.directory}",
        flush=True,
    )

    def sink(record: dict[str, Any]) -> None:
        append_result(config.directory, record)
        label = mission_label(record["index"], config.missions)
        verdict = "ok" if record.get("success") else f"FAILED: {record.get('error', '')[:160]}"
        print(f"[campaign] mission {label}: {verdict}", flush=True)
        print(progress.update(record), flush=True)

    try:
        if ray is None:
            run_local(tasks, workers, sink)
        else:
            run_ray(ray, tasks, config.cpus_per_mission, sink)
    finally:
        if ray is not None:
            ray.shutdown()
    return write_campaign_report(config.directory, config, read_results(config.directory))


def main(argv: list[str] | None = None) -> int:
    """``rosrun ow_mission campaign <file | directory> [--missions 0,2-4]``: 0 when every mission
    succeeded, 1 when some failed, 2 for bad input, 130 when interrupted."""
    args = [a for a in (sys.argv[1:] if argv is None else argv) if ":=" not in a]
    if not args or args[0] in ("-h", "--help"):
        print(USAGE)
        return 0 if args else 2
    only: list[int] | None = None
    # A job killed (SIGTERM) stops its running missions as Ctrl-C does.
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        if len(args) == 3 and args[1] == "--missions":
            selection = args[2]
        elif len(args) != 1:
            msg = f"unexpected arguments: {' '.join(args[1:])}\n{USAGE}"
            raise ConfigError(msg)
        path = Path(args[0])
        config = CampaignConfig.load(path)
        if len(args) == 3:
            only = parse_selection(selection, config.missions)
        raw_text = (path / "campaign.yaml" if path.is_dir() else path).read_text()
        summary = run_campaign(config, _pinned(raw_text, config), only)
    except AnyConfigError as exc:
        print(f"campaign: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("[campaign] interrupted: finished missions are kept; run again to resume")
        return 130
    print(f"[campaign] report: {config.directory / 'report.md'}")
    return 0 if summary["missions_failed"] == 0 else 1


def _pinned(raw_text: str, config: CampaignConfig) -> str:
    """The campaign file as the campaign directory keeps it: its text, with the directory and
    the base mission as absolute paths (so the directory alone resumes it)."""
    raw = yaml.safe_load(raw_text) or {}
    raw["directory"] = str(config.directory)
    if "base" in raw:
        raw["base"] = str(config.base)
    return yaml.safe_dump(raw, sort_keys=False)
