"""What a mission's bags hold for its pictures, and the animated replay made from them (no ROS).

:func:`read_recording` reads the joint positions, the terrains and the ground-detector samples
of a run's (split) bags with rosbags; :func:`frame_times` picks the replay's frames;
:func:`make_replay` renders them with :class:`ow_mission.render.SceneRenderer` into a GIF with
a caption per frame.
"""

from __future__ import annotations

import bisect
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from rosbags.highlevel import AnyReader, AnyReaderError

from ow_lander.terrain import HeightMap
from ow_mission.errors import OwMissionError

FloatArray = npt.NDArray[np.float64]

JOINT_STATES_TOPIC = "/joint_states"
TERRAIN_TOPIC = "/sim/terrain"
DETECTOR_TOPIC = "/arm/ground_detector"
GUARDED_RESULT_TOPIC = "/guarded_move_result"


class ReplayError(OwMissionError):
    """The bags cannot be read, or lack what a figure needs."""


@dataclass(frozen=True)
class DetectorSample:
    """One ``/arm/ground_detector`` message (ow_msgs/GroundDetectorSignal).

    Attributes:
        t_s: s, simulation time of the sample.
        detector: "velocity" or "force".
        signal: m/s or N.
        moving_average: same unit.
        threshold: same unit.
        contact: True at the sample where contact was declared.
    """

    t_s: float
    detector: str
    signal: float
    moving_average: float
    threshold: float
    contact: bool


@dataclass
class Recording:
    """A run's bags, as the report's figures need them.

    Attributes:
        bags: the files read, in recording order.
        joint_t: (N,) s, stamps of ``/joint_states``.
        joint_names: names of the columns of ``joint_positions``.
        joint_positions: (N, n) rad.
        terrains: (stamp s, terrain) of every ``/sim/terrain`` message, in time order.
        detector: the ``/arm/ground_detector`` samples (empty when none was recorded).
        contacts: (stamp s, (3,) m) of successful ``/guarded_move_result`` messages.
    """

    bags: list[Path]
    joint_t: FloatArray
    joint_names: list[str]
    joint_positions: FloatArray
    terrains: list[tuple[float, HeightMap]] = field(default_factory=list)
    detector: list[DetectorSample] = field(default_factory=list)
    contacts: list[tuple[float, FloatArray]] = field(default_factory=list)

    def joints_at(self, t_s: float) -> dict[str, float]:
        """rad by name: the last joint state at or before ``t_s`` (the first one before it)."""
        i = max(int(np.searchsorted(self.joint_t, t_s, side="right")) - 1, 0)
        return dict(zip(self.joint_names, self.joint_positions[i].tolist(), strict=True))

    def terrain_at(self, t_s: float) -> HeightMap | None:
        """The last terrain published at or before ``t_s`` (the first one before it)."""
        if not self.terrains:
            return None
        stamps = [t for t, _ in self.terrains]
        i = max(bisect.bisect_right(stamps, t_s) - 1, 0)
        return self.terrains[i][1]


def _stamp_s(msg: Any) -> float:
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


