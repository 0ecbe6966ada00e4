"""A run's figures made after its mission exits, by a process of their own (no ROS).

With ``figures: after_exit`` (the default) a mission writes its report's numbers before it exits:
:func:`ow_mission.report.write_run_report` with ``draw=False`` takes the energies, the trench,
the detector and the faults from the bags and writes ``report.json`` (marked
``figures_pending``) and ``report.md``. :func:`start_figures` then starts
``python -m ow_mission.figures RUN_DIR`` in a session of its own. That process draws the
figures from the same bags and rewrites both files with them (the same numbers: the same
code on the same bags). While it runs its pid is in ``figures.pid``; its output goes to
``figures.log``.

Who needs the figures waits for them: ``python -m ow_mission.figures --wait RUN_DIR``, or
:func:`wait_for_figures`.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeAlias

from ow_bringup.stack import NODE_ENVIRONMENT
from ow_mission.errors import FiguresError
from ow_mission.report_files import draw_command, left_to_draw

#: The figures' process output, in the run directory.
FIGURES_LOG = "figures.log"
#: Its pid while it runs, in the run directory.
PID_FILE = "figures.pid"
#: s of wall time between two looks at a run whose figures are pending.
POLL_S = 0.1

#: The process :func:`start_figures` starts.
FiguresProcess: TypeAlias = "subprocess.Popen[bytes]"


def start_figures(run_dir: Path, renders: bool) -> FiguresProcess:
    """Start the process that draws the figures of ``run_dir`` (its ``report.json`` written
    with ``draw=False``), in a session of its own: it outlives the caller and a signal to the
    caller's process group.

    Args:
        run_dir: the run directory.
        renders: also the stills and the replay.

    Returns:
        The process (the caller need not wait for it).
    """
    run_dir = Path(run_dir)
    # -OO: no docstrings in memory, as the stack's nodes (ow_bringup.stack.NODE_PYTHON_OPTIMIZE).
    command = [sys.executable, "-OO", "-m", "ow_mission.figures", str(run_dir)]
    if not renders:
        command.append("--no-renders")
    with (run_dir / FIGURES_LOG).open("wb") as log:
        proc = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            env={**NODE_ENVIRONMENT, **os.environ},  # as the nodes; a user's setting wins
        )
    (run_dir / PID_FILE).write_text(f"{proc.pid}\n")
    return proc


def _running(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, exited but not yet waited for, does not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _document(run_dir: Path) -> dict[str, Any]:
    document: dict[str, Any] = json.loads((run_dir / "report.json").read_text())
    return document


def figures_status(run_dir: Path) -> str:
    """Where the figures of ``run_dir`` are: "drawn" (or not pending: ``figures: inline``),
    "drawing" (their process runs), "not_drawn" (``figures: none``: nobody was to draw them)
    or "lost" (pending, and the process that was to draw them is gone)."""
    run_dir = Path(run_dir)
    document = _document(run_dir)
    if not document.get("figures_pending"):
        return "drawn"
    try:
        pid = int((run_dir / PID_FILE).read_text())
    except (OSError, ValueError):
        pid = None
    if pid is not None and _running(pid):
        return "drawing"
    # It may have finished between the two reads.
    if not _document(run_dir).get("figures_pending"):
        return "drawn"
    return "not_drawn" if pid is None and left_to_draw(document) else "lost"


def wait_for_figures(run_dir: Path, timeout_s: float = 600.0) -> dict[str, Any]:
    """Wait until the figures of ``run_dir`` are drawn (at once when they are not pending).

    Args:
        run_dir: a run directory with its ``report.json``.
        timeout_s: s of wall time to wait at most.

    Returns:
        ``report.json`` with the figures.

    Raises:
        FiguresError: the figures' process ended without writing them, or did not finish in
            time (the message says where its output is), or nobody was to draw them
            (``figures: none``: the message says how to).
    """
    run_dir = Path(run_dir)
    deadline = time.monotonic() + timeout_s
    while True:
        status = figures_status(run_dir)
        if status == "drawn":
            return _document(run_dir)
        if status == "not_drawn":
            msg = (
                f"the figures of {run_dir} were not drawn (its mission said figures: none); "
                f"draw them from its bags with `{draw_command(run_dir)}`"
            )
            raise FiguresError(msg)
        if status == "lost":
            msg = (
                f"the figures of {run_dir} are pending but no process is making them; its "
                f"output: {run_dir / FIGURES_LOG}. Draw them with "
                f"`python -m ow_mission.report {run_dir}`"
            )
            raise FiguresError(msg)
        if time.monotonic() > deadline:
            msg = (
                f"the figures of {run_dir} were not drawn within {timeout_s:g} s "
                f"(their output: {run_dir / FIGURES_LOG})"
            )
            raise FiguresError(msg)
        time.sleep(POLL_S)


def tell_figures(
    proc: FiguresProcess | None, run_dir: Path, wait: bool, say: Callable[[str], None]
) -> None:
    """Say where the report of ``run_dir`` is and where its figures are being made (``proc``,
    from :func:`start_figures`; None: they are in it); with ``wait``, wait for ``proc`` and say
    what it drew and what it could not."""
    say(f"[mission] report: {Path(run_dir) / 'report.md'}")
    if proc is None:
        try:
            status = figures_status(Path(run_dir))
        except (OSError, ValueError):  # no report.json to tell of
            return
        if status == "not_drawn":
            say(
                "[mission] figures: not drawn (figures: none); "
                f"`{draw_command(run_dir)}` draws them from the bags"
            )
        return
    log = Path(run_dir) / FIGURES_LOG
    if not wait:
        say(
            f"[mission] figures: being drawn by process {proc.pid} ({log}); "
            f"`python -m ow_mission.figures --wait {run_dir}` waits for them"
        )
        return
    say(f"[mission] waiting for the figures (process {proc.pid}, {log})")
    proc.wait()
    document = _document(Path(run_dir))
    notes = document.get("figure_notes") or {}
    say(f"[mission] figures: {len(document['figures'])} drawn, {len(notes)} not")
    for note in notes.values():
        say(f"[mission]   {note}")


def make_figures(run_dir: Path, renders: bool) -> int:
    """Draw the pending figures of ``run_dir`` and rewrite its report with them (what the
    process :func:`start_figures` starts does). Should that fail as a whole, the report says
    so instead of waiting for figures forever.

    Returns:
        The process's exit code: 0 when the report was rewritten with its figures.
    """
    from ow_mission.report import write_run_report
    from ow_mission.report_files import Figures, markdown, write_report_files

    run_dir = Path(run_dir)
    try:
        try:
            write_run_report(run_dir, _document(run_dir), renders=renders)
            return 0
        except Exception as exc:
            traceback.print_exc()
            document = _document(run_dir)
            document.pop("figures_pending", None)
            note = f"the figures could not be made: {type(exc).__name__}: {exc} (figures.log)"
            document["figure_notes"] = {**document.get("figure_notes", {}), "figures": note}
            figures = Figures(notes=dict(document["figure_notes"]))
            write_report_files(run_dir, document, markdown(run_dir, document, figures))
            return 1
    finally:
        (run_dir / PID_FILE).unlink(missing_ok=True)


USAGE = (
    "usage: python -m ow_mission.figures --wait RUN_DIR           (wait for a run's figures)\n"
    "       python -m ow_mission.figures RUN_DIR [--no-renders]   (draw its pending figures;\n"
    "                                      the stills and replay too if its mission renders)"
)


def main(argv: list[str] | None = None) -> int:
    """``python -m ow_mission.figures --wait RUN_DIR``: wait for a run's figures (1 when they
    will not come); ``python -m ow_mission.figures RUN_DIR [--no-renders]``: draw them (what
    :func:`start_figures` runs; the stills and the replay only if the run's mission renders)."""
    args = list(sys.argv[1:] if argv is None else argv)
    paths = [a for a in args if not a.startswith("--")]
    if len(paths) != 1 or set(args) - {*paths, "--no-renders", "--wait"}:
        print(USAGE)
        return 0 if args[:1] in (["-h"], ["--help"]) else 2
    if "--wait" in args:
        try:
            done = wait_for_figures(Path(paths[0]))
        except FiguresError as exc:
            print(f"[figures] {exc}", file=sys.stderr)
            return 1
        print(json.dumps({"figures": done["figures"], "notes": done["figure_notes"]}, indent=1))
        return 0
    run_dir = Path(paths[0])
    try:
        renders = bool((_document(run_dir).get("config") or {}).get("renders", True))
    except (OSError, ValueError) as exc:
        print(f"[figures] cannot read {run_dir / 'report.json'}: {exc}", file=sys.stderr)
        return 1
    return make_figures(run_dir, renders=renders and "--no-renders" not in args)


if __name__ == "__main__":
    sys.exit(main())
