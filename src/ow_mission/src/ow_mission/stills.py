"""The report's stills (no ROS): the scene at the end of chosen steps, rendered from the bags in
a forked process while the report makes its other figures (each takes TinyRenderer about half a
second at 1024x768 with shadows: four of them were the report's longest piece of work). The
report renders them in the replay's pool of processes (:func:`ow_mission.replay.render_pool`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ow_description.terrain import HeightMap
from ow_mission.recording import Recording
from ow_mission.replay import release_free_memory, render_pool

#: What a still shows: the pose (rad by joint name) and the terrain (None: none recorded yet).
Scene = tuple[dict[str, float], HeightMap | None]

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
    _render_scenes([s.path for s in stills], _scenes(stills, recording), list(around))


def _scenes(stills: Sequence[Still], recording: Recording) -> list[Scene]:
    """What each still shows: the pose (rad by joint name) and the terrain at its time."""
    return [(recording.joints_at(s.t_s), recording.terrain_at(s.t_s)) for s in stills]


def _render_scenes(
    paths: Sequence[Path], scenes: Sequence[Scene], around: list[tuple[float, float, float]]
) -> None:
    from PIL import Image

    from ow_mission.render import SceneRenderer

    with SceneRenderer() as scene:
        for path, (joints, terrain) in zip(paths, scenes, strict=True):
            image = scene.picture(joints, terrain, around=around)
            Image.fromarray(image).save(path)
    release_free_memory()


class StillsRendering:
    """Stills being rendered by a forked process while the caller goes on; :meth:`finish`
    waits for them.

    Args:
        stills: what to render (:func:`plan_stills`).
        recording: the run's joint states and terrains.
        around: points the camera must see besides the arm (m, base_link).
        pool: the forked processes to render them in (:func:`ow_mission.replay.render_pool`,
            shared with the replay's frames: one pybullet client fewer than a process of their
            own); None starts a process for them alone.
    """

    def __init__(
        self,
        stills: Sequence[Still],
        recording: Recording,
        around: Iterable[tuple[float, float, float]],
        pool: ProcessPoolExecutor | None = None,
    ) -> None:
        self.stills = list(stills)
        for still in self.stills:
            still.path.parent.mkdir(parents=True, exist_ok=True)
        self._own_pool = pool is None
        self._pool = render_pool(1) if pool is None else pool
        # The scenes are taken from the recording here, so the task sent is a few poses and
        # terrains, not the recording.
        self._future = self._pool.submit(
            _render_scenes,
            [s.path for s in self.stills],
            _scenes(self.stills, recording),
            list(around),
        )

    def finish(self) -> list[Still]:
        """Wait for the stills; the stills written.

        Raises:
            RuntimeError: rendering them failed (the error is named) or wrote no file.
        """
        failure = ""
        try:
            self._future.result()
        except Exception as error:  # the worker's error, or its process died
            failure = f"rendering them failed: {type(error).__name__}: {error}"
        finally:
            if self._own_pool:
                self._pool.shutdown(wait=True)
        missing = [s.path.name for s in self.stills if not s.path.is_file()]
        if failure or missing:
            msg = (failure or "rendering them wrote no file") + (
                f"; missing: {', '.join(missing)}" if missing else ""
            )
            raise RuntimeError(msg)
        return self.stills

    def cancel(self) -> None:
        """Drop the stills if they have not started; a process of their own exits once done."""
        self._future.cancel()
        if self._own_pool:
            self._pool.shutdown(wait=False, cancel_futures=True)
