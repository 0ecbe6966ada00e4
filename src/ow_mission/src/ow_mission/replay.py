"""The animated replay of a mission, made from its bags (no ROS).

:func:`frame_times` picks the replay's frames from a :class:`ow_mission.recording.Recording`;
:func:`make_replay` renders them with :class:`ow_mission.render.SceneRenderer` into a GIF with a
caption per frame, in worker processes (two by default: TinyRenderer and the GIF's
palette quantisation cost ~65 ms per frame); :func:`start_replay` starts that rendering and
returns, so that the caller can make other figures until :meth:`ReplayRendering.finish`.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import signal
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ow_description.terrain import HeightMap
from ow_mission.errors import ReplayError
from ow_mission.recording import FloatArray, Recording

if TYPE_CHECKING:
    from ow_mission.render import Camera

#: Colours of each frame's GIF palette.
PALETTE_COLORS = 256


def frame_times(t_start: float, t_end: float, max_frames: int, min_step_s: float) -> FloatArray:
    """Simulation times of a replay's frames: evenly spaced over [t_start, t_end], both ends
    included, at most ``max_frames`` and no closer than ``min_step_s`` (s).

    Raises:
        ReplayError: ``max_frames`` < 2, ``min_step_s`` <= 0 or an empty span.
    """
    if max_frames < 2 or min_step_s <= 0 or not t_end > t_start:
        msg = (
            f"cannot choose frames over [{t_start}, {t_end}] s with max_frames={max_frames}, "
            f"min_step_s={min_step_s}"
        )
        raise ReplayError(msg)
    # The epsilon keeps a span of exactly k steps at k + 1 frames despite rounding.
    n = min(max_frames, int(np.floor((t_end - t_start) / min_step_s + 1e-9)) + 1)
    return np.linspace(t_start, t_end, max(n, 2))


def step_at(steps: Sequence[tuple[str, float, float]], t_s: float) -> str:
    """Name of the step whose [start, end] (s) holds ``t_s``; "between steps" otherwise."""
    for name, start, end in steps:
        if start <= t_s <= end:
            return name
    return "between steps"


@dataclass(frozen=True)
class ReplayResult:
    """What :func:`make_replay` wrote.

    Attributes:
        path: the GIF.
        frames: number of frames.
        fps: frames per second of output.
        width: px.
        height: px.
        seconds: s of wall time to make it: choosing the frames, rendering them, writing the
            GIF (not the caller's own work between :func:`start_replay` and
            :meth:`ReplayRendering.finish`, while nothing rendered or the frames were ready).
        cpu_seconds: s of CPU time to make it, of this process and of the workers rendering the
            frames (the cost on a shared machine).
        sim_span_s: s of simulation time it covers.
    """

    path: Path
    frames: int
    fps: float
    width: int
    height: int
    seconds: float
    cpu_seconds: float
    sim_span_s: float


def caption_font_file() -> str:
    """The TrueType file of the captions: matplotlib's DejaVu Sans."""
    from matplotlib import font_manager

    return str(font_manager.findfont("DejaVu Sans"))


def caption_font(size: int, font_file: str | None = None) -> Any:
    """A TrueType font of ``size`` px from ``font_file`` (default :func:`caption_font_file`),
    PIL's default font when it cannot be loaded."""
    from PIL import ImageFont

    try:
        return ImageFont.truetype(font_file or caption_font_file(), size)
    except OSError:
        return ImageFont.load_default()


def captioned(image: npt.NDArray[np.uint8], lines: Iterable[str], font: Any) -> Any:
    """A PIL image of ``image`` with a dark band above it holding ``lines`` of text."""
    from PIL import Image, ImageDraw

    text = list(lines)
    line_h = int(font.size * 1.3) if hasattr(font, "size") else 14
    band = line_h * len(text) + 8
    out = Image.new("RGB", (image.shape[1], image.shape[0] + band), (25, 28, 34))
    out.paste(Image.fromarray(image), (0, band))
    draw = ImageDraw.Draw(out)
    for i, line in enumerate(text):
        draw.text((8, 4 + i * line_h), line, fill=(240, 240, 240), font=font)
    return out


@dataclass(frozen=True)
class _Frame:
    """What one frame of a replay shows: the pose (rad by joint name), the (cropped) terrain
    and the caption's lines."""

    joints: dict[str, float]
    terrain: HeightMap | None
    lines: list[str]


@dataclass(frozen=True)
class _Part:
    """Consecutive frames of a replay for one process to render, and how."""

    frames: list[_Frame]
    camera: Camera
    font_file: str
    font_size: int


