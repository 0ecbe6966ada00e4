"""Timed joint trajectories: time parameterisation, CSV files, the node's trajectory directory.

A plan is a list of :class:`PathSegment` (joint waypoints with a label and a :class:`Speed`). It
is timed by :func:`time_parameterize`, which gives each speed class its fraction of the velocity
limits, into a :class:`Trajectory` sampled every ``sample_period_s``, written as CSV by
:class:`TrajectoryStore`.

CSV format (one file per operation, UTF-8, comma separated)::

    # ow_lander trajectory v1
    # operation: grind
    time,segment,j_shou_yaw,...,j_scoop_yaw,v_j_shou_yaw,...,v_j_scoop_yaw
    0.000000,approach,-0.028990,...

Comment lines start with ``#``. ``time`` is s from the start of the trajectory, ``segment`` the
label of the motion the row belongs to (e.g. ``approach``, ``pass_1``, ``guarded``), then one
position column (rad) per joint named in the header and one velocity column (rad/s) per joint,
prefixed ``v_``. Between consecutive rows playback follows the cubic Hermite spline through both
rows' positions and velocities (:class:`Spline`): the one interpolation of the simulation's joint
trajectory controller and of the arm services' execution monitor and set-point streaming.
"""

from __future__ import annotations

import bisect
import contextlib
import enum
import functools
import json
import os
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ow_description.errors import TrajectoryError

FloatArray = npt.NDArray[np.float64]

FORMAT_LINE = "# ow_lander trajectory v1"
MANIFEST_NAME = ".ow_lander_manifest.json"
#: rad, a direction change between waypoint steps above this makes the arm stop at the waypoint.
CORNER_ANGLE_RAD = 0.35


