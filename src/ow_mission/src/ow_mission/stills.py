"""The report's stills (no ROS): the scene at the end of chosen steps, rendered from the bags in
a forked process while the report makes its other figures (each takes TinyRenderer about a
second at 1024x768 with shadows: four of them were the report's longest piece of work).
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ow_mission.recording import Recording
from ow_mission.replay import default_signals

#: Steps after which a still is rendered, and what it shows.
STILLS: dict[str, str] = {
    "guarded_move": "the scoop resting on the ground the guarded move found",
    "grind": "the grinder lifted out of the freshly ground trench",
    "dig_sample": "the scoop lifted out of the trench holding the sample",
    "deliver_sample": "the scoop tipped over the sample dock after the delivery",
}


@dataclass(frozen=True)
class Still:
    """One still: its figure role, its file, the time it shows (s, sim) and its caption."""

    role: str
    path: Path
    t_s: float
    caption: str


def plan_stills(renders: Path, steps: Sequence[Mapping[str, Any]]) -> list[Still]:
    """A still at the end of each of the report's ``steps`` (``report.json`` rows) named in
    :data:`STILLS`, in order: ``renders/NN_<step>.png``."""
    stills: list[Still] = []
    for step in steps:
        if step["step"] not in STILLS:
            continue
        index, t = len(stills), float(step["sim_end_s"])
        stills.append(
            Still(
                f"still_{index:02d}",
                renders / f"{index:02d}_{step['step']}.png",
                t,
                f"After {step['step']} (t = {t:.1f} s sim): {STILLS[step['step']]}"
                f"{'' if step['success'] else ' (the step FAILED)'}.",
            )
        )
    return stills


def render_stills(
    stills: Sequence[Still], recording: Recording, around: Iterable[tuple[float, float, float]]
) -> None:
    """Render and write each still (PNG), framed on the whole arm and the ``around`` points
    (m, base_link), with one renderer."""
    from PIL import Image

    from ow_mission.render import SceneRenderer

    points = list(around)
    with SceneRenderer() as scene:
        for still in stills:
            t = still.t_s
            image = scene.picture(recording.joints_at(t), recording.terrain_at(t), around=points)
            Image.fromarray(image).save(still.path)


def _render_in_child(
    stills: Sequence[Still], recording: Recording, around: list[tuple[float, float, float]]
) -> None:
    default_signals()
    render_stills(stills, recording, around)


class StillsRendering:
    """Stills being rendered by a forked process (fork: it starts at once, with the recording,
    without importing anything); :meth:`finish` waits for them.

    Args:
        stills: what to render (:func:`plan_stills`).
        recording: the run's joint states and terrains.
        around: points the camera must see besides the arm (m, base_link).
    """

    def __init__(
        self,
        stills: Sequence[Still],
        recording: Recording,
        around: Iterable[tuple[float, float, float]],
    ) -> None:
        self.stills = list(stills)
        for still in self.stills:
            still.path.parent.mkdir(parents=True, exist_ok=True)
        self._process = multiprocessing.get_context("fork").Process(
            target=_render_in_child, args=(self.stills, recording, list(around)), daemon=True
        )
        self._process.start()

    def finish(self) -> list[Still]:
        """Wait for the process; the stills it wrote.

        Raises:
            RuntimeError: the process failed (its traceback is on stderr) or wrote no file.
        """
        self._process.join()
        missing = [s.path.name for s in self.stills if not s.path.is_file()]
        if self._process.exitcode != 0 or missing:
            msg = f"the process rendering them exited with code {self._process.exitcode}" + (
                f"; missing: {', '.join(missing)}" if missing else ""
            )
            raise RuntimeError(msg)
        return self.stills

    def cancel(self) -> None:
        """Stop the process if it still runs."""
        if self._process.is_alive():
            self._process.terminate()
            self._process.join()