@dataclass
class _Rendered:
    """A part's frames as palette-mode PIL images, with the s of CPU time its process spent
    on them and the time.monotonic() (s, system-wide) when they were done."""

    images: list[Any]
    cpu_s: float
    done_s: float


def _render_part(part: _Part, on_frame: Callable[[int], None] | None = None) -> _Rendered:
    """Render and caption ``part``'s frames in order with one :class:`SceneRenderer`, each turned
    into a palette image: the GIF's quantisation, done here so that workers share it. Uses only
    pybullet, numpy and PIL. ``on_frame`` is called with the index of each frame done."""
    from PIL import Image

    from ow_mission.render import SceneRenderer

    cpu0 = time.process_time()
    font = caption_font(part.font_size, part.font_file)
    images = []
    with SceneRenderer() as scene:
        for frame in part.frames:
            scene.set_joints(frame.joints)
            # The same object for consecutive frames: the heightfield is rebuilt on changes only.
            scene.set_terrain(frame.terrain)
            image = captioned(scene.render(part.camera, shadow=False), frame.lines, font)
            # Fast octree: a ninth of the median cut's time (16 ms a frame at 512 x 384, a
            # quarter of the workers' CPU time), and the same colours to the eye.
            images.append(image.quantize(PALETTE_COLORS, method=Image.Quantize.FASTOCTREE))
            if on_frame is not None:
                on_frame(len(images) - 1)
    release_free_memory()
    return _Rendered(images, time.process_time() - cpu0, time.monotonic())