def read_recording(bags: Sequence[Path]) -> Recording:
    """Read the joint states, terrains, detector samples and contacts of ``bags``.

    Terrains are stamped with their bag time (the receipt time on the simulation clock: the
    first, latched one may carry a zero header stamp).

    Raises:
        ReplayError: a bag is unreadable, or there is no ``/joint_states``.
    """
    wanted = {JOINT_STATES_TOPIC, TERRAIN_TOPIC, DETECTOR_TOPIC, GUARDED_RESULT_TOPIC}
    names: list[str] = []
    stamps: list[float] = []
    rows: list[FloatArray] = []
    recording = Recording(list(bags), np.zeros(0), [], np.zeros((0, 0)))
    try:
        with AnyReader(list(bags)) as reader:
            connections = [c for c in reader.connections if c.topic in wanted]
            for connection, bag_ns, raw in reader.messages(connections=connections):
                msg: Any = reader.deserialize(raw, connection.msgtype)
                topic = connection.topic
                if topic == JOINT_STATES_TOPIC:
                    if not names:
                        names = list(msg.name)
                    position = dict(zip(msg.name, msg.position, strict=False))
                    stamps.append(_stamp_s(msg))
                    rows.append(np.array([position.get(n, np.nan) for n in names]))
                elif topic == TERRAIN_TOPIC:
                    heights = np.asarray(msg.heights, dtype=np.float64).reshape(msg.rows, msg.cols)
                    terrain = HeightMap(heights, msg.resolution, msg.origin_x, msg.origin_y)
                    recording.terrains.append((bag_ns * 1e-9, terrain))
                elif topic == DETECTOR_TOPIC:
                    recording.detector.append(
                        DetectorSample(
                            _stamp_s(msg),
                            str(msg.detector),
                            float(msg.signal),
                            float(msg.moving_average),
                            float(msg.threshold),
                            bool(msg.contact),
                        )
                    )
                elif msg.success:
                    p = msg.position
                    recording.contacts.append((_stamp_s(msg), np.array([p.x, p.y, p.z])))
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        msg_text = f"cannot read {[str(b) for b in bags]}: {exc}"
        raise ReplayError(msg_text) from exc
    if not stamps:
        msg_text = f"no {JOINT_STATES_TOPIC} in {[str(b) for b in bags]}"
        raise ReplayError(msg_text)
    order = np.argsort(np.asarray(stamps), kind="stable")
    recording.joint_t = np.asarray(stamps)[order]
    recording.joint_names = names
    recording.joint_positions = np.vstack(rows)[order]
    recording.terrains.sort(key=lambda item: item[0])
    recording.detector.sort(key=lambda s: s.t_s)
    return recording


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
        seconds: s of wall time to make it.
        cpu_seconds: s of CPU time of this process to make it (the cost on a shared machine).
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


def caption_font(size: int) -> Any:
    """A TrueType font of ``size`` px (matplotlib's DejaVu Sans), PIL's default without one."""
    from matplotlib import font_manager
    from PIL import ImageFont

    try:
        return ImageFont.truetype(font_manager.findfont("DejaVu Sans"), size)
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
) -> ReplayResult:
    """Render the whole recording into an animated GIF at ``path``.

    The camera is fixed and framed on every pose of the replay plus the ``around`` points (m,
    base_link), so nothing leaves the picture; each frame's caption names the step and the
    simulation time.

    Args:
        recording: the run's bags (:func:`read_recording`).
        steps: (name, start s, end s) of the mission's steps.
        path: GIF to write.
        around: points the camera must also see (e.g. the trench).
        max_frames: upper bound of the frame count (the cost is ~linear in it).
        fps: frames per second of the GIF.
        width: px of the rendered scene.
        height: px of the rendered scene (the caption band is added above).
        title: first caption line of every frame.
        on_frame: called with (index, count) after each frame.

    Raises:
        ReplayError: no joint states to replay.
    """
    from ow_mission.render import SceneRenderer, fit_camera, scene_points, visible_terrain

    wall0, cpu0 = time.monotonic(), time.process_time()
    t0, t1 = float(recording.joint_t[0]), float(recording.joint_t[-1])
    times = frame_times(t0, t1, max_frames, min_step_s=0.1)
    font = caption_font(max(12, height // 26))
    images = []
    with SceneRenderer() as scene:
        extents = []
        for t in times:
            scene.set_joints(recording.joints_at(float(t)))
            extents.append(scene.robot_points())
        seen = scene_points(np.vstack(extents), around)
        camera = fit_camera(seen, width=width, height=height)
        cropped: dict[int, HeightMap] = {}
        for i, t in enumerate(times):
            scene.set_joints(recording.joints_at(float(t)))
            terrain = recording.terrain_at(float(t))
            if terrain is not None and id(terrain) not in cropped:
                cropped[id(terrain)] = visible_terrain(terrain, camera)
            scene.set_terrain(None if terrain is None else cropped[id(terrain)])
            lines = [title] if title else []
            lines.append(
                f"{step_at(steps, float(t))}   t = {t - t0:6.1f} s sim   frame {i + 1}/{len(times)}"
            )
            images.append(captioned(scene.render(camera, shadow=False), lines, font))
            if on_frame is not None:
                on_frame(i, len(times))
    images[0].save(
        path,
        save_all=True,
        append_images=images[1:],
        duration=round(1000.0 / fps),
        loop=0,
        optimize=False,
    )
    return ReplayResult(
        path,
        len(images),
        fps,
        images[0].width,
        images[0].height,
        time.monotonic() - wall0,
        time.process_time() - cpu0,
        t1 - t0,
    )