class Spline:
    """Piecewise cubic Hermite interpolation through rows of positions and velocities (linear
    when there are no velocities), held at the first row before it and at the last after it.

    Sampled every physics step by the simulation, so the row times are kept as Python floats:
    scalar arithmetic and :func:`bisect.bisect_right` on them are cheaper than numpy scalars
    and ``searchsorted``, with the same values.

    Args:
        times: (n,) s, strictly increasing.
        positions: (n, k) rad.
        velocities: (n, k) rad/s, or None for linear interpolation.
    """

    def __init__(
        self, times: FloatArray, positions: FloatArray, velocities: FloatArray | None
    ) -> None:
        self._times: list[float] = np.asarray(times, dtype=np.float64).tolist()
        self._pos = positions
        self._vel = velocities

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Positions (k,) rad and velocities (k,) rad/s at time ``t`` (s, the rows' time base).

        Outside the rows: the first or last row's positions and zero velocities.
        """
        times = self._times
        if t <= times[0]:
            return self._pos[0].copy(), np.zeros(self._pos.shape[1])
        if t >= times[-1]:
            return self._pos[-1].copy(), np.zeros(self._pos.shape[1])
        i = bisect.bisect_right(times, t) - 1
        h = times[i + 1] - times[i]
        s = (t - times[i]) / h
        p0, p1 = self._pos[i], self._pos[i + 1]
        if self._vel is None:
            return p0 + s * (p1 - p0), (p1 - p0) / h
        v0, v1 = self._vel[i] * h, self._vel[i + 1] * h
        h00, h10, h01, h11 = (
            2 * s**3 - 3 * s**2 + 1,
            s**3 - 2 * s**2 + s,
            -2 * s**3 + 3 * s**2,
            s**3 - s**2,
        )
        d00, d10, d01, d11 = (
            6 * s**2 - 6 * s,
            3 * s**2 - 4 * s + 1,
            -6 * s**2 + 6 * s,
            3 * s**2 - 2 * s,
        )
        position = h00 * p0 + h10 * v0 + h01 * p1 + h11 * v1
        velocity = (d00 * p0 + d10 * v0 + d01 * p1 + d11 * v1) / h
        return position, velocity


class Speed(enum.Enum):
    """How fast a segment may move; timing gives each class its fraction of the velocity limits
    (the arm services: ``timing/velocity_scale``, ``dig_velocity_scale``,
    ``guarded_velocity_scale``)."""

    #: Free space: approaches, retracts, lifts, stowing, pouring.
    FREE = "free"
    #: A tool in the ground: trench passes, cuts, sweeps.
    DIG = "dig"
    #: The guarded descent searching for the ground.
    GUARDED = "guarded"


@dataclass(frozen=True)
class PathSegment:
    """A geometric path: joint waypoints the arm passes through, with straight lines between.

    Attributes:
        label: name of the motion, e.g. ``approach`` or ``pass_1``.
        waypoints: (n, k) rad, n >= 1 joint vectors, columns in the order of the plan's joints.
        speed: the speed class of the motion, which timing turns into a velocity scale.
    """

    label: str
    waypoints: FloatArray
    speed: Speed = Speed.FREE


@dataclass(frozen=True)
class Trajectory:
    """A timed joint trajectory.

    Attributes:
        joints: joint names, the columns of ``positions`` and ``velocities``.
        times: (n,) s from the start, strictly increasing, times[0] == 0.
        positions: (n, k) rad.
        velocities: (n, k) rad/s.
        segments: (n,) label of the segment each row belongs to.
        operation: name of the operation that planned it.
    """

    joints: tuple[str, ...]
    times: FloatArray
    positions: FloatArray
    velocities: FloatArray
    segments: tuple[str, ...]
    operation: str = ""

    @property
    def duration(self) -> float:
        """s, time of the last row."""
        return float(self.times[-1])

    @functools.cached_property
    def spline(self) -> Spline:
        """The rows' cubic Hermite spline: what the simulation's trajectory controller follows."""
        return Spline(self.times, self.positions, self.velocities)

    def sample(self, t: float) -> FloatArray:
        """(k,) rad, positions at time ``t`` (s) on :attr:`spline`, clamped at both ends."""
        return self.spline.sample(t)[0]

    def segment_at(self, t: float) -> str:
        """Label of the segment running at time ``t`` (s)."""
        i = int(np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 1))
        return self.segments[i]

    def with_pause(self, at: float, pause: float) -> Trajectory:
        """A copy that holds still for ``pause`` s at the first row at or after ``at`` s.

        Used to let the arm settle before a guarded descent (OceanWATERS waits 2 s).
        """
        i = int(np.searchsorted(self.times, at - 1e-9))
        if pause <= 0 or i >= len(self.times):
            return self
        velocities = self.velocities.copy()
        velocities[i] = 0.0
        return Trajectory(
            self.joints,
            np.concatenate([self.times[: i + 1], self.times[i:] + pause]),
            np.vstack([self.positions[: i + 1], self.positions[i:]]),
            np.vstack([velocities[: i + 1], velocities[i:]]),
            (*self.segments[: i + 1], *self.segments[i:]),
            self.operation,
        )

    def segment_span(self, label: str) -> tuple[float, float] | None:
        """(first, last) time (s) of the rows of segment ``label``, or None if absent."""
        rows = [i for i, s in enumerate(self.segments) if s == label]
        if not rows:
            return None
        return float(self.times[rows[0]]), float(self.times[rows[-1]])

    def steady_span(self, label: str, ramp_step: float = 0.02) -> tuple[float, float] | None:
        """(first, last) time (s) of the cruise of segment ``label``: after its acceleration
        ramp, before its braking ramp, where the paper's guarded descent is steady. A ramp is
        a run of rows whose joint speed (norm of the velocity row) changes by more than
        ``ramp_step`` times the segment's top speed from one row to the next (along a Cartesian
        line the speed drifts slowly, on a ramp it changes by a * dt per row); rows at rest
        before the ramp (a settle pause) are skipped. None if the segment is absent."""
        rows = np.array([i for i, s in enumerate(self.segments) if s == label], dtype=np.intp)
        if len(rows) == 0:
            return None
        speed = np.linalg.norm(self.velocities[rows], axis=1)
        step = ramp_step * float(speed.max())
        first, last = 0, len(rows) - 1
        while first < last and speed[first + 1] <= step:  # at rest (e.g. a settle pause)
            first += 1
        while first < last and speed[first + 1] - speed[first] > step:
            first += 1
        while last > first and speed[last - 1] - speed[last] > step:
            last -= 1
        return float(self.times[rows[first]]), float(self.times[rows[last]])


def _split_at_corners(points: FloatArray, scale: FloatArray) -> list[FloatArray]:
    """Split a polyline where its direction (in velocity-normalised joint space) turns sharply."""
    steps = np.diff(points, axis=0) / scale
    norms = np.linalg.norm(steps, axis=1)
    keep = norms > 1e-12
    points = np.vstack([points[:1], points[1:][keep]])
    steps = steps[keep]
    norms = norms[keep]
    pieces = []
    start = 0
    for i in range(1, len(steps)):
        cos = float(steps[i - 1] @ steps[i]) / (norms[i - 1] * norms[i])
        if np.arccos(np.clip(cos, -1.0, 1.0)) > CORNER_ANGLE_RAD:
            pieces.append(points[start : i + 1])
            start = i
    pieces.append(points[start:])
    return pieces


def _trapezoid(length: float, v: float, a: float) -> tuple[float, float, float]:
    """(ramp time, cruise time, peak rate) of a rest-to-rest trapezoid over ``length``."""
    t_ramp = v / a
    if a * t_ramp**2 >= length:  # never reaches v: triangle
        t_ramp = float(np.sqrt(length / a))
        return t_ramp, 0.0, a * t_ramp
    return t_ramp, (length - a * t_ramp**2) / v, v


def time_parameterize(
    segments: Sequence[PathSegment],
    joints: Sequence[str],
    velocity_limits: FloatArray,
    acceleration_limits: FloatArray,
    sample_period_s: float,
    operation: str = "",
    speed_scales: Mapping[Speed, float] | None = None,
) -> Trajectory:
    """Time a plan: rest-to-rest trapezoids along each straight-ish piece of each segment.

    Every piece (a segment split where it turns sharply) is traversed with all joints
    synchronised along the path: the path rate is limited so that no joint exceeds its velocity
    limit times the scale of the segment's speed class nor its acceleration limit (on straight
    lines; at the shallow bends of a Cartesian path the acceleration can exceed it slightly).

    Args:
        segments: the plan, in order; each segment starts where the previous one ended.
        joints: names of the k joints (columns of the waypoints).
        velocity_limits: (k,) rad/s, URDF velocity limits.
        acceleration_limits: (k,) rad/s^2.
        sample_period_s: s, time between output rows (segment ends are always rows).
        operation: stored in the trajectory.
        speed_scales: fraction (0, 1] of the velocity limits for each speed class; None: the
            full limits for every class.

    Returns:
        The timed trajectory; its first row is the first waypoint at t = 0.

    Raises:
        TrajectoryError: empty plan, or waypoints with the wrong number of joints.
    """
    vmax = np.asarray(velocity_limits, dtype=np.float64)
    amax = np.asarray(acceleration_limits, dtype=np.float64)
    if not segments:
        msg = "cannot time an empty plan"
        raise TrajectoryError(msg)
    times: list[float] = [0.0]
    first = np.asarray(segments[0].waypoints, dtype=np.float64)
    positions: list[FloatArray] = [first[0]]
    velocities: list[FloatArray] = [np.zeros(len(joints))]
    labels: list[str] = [segments[0].label]
    t0 = 0.0
    for segment in segments:
        points = np.asarray(segment.waypoints, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != len(joints):
            msg = (
                f"segment {segment.label!r} has waypoints of shape {points.shape}, "
                f"expected (n, {len(joints)})"
            )
            raise TrajectoryError(msg)
        v_scaled = vmax * (1.0 if speed_scales is None else speed_scales[segment.speed])
        if len(points) < 2:
            continue
        for piece in _split_at_corners(points, v_scaled):
            if len(piece) < 2:
                continue
            # Path parameter s = time at full speed: piece i takes max_j |dq_j| / v_j.
            ds = np.max(np.abs(np.diff(piece, axis=0)) / v_scaled, axis=1)
            s_knots = np.concatenate([[0.0], np.cumsum(ds)])
            length = float(s_knots[-1])
            if length <= 0.0:
                continue
            # ds/dt <= 1 keeps every joint within its velocity limit; dq/ds <= v_j, so
            # d2s/dt2 <= min(a_j / v_j) keeps it within its acceleration limit.
            a_s = float(np.min(amax / v_scaled))
            t_ramp, t_cruise, peak = _trapezoid(length, 1.0, a_s)
            total = 2 * t_ramp + t_cruise
            n = max(2, int(np.ceil(total / sample_period_s)) + 1)
            for t in np.linspace(0.0, total, n)[1:]:
                if t < t_ramp:
                    s, rate = 0.5 * a_s * t**2, a_s * t
                elif t <= t_ramp + t_cruise:
                    s, rate = 0.5 * a_s * t_ramp**2 + peak * (t - t_ramp), peak
                else:
                    left = total - t
                    s, rate = length - 0.5 * a_s * left**2, a_s * left
                s = min(max(s, 0.0), length)
                k = int(np.clip(np.searchsorted(s_knots, s, side="right") - 1, 0, len(ds) - 1))
                w = (s - s_knots[k]) / ds[k] if ds[k] > 0 else 0.0
                q = piece[k] + w * (piece[k + 1] - piece[k])
                dq_ds = (piece[k + 1] - piece[k]) / ds[k] if ds[k] > 0 else np.zeros(len(joints))
                times.append(t0 + float(t))
                positions.append(q)
                velocities.append(dq_ds * rate if t < total else np.zeros(len(joints)))
                labels.append(segment.label)
            positions[-1] = piece[-1].copy()
            t0 = times[-1]
    return Trajectory(
        tuple(joints),
        np.asarray(times),
        np.asarray(positions),
        np.asarray(velocities),
        tuple(labels),
        operation,
    )


def write_csv(trajectory: Trajectory, path: Path) -> None:
    """Write ``trajectory`` to ``path`` atomically (temporary file in the same directory, then
    ``os.replace``): a reader never sees a half-written file.

    Raises:
        TrajectoryError: the file cannot be written.
    """
    header = ["time", "segment", *trajectory.joints, *(f"v_{j}" for j in trajectory.joints)]
    lines = [FORMAT_LINE, f"# operation: {trajectory.operation}", ",".join(header)]
    for t, seg, q, v in zip(
        trajectory.times,
        trajectory.segments,
        trajectory.positions,
        trajectory.velocities,
        strict=True,
    ):
        values = ",".join(f"{x:.6f}" for x in (*q, *v))
        lines.append(f"{t:.6f},{seg},{values}")
    text = "\n".join(lines) + "\n"
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
        with os.fdopen(fd, "w", encoding="utf-8") as stream:
            stream.write(text)
        os.replace(tmp, path)
    except OSError as error:
        with contextlib.suppress(OSError, UnboundLocalError):
            os.unlink(tmp)
        msg = f"cannot write trajectory file {path}: {error}"
        raise TrajectoryError(msg) from error


def read_csv(path: Path) -> Trajectory:
    """Read a trajectory file written by :func:`write_csv`.

    Raises:
        TrajectoryError: missing file or malformed contents (the message says where).
    """
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as error:
        msg = f"cannot read trajectory file {path}: {error}"
        raise TrajectoryError(msg) from error
    operation = ""
    rows: list[list[str]] = []
    header: list[str] | None = None
    for number, line in enumerate(lines, start=1):
        if line.startswith("# operation:"):
            operation = line.split(":", 1)[1].strip()
        if not line.strip() or line.startswith("#"):
            continue
        cells = line.split(",")
        if header is None:
            header = cells
            continue
        if len(cells) != len(header):
            msg = f"{path}:{number}: {len(cells)} columns, the header has {len(header)}"
            raise TrajectoryError(msg)
        rows.append(cells)
    if header is None or len(header) < 4 or header[:2] != ["time", "segment"]:
        msg = f"{path}: no 'time,segment,<joints>,v_<joints>' header line"
        raise TrajectoryError(msg)
    k = (len(header) - 2) // 2
    joints = tuple(header[2 : 2 + k])
    if len(header) != 2 + 2 * k or tuple(header[2 + k :]) != tuple(f"v_{j}" for j in joints):
        msg = f"{path}: header must name each joint's position and then its v_ velocity"
        raise TrajectoryError(msg)
    if not rows:
        msg = f"{path}: no trajectory rows"
        raise TrajectoryError(msg)
    try:
        numbers = np.array([[float(c) for c in (r[0], *r[2:])] for r in rows])
    except ValueError as error:
        msg = f"{path}: non-numeric value ({error})"
        raise TrajectoryError(msg) from error
    times = numbers[:, 0]
    if not np.all(np.isfinite(numbers)) or times[0] != 0.0 or np.any(np.diff(times) <= 0):
        msg = f"{path}: times must start at 0 and increase, and every value must be finite"
        raise TrajectoryError(msg)
    return Trajectory(
        joints,
        times,
        numbers[:, 1 : 1 + k],
        numbers[:, 1 + k :],
        tuple(r[1] for r in rows),
        operation,
    )


class TrajectoryStore:
    """The node's trajectory directory and the manifest of the files it wrote there.

    Only files listed in the manifest (written by this class) are ever deleted, and only inside
    the directory: ``delete_prev_traj`` cannot remove anything a user put there.

    Args:
        directory: where trajectory files go (created if missing).

    Raises:
        TrajectoryError: the directory cannot be created.
    """

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory).resolve()
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            msg = f"cannot create trajectory directory {self.directory}: {error}"
            raise TrajectoryError(msg) from error
        self._manifest = self.directory / MANIFEST_NAME
        self._counter = 0

    def written(self) -> list[str]:
        """File names this node (or an earlier run of it) wrote, oldest first."""
        try:
            names = json.loads(self._manifest.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return []
        return [n for n in names if isinstance(n, str)] if isinstance(names, list) else []

    def _save_manifest(self, names: list[str]) -> None:
        fd, tmp = tempfile.mkstemp(prefix=".manifest.", dir=self.directory)
        with os.fdopen(fd, "w", encoding="utf-8") as stream:
            json.dump(names, stream)
        os.replace(tmp, self._manifest)

    def save(self, trajectory: Trajectory, stamp: float | None = None) -> Path:
        """Write ``trajectory`` as ``<operation>_<YYYY-mm-dd_HH-MM-SS>_<n>.csv``; return its path.

        Args:
            trajectory: what to write.
            stamp: s since the epoch for the name (default: now).

        Raises:
            TrajectoryError: the file cannot be written.
        """
        self._counter += 1
        when = time.strftime("%Y-%m-%d_%H-%M-%S", time.localtime(stamp))
        name = f"{trajectory.operation or 'trajectory'}_{when}_{os.getpid()}_{self._counter}.csv"
        path = self.directory / name
        write_csv(trajectory, path)
        try:
            self._save_manifest([*self.written(), name])
        except OSError as error:
            msg = f"cannot update the manifest {self._manifest}: {error}"
            raise TrajectoryError(msg) from error
        return path

    def delete_written(self) -> int:
        """Delete every file of the manifest that still exists in the directory; return how many.

        Raises:
            TrajectoryError: the manifest cannot be updated.
        """
        deleted = 0
        for name in self.written():
            path = self.directory / name
            # Manifest entries are plain names; anything else is not ours to touch.
            if Path(name).name != name or path.parent != self.directory:
                continue
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
                deleted += 1
        try:
            self._save_manifest([])
        except OSError as error:
            msg = f"cannot update the manifest {self._manifest}: {error}"
            raise TrajectoryError(msg) from error
        return deleted

    def resolve(self, name: str) -> Path:
        """The trajectory file called ``name`` (a name in the directory, or an absolute path
        inside it).

        Raises:
            TrajectoryError: empty name, outside the directory, or no such file.
        """
        if not name:
            msg = "no trajectory file name given (set trajectory_filename or use_latest)"
            raise TrajectoryError(msg)
        path = Path(name)
        path = (path if path.is_absolute() else self.directory / path).resolve()
        if path.parent != self.directory:
            msg = f"trajectory file {name!r} is not in the trajectory directory {self.directory}"
            raise TrajectoryError(msg)
        if not path.is_file():
            msg = f"unknown trajectory file {name!r}: no such file in {self.directory}"
            raise TrajectoryError(msg)
        return path

    def latest(self) -> Path:
        """The newest file this node wrote that still exists.

        Raises:
            TrajectoryError: none.
        """
        for name in reversed(self.written()):
            path = self.directory / name
            if path.is_file():
                return path
        msg = f"no trajectory written by this node exists in {self.directory}"
        raise TrajectoryError(msg)