def release_free_memory() -> None:
    """Give the C heap's free pages back to the system (glibc's ``malloc_trim``; nothing where
    there is none). A render process calls it once its pybullet client is closed: it then
    waits for the rest of the report holding ~20 MB instead of the ~90 MB its client and
    terrain reached (docs/history/performance-journal.md, eighth round)."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL("libc.so.6").malloc_trim(0)


def default_signals() -> None:
    """A forked worker (of the replay, of the stills) takes the default action on SIGINT and
    SIGTERM: the caller's handlers (rospy's shutdown) must not run in a copy of it."""
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_DFL)


def render_pool(workers: int) -> ProcessPoolExecutor:
    """``workers`` forked processes for renders (the replay's parts, the stills), each taking
    the default action on SIGINT and SIGTERM. fork: they start at once, without importing
    anything; a dead one fails its future (BrokenProcessPool) where a multiprocessing.Pool
    hangs. Each task makes its own pybullet client, so a process holds one at a time."""
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("fork"),
        initializer=default_signals,
    )


@dataclass(frozen=True)
class _Written:
    """What a process that rendered the whole replay and wrote its GIF sends back: the frame
    count and size (px), its CPU time on them (s) and the time.monotonic() when done."""

    frames: int
    width: int
    height: int
    cpu_s: float
    done_s: float


def _write_gif(images: Sequence[Any], path: Path, fps: float) -> None:
    images[0].save(
        path,
        save_all=True,
        append_images=images[1:],
        duration=round(1000.0 / fps),
        loop=0,
        optimize=False,
    )


def _render_gif(part: _Part, path: Path, fps: float) -> _Written:
    """Render the whole replay (one part) and write its GIF, in a render process: its frames
    never travel to the caller (~20 MB for the default mission's 160, twice while pickled)."""
    rendered = _render_part(part)
    cpu0 = time.process_time()
    _write_gif(rendered.images, path, fps)
    first = rendered.images[0]
    cpu_s = rendered.cpu_s + time.process_time() - cpu0
    return _Written(len(rendered.images), first.width, first.height, cpu_s, time.monotonic())


class ReplayRendering:
    """A replay whose frames are being rendered (:func:`start_replay`): :meth:`finish` collects
    them and writes the GIF, :meth:`cancel` drops them. As a context manager, it cancels what
    was not finished."""

    def __init__(
        self,
        path: Path,
        fps: float,
        sim_span_s: float,
        parts: list[_Part],
        on_frame: Callable[[int, int], None] | None,
        wall0: float,
        cpu0: float,
        pool: ProcessPoolExecutor | None = None,
    ) -> None:
        """Start rendering ``parts``, now: more than one in ``pool``'s processes (None: as many
        forked for them alone), one in ``pool``'s with its GIF written there, else in this
        process by :meth:`finish`."""
        self.path = path
        self._fps = fps
        self._sim_span_s = sim_span_s
        self._parts = parts
        self._on_frame = on_frame
        self._wall0 = wall0
        self._state = "started"
        self._executor: ProcessPoolExecutor | None = None
        self._own_executor = pool is None
        self._futures: list[Future[_Rendered]] = []
        self._written: Future[_Written] | None = None
        if len(parts) == 1 and pool is not None:
            self._executor = pool
            self._written = pool.submit(_render_gif, parts[0], path, fps)
        elif len(parts) > 1:
            self._executor = render_pool(len(parts)) if pool is None else pool
            self._futures = [self._executor.submit(_render_part, part) for part in parts]
        self._started_s = time.monotonic()
        self._start_wall_s = self._started_s - wall0
        self._start_cpu_s = time.process_time() - cpu0

    def __enter__(self) -> ReplayRendering:
        return self

    def __exit__(self, *exc: object) -> None:
        self.cancel()

    def cancel(self) -> None:
        """Drop the frames: parts not started are cancelled, workers exit after their part.
        Nothing once finished."""
        if self._state != "started":
            return
        self._state = "cancelled"
        for future in self._futures:
            future.cancel()
        if self._written is not None:
            self._written.cancel()
        if self._executor is not None and self._own_executor:
            self._executor.shutdown(wait=False, cancel_futures=True)

    def finish(self) -> ReplayResult:
        """Wait for the frames (with one process, render them now), then write the GIF.

        Raises:
            ReplayError: the replay was finished or cancelled already.
        """
        if self._state != "started":
            msg = f"the replay {self.path} was {self._state} already"
            raise ReplayError(msg)
        self._state = "finished"
        called_s, cpu0 = time.monotonic(), time.process_time()
        count = sum(len(part.frames) for part in self._parts)
        on_frame = self._on_frame
        if self._written is not None:
            return self._finish_written(self._written, called_s, cpu0, count)
        workers_cpu_s = 0.0  # with one process, the rendering is in this process's CPU time
        if self._executor is None:
            rendering_from_s = called_s
            report = None if on_frame is None else (lambda i: on_frame(i, count))
            rendered = [_render_part(self._parts[0], report)]
        else:
            rendering_from_s = self._started_s
            rendered = []
            try:
                for future in self._futures:
                    first = sum(len(r.images) for r in rendered)
                    rendered.append(future.result())
                    for i in range(first, first + len(rendered[-1].images)):
                        if on_frame is not None:
                            on_frame(i, count)
            finally:
                if self._own_executor:
                    self._executor.shutdown(wait=True, cancel_futures=True)
                else:
                    for future in self._futures:
                        future.cancel()
            workers_cpu_s = sum(r.cpu_s for r in rendered)
        images = [image for r in rendered for image in r.images]
        _write_gif(images, self.path, self._fps)
        written = _Written(
            len(images),
            images[0].width,
            images[0].height,
            workers_cpu_s,
            max(r.done_s for r in rendered),
        )
        return self._result(written, rendering_from_s, called_s, cpu0)

    def _finish_written(
        self, future: Future[_Written], called_s: float, cpu0: float, count: int
    ) -> ReplayResult:
        """:meth:`finish` of a replay a render process wrote."""
        written = future.result()
        if self._on_frame is not None:
            for i in range(count):
                self._on_frame(i, count)
        return self._result(written, self._started_s, called_s, cpu0)

    def _result(
        self, written: _Written, rendering_from_s: float, called_s: float, cpu0: float
    ) -> ReplayResult:
        """The replay's figures once its GIF is written: ``written.cpu_s`` is the CPU time of
        other processes (0 when this one rendered), ``written.done_s`` when the frames were
        ready. Its own time: choosing the frames, rendering them, collecting and writing them;
        not the caller's time between start and finish with nothing rendering or with the
        frames ready."""
        seconds = (
            self._start_wall_s
            + (written.done_s - rendering_from_s)
            + (time.monotonic() - max(called_s, written.done_s))
        )
        return ReplayResult(
            self.path,
            written.frames,
            self._fps,
            written.width,
            written.height,
            seconds,
            self._start_cpu_s + (time.process_time() - cpu0) + written.cpu_s,
            self._sim_span_s,
        )


def start_replay(
    recording: Recording,
    steps: Sequence[tuple[str, float, float]],
    path: Path,
    around: Iterable[tuple[float, float, float]] = (),
    max_frames: int = 160,
    fps: float = 12.0,
    width: int = 400,
    height: int = 300,
    title: str = "",
    on_frame: Callable[[int, int], None] | None = None,
    workers: int = 2,
    pool: ProcessPoolExecutor | None = None,
) -> ReplayRendering:
    """Choose the frames and the camera of the replay of the whole recording, and start
    rendering them; :meth:`ReplayRendering.finish` writes the GIF at ``path``.

    The camera is fixed and framed on every pose of the replay plus the ``around`` points (m,
    base_link), so nothing leaves the picture; each frame's caption names the step and the
    simulation time. With ``workers`` > 1 the frames are split into that many contiguous parts,
    each rendered (and quantised to the GIF's palette) by a forked process with its own pybullet
    client, while the caller goes on (e.g. with other figures) until it calls ``finish``; the GIF
    is the same as with one process, byte for byte.

    Args:
        recording: the run's bags (:func:`ow_mission.recording.read_recording`).
        steps: (name, start s, end s) of the mission's steps.
        path: GIF to write.
        around: points the camera must also see (e.g. the trench).
        max_frames: upper bound of the frame count (the cost is ~linear in it).
        fps: frames per second of the GIF.
        width: px of the rendered scene.
        height: px of the rendered scene (the caption band is added above).
        title: first caption line of every frame.
        on_frame: called with (index, count) for each frame, in order, once it is rendered (with
            workers, once its worker's part has arrived).
        workers: processes rendering the frames; 1 renders them in this process, in ``finish``.
            The workers run only pybullet, numpy and PIL, so the caller may have threads (rospy).
        pool: the processes to render the parts in (:func:`render_pool`, which the caller
            shuts down; e.g. shared with the stills); with ``workers`` = 1 the process renders
            every frame and writes the GIF itself. None forks ``workers`` for this replay alone
            when it is > 1.

    Raises:
        ReplayError: ``workers`` < 1.
    """
    from ow_mission.render import SceneRenderer, fit_camera, scene_points, visible_terrain

    if workers < 1:
        msg = f"workers={workers}: the replay needs at least 1 process to render its frames"
        raise ReplayError(msg)
    wall0, cpu0 = time.monotonic(), time.process_time()
    t0, t1 = float(recording.joint_t[0]), float(recording.joint_t[-1])
    times = frame_times(t0, t1, max_frames, min_step_s=0.1)
    with SceneRenderer() as scene:
        extents = []
        for t in times:
            scene.set_joints(recording.joints_at(float(t)))
            extents.append(scene.robot_points())
    camera = fit_camera(scene_points(np.vstack(extents), around), width=width, height=height)
    # By content: the recorder repeats the latched terrain at the start of every split file, and
    # a new object would rebuild the same heightfield. Each recorded terrain is keyed once.
    by_content: dict[tuple[Any, ...], HeightMap] = {}
    cropped: dict[int, HeightMap] = {}
    for _, recorded in recording.terrains:
        h = recorded.heights
        key = (h.shape, h.tobytes(), recorded.resolution, recorded.origin_x, recorded.origin_y)
        if key not in by_content:
            by_content[key] = visible_terrain(recorded, camera)
        cropped[id(recorded)] = by_content[key]
    frames = []
    for i, t in enumerate(times):
        terrain = recording.terrain_at(float(t))
        shown = None if terrain is None else cropped[id(terrain)]
        lines = [title] if title else []
        lines.append(
            f"{step_at(steps, float(t))}   t = {t - t0:6.1f} s sim   frame {i + 1}/{len(times)}"
        )
        frames.append(_Frame(recording.joints_at(float(t)), shown, lines))
    font_file, font_size = caption_font_file(), max(12, height // 26)
    parts = [
        _Part(frames[int(part[0]) : int(part[-1]) + 1], camera, font_file, font_size)
        for part in np.array_split(np.arange(len(frames)), min(workers, len(frames)))
    ]
    return ReplayRendering(path, fps, t1 - t0, parts, on_frame, wall0, cpu0, pool)


def make_replay(
    recording: Recording,
    steps: Sequence[tuple[str, float, float]],
    path: Path,
    around: Iterable[tuple[float, float, float]] = (),
    max_frames: int = 160,
    fps: float = 12.0,
    width: int = 400,
    height: int = 300,
    title: str = "",
    on_frame: Callable[[int, int], None] | None = None,
    workers: int = 2,
) -> ReplayResult:
    """Render the whole recording into an animated GIF at ``path``: :func:`start_replay` (see
    it for the arguments), then :meth:`ReplayRendering.finish`.

    Raises:
        ReplayError: ``workers`` < 1.
    """
    with start_replay(
        recording, steps, path, around, max_frames, fps, width, height, title, on_frame, workers
    ) as rendering:
        return rendering.finish()
