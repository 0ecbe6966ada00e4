"""The mission report's figures made from its bags (no ROS): the trench profile and the guarded
move's ground detector (the paper's Figure 11).

The numbers each figure shows are computed by a pure function (:func:`trench_profile`,
:func:`detector_trace`) that the tests check on synthetic bags; the ``plot_*`` functions only draw.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_description.terrain import HeightMap
from ow_lander.execution.ground_detection import GroundDetector
from ow_lander.operations.workspace import GRIND_PASS_SHIFT, shoulder_yaw_for
from ow_mission.recording import Recording

FloatArray = npt.NDArray[np.float64]

#: m, how far the trench's floor may stay above the requested floor and the dig still count as
#: done: about a quarter of the terrain grid's 4 cm cells, which the carving follows.
DEPTH_TOLERANCE_M = 0.01
#: m, terrain shown beyond each end of the trench line and on each side across it.
PROFILE_MARGIN_M = 0.15
ACROSS_HALF_WIDTH_M = 0.3
#: m, terrain shown around the profiles' lines in the top view.
MAP_MARGIN_M = 0.1
#: Hz, rate of the scoop-tip samples of the offline detector replay: /tf's rate in the
#: simulation (``tf_rate_hz``), at which the arm services sample the tip.
TF_RATE_HZ = 30.0
#: Fraction of the descent speed within which a sample counts as steady descent.
STEADY_FRACTION = 0.25


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    with warnings.catch_warnings():
        # Debian's python3-matplotlib next to the venv's makes pyplot warn about Axes3D.
        warnings.simplefilter("ignore", UserWarning)
        import matplotlib.pyplot as plt
    return plt


# ----------------------------------------------------------------------------- trench profile
@dataclass(frozen=True)
class TrenchGeometry:
    """Where the trench is, from the mission's settings (all m, base_link).

    Attributes:
        start: (2,) x, y of the trench line's start: the mission's (x, y) moved half a grinder
            pass shift sideways, between the two passes.
        direction: (2,) unit vector along the trench.
        normal: (2,) unit vector across it (to the left of ``direction``).
        length: m, trench length.
    """

    start: FloatArray
    direction: FloatArray
    normal: FloatArray
    length: float

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> TrenchGeometry:
        """From ``report.json``'s ``config`` (x, y, trench_length, parallel), as the grind
        service lays its passes out (``ow_lander.operations.ground.plan_grind``)."""
        x, y = float(config["x"]), float(config["y"])
        yaw = shoulder_yaw_for(x, y, -math.pi, math.pi)
        heading = np.array([math.cos(yaw), math.sin(yaw)])
        right = np.array([math.sin(yaw), -math.cos(yaw)])
        parallel = bool(config["parallel"])
        direction = heading if parallel else right
        shift = -right if parallel else heading
        start = np.array([x, y]) + shift * GRIND_PASS_SHIFT / 2
        normal = np.array([-direction[1], direction[0]])
        return cls(start, direction, normal, float(config["trench_length"]))

    @property
    def middle(self) -> FloatArray:
        """(2,) m, the middle of the trench line."""
        return self.start + self.direction * self.length / 2


@dataclass(frozen=True)
class TrenchProfile:
    """Terrain before and after the mission along the trench line and across its middle.

    Attributes:
        along_m: (N,) m, distance along the line from its start (negative before it).
        along_before: (N,) m, terrain z before (first ``/sim/terrain``).
        along_after: (N,) m, terrain z after (last ``/sim/terrain``).
        across_m: (M,) m, offset across the middle (positive to the left of the line).
        across_before: (M,) m.
        across_after: (M,) m.
        length: m, trench length.
        ground_z: m, the ground the guarded move found.
        requested_floor_z: m, ground found minus ``trench_depth``.
        requested_bottom_z: m, that floor minus ``bottom_grind_depth``.
        map_x: (cols,) m, x of the cells of ``map_change``.
        map_y: (rows,) m, y of its cells.
        map_change: (rows, cols) m, after minus before around the trench (top view).
        line: (2, 2) m, x, y of the ends of the along profile.
        cut: (2, 2) m, x, y of the ends of the across profile.
    """

    along_m: FloatArray
    along_before: FloatArray
    along_after: FloatArray
    across_m: FloatArray
    across_before: FloatArray
    across_after: FloatArray
    length: float
    ground_z: float
    requested_floor_z: float
    requested_bottom_z: float
    map_x: FloatArray
    map_y: FloatArray
    map_change: FloatArray
    line: FloatArray
    cut: FloatArray

    def _inside(self) -> npt.NDArray[np.bool_]:
        return (self.along_m >= 0.0) & (self.along_m <= self.length)

    @property
    def floor_z(self) -> float:
        """m, median terrain z after the mission along the trench's length: its floor."""
        return float(np.median(self.along_after[self._inside()]))

    @property
    def deepest_z(self) -> float:
        """m, lowest terrain z after the mission along the trench's length."""
        return float(np.min(self.along_after[self._inside()]))

    @property
    def depth_reached_m(self) -> float:
        """m, ground found minus the trench floor."""
        return self.ground_z - self.floor_z

    @property
    def depth_requested_m(self) -> float:
        """m, ground found minus the requested floor after the bottom grind."""
        return self.ground_z - self.requested_bottom_z

    @property
    def worked(self) -> bool:
        """True when the floor reached the requested trench floor (``trench_depth``) within
        :data:`DEPTH_TOLERANCE_M`."""
        return self.floor_z <= self.requested_floor_z + DEPTH_TOLERANCE_M

    def verdict(self) -> str:
        """One sentence for the report: did the dig work, by how much."""
        requested = self.ground_z - self.requested_floor_z
        return (
            f"{'The dig worked' if self.worked else 'The dig did NOT reach the requested depth'}: "
            f"trench floor (median along its {self.length:.2f} m) at z = {self.floor_z:.3f} m, "
            f"{self.depth_reached_m * 100:.1f} cm below the ground found "
            f"(z = {self.ground_z:.3f} m); requested {requested * 100:.1f} cm "
            f"(trench_depth), {self.depth_requested_m * 100:.1f} cm with the bottom grind; "
            f"deepest point {(self.ground_z - self.deepest_z) * 100:.1f} cm."
        )


def trench_profile(
    before: HeightMap,
    after: HeightMap,
    config: Mapping[str, Any],
    ground_z: float | None,
    step_m: float | None = None,
) -> TrenchProfile:
    """Sample the terrain before and after along the trench line and across its middle.

    Args:
        before: the first terrain of the run.
        after: the last terrain of the run.
        config: ``report.json``'s ``config`` (x, y, trench_length, parallel, trench_depth,
            bottom_grind_depth, expected_ground).
        ground_z: m, ground found by the guarded move (None: the expected ground).
        step_m: m, sample spacing (default: half the terrain resolution).
    """
    geometry = TrenchGeometry.from_config(config)
    ground = float(config["expected_ground"]) if ground_z is None else float(ground_z)
    step = step_m or after.resolution / 2
    along = np.arange(-PROFILE_MARGIN_M, geometry.length + PROFILE_MARGIN_M + step / 2, step)
    across = np.arange(-ACROSS_HALF_WIDTH_M, ACROSS_HALF_WIDTH_M + step / 2, step)
    line = geometry.start[None, :] + along[:, None] * geometry.direction[None, :]
    cut = geometry.middle[None, :] + across[:, None] * geometry.normal[None, :]
    floor = ground - float(config["trench_depth"])
    xs, ys = after.cell_centres()
    corners = np.vstack([line, cut])
    area = MAP_MARGIN_M
    cols = (xs >= corners[:, 0].min() - area) & (xs <= corners[:, 0].max() + area)
    rows = (ys >= corners[:, 1].min() - area) & (ys <= corners[:, 1].max() + area)
    X, Y = np.meshgrid(xs[cols], ys[rows])
    change = after.heights[np.ix_(rows, cols)] - before.height_at(X, Y)
    return TrenchProfile(
        along,
        before.height_at(line[:, 0], line[:, 1]),
        after.height_at(line[:, 0], line[:, 1]),
        across,
        before.height_at(cut[:, 0], cut[:, 1]),
        after.height_at(cut[:, 0], cut[:, 1]),
        geometry.length,
        ground,
        floor,
        floor - float(config["bottom_grind_depth"]),
        xs[cols],
        ys[rows],
        change,
        line[[0, -1]],
        cut[[0, -1]],
    )


def plot_trench(profile: TrenchProfile, png_path: Path) -> None:
    """Draw the profile: along the trench (left) and across its middle (right), cm."""
    plt = _pyplot()
    fig, all_axes = plt.subplots(1, 3, figsize=(15, 4.6), dpi=110, width_ratios=(1.1, 1.6, 1))
    top, axes = all_axes[0], all_axes[1:]
    depth = -profile.map_change * 100
    image = top.pcolormesh(
        profile.map_x,
        profile.map_y,
        depth,
        cmap="YlOrBr",
        vmin=0.0,
        vmax=max(float(depth.max()), 1.0),
        shading="nearest",
    )
    fig.colorbar(image, ax=top, label="terrain lowered by the mission [cm]", shrink=0.85)
    top.plot(*profile.line.T, color="tab:blue", lw=1.0, label="along profile")
    top.plot(*profile.cut.T, color="tab:green", lw=1.0, label="across profile")
    top.set_aspect("equal")
    top.set_xlabel("x in base_link [m]")
    top.set_ylabel("y in base_link [m]")
    top.set_title("top view: terrain after - before", fontsize=10)
    top.legend(fontsize=7, loc="lower left")
    for ax, x, before, after, span, label in (
        (
            axes[0],
            profile.along_m,
            profile.along_before,
            profile.along_after,
            (0.0, profile.length),
            "distance along the trench line from its start [m]",
        ),
        (
            axes[1],
            profile.across_m,
            profile.across_before,
            profile.across_after,
            None,
            "offset across the trench at its middle [m] (+ = left)",
        ),
    ):
        ax.plot(x, before * 100, color="0.45", lw=1.2, label="before (first /sim/terrain)")
        ax.plot(x, after * 100, color="tab:brown", lw=1.6, label="after (last /sim/terrain)")
        ax.fill_between(
            x, after * 100, before * 100, where=after < before, color="tab:brown", alpha=0.15, lw=0
        )
        ax.axhline(
            profile.ground_z * 100,
            color="tab:green",
            lw=0.9,
            ls=":",
            label=f"ground found {profile.ground_z * 100:.1f} cm",
        )
        lo, hi = span if span is not None else (x[0], x[-1])
        ax.hlines(
            profile.requested_floor_z * 100,
            lo,
            hi,
            color="tab:blue",
            lw=1.2,
            ls="--",
            label=f"requested floor (ground - trench_depth) "
            f"{profile.requested_floor_z * 100:.1f} cm",
        )
        ax.hlines(
            profile.requested_bottom_z * 100,
            lo,
            hi,
            color="tab:purple",
            lw=1.0,
            ls="-.",
            label=f"bottom grind depth {profile.requested_bottom_z * 100:.1f} cm",
        )
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("terrain z in base_link [cm]")
    axes[0].legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=3)
    axes[0].set_title("along the trench", fontsize=10)
    axes[1].set_title("across the trench, at its middle", fontsize=10)
    fig.suptitle(
        f"Trench profile: floor {profile.depth_reached_m * 100:.1f} cm below the ground found, "
        f"requested {(profile.ground_z - profile.requested_floor_z) * 100:.1f} cm "
        f"({'reached' if profile.worked else 'NOT reached'})",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(png_path, dpi=fig.dpi)  # not rcParams: progpy.visualize sets 300 on import
    plt.close(fig)


# ----------------------------------------------------------------------- ground detector
@dataclass(frozen=True)
class DetectorTrace:
    """The guarded move's ground detector over its descent.

    Attributes:
        source: "recorded" (``/arm/ground_detector``) or "replayed" (the paper's detector run
            offline on the scoop tip's z velocity from the recorded joint states).
        detector: "velocity" or "force".
        unit: unit of the signal, "m/s" or "N".
        t_s: (N,) s, simulation time of each sample.
        signal: (N,) the detector's input.
        moving_average: (N,) its moving average (NaN before a full window).
        threshold: (N,) the threshold in force at each sample (NaN before it is known).
        contact_s: s, when the detector declared contact, or None.
        result_s: s, the contact stamp of ``/guarded_move_result`` (the arm services'), or None.
    """

    source: str
    detector: str
    unit: str
    t_s: FloatArray
    signal: FloatArray
    moving_average: FloatArray
    threshold: FloatArray
    contact_s: float | None
    result_s: float | None


def _result_in(recording: Recording, start: float, end: float) -> float | None:
    inside = [t for t, _ in recording.contacts if start <= t <= end]
    return inside[0] if inside else None


def detector_trace(
    recording: Recording,
    start_s: float,
    end_s: float,
    relative_tolerance: float,
    window: int = 5,
) -> DetectorTrace | None:
    """The detector's samples of the guarded move in [start_s, end_s] (s, sim).

    The recorded ``/arm/ground_detector`` samples when the bags have them; else the paper's
    detector (:class:`ow_lander.execution.ground_detection.GroundDetector`) replayed on the scoop
    tip's position from forward kinematics of ``/joint_states`` (what tf gives the arm services),
    sampled at :data:`TF_RATE_HZ`, over the steady descent before the recorded contact. None when
    there is neither (no detector message and no ground found).

    Args:
        recording: the run's bags.
        start_s: s, the guarded move step's start.
        end_s: s, its end.
        relative_tolerance: the arm services' ``ground_relative_tolerance``.
        window: samples of the moving average.
    """
    result_s = _result_in(recording, start_s, end_s)
    recorded = [s for s in recording.detector if start_s <= s.t_s <= end_s]
    if recorded:
        contact = next((s.t_s for s in recorded if s.contact), None)
        return DetectorTrace(
            "recorded",
            recorded[0].detector,
            "m/s" if recorded[0].detector == "velocity" else "N",
            np.array([s.t_s for s in recorded]),
            np.array([s.signal for s in recorded]),
            np.array([s.moving_average for s in recorded]),
            np.array([s.threshold for s in recorded]),
            contact,
            result_s,
        )
    if result_s is None:
        return None
    t, z = _tip_z(recording, start_s, result_s + 1.0)
    if len(t) < 2 * window + 2:
        return None
    vz = np.diff(z) / np.diff(t)
    tv = t[1:]
    first = _steady_start(tv, vz, result_s)
    if first is None:
        return None
    # The detector sees positions from the sample before the first steady velocity on.
    detector = GroundDetector(window=window, relative_tolerance=relative_tolerance)
    average = np.full(len(vz), np.nan)
    threshold = np.full(len(vz), np.nan)
    contact_s = None
    detector.update(float(t[first]), np.array([0.0, 0.0, z[first]]))
    for k in range(first, len(vz)):
        fired = detector.update(float(t[k + 1]), np.array([0.0, 0.0, z[k + 1]]))
        if k - first + 1 >= window:
            average[k] = float(np.mean(vz[k - window + 1 : k + 1]))
        if detector.threshold is not None:
            threshold[k] = detector.threshold
        if fired and contact_s is None:
            contact_s = float(tv[k])
    keep = slice(max(first - 3 * window, 0), None)
    return DetectorTrace(
        "replayed",
        "velocity",
        "m/s",
        tv[keep],
        vz[keep],
        average[keep],
        threshold[keep],
        contact_s,
        result_s,
    )


def _tip_z(recording: Recording, start_s: float, end_s: float) -> tuple[FloatArray, FloatArray]:
    """(t s, scoop-tip z m) in [start_s, end_s], one joint state per /tf period."""
    from ow_description.model import LanderModel

    inside = np.flatnonzero((recording.joint_t >= start_s) & (recording.joint_t <= end_s))
    if len(inside) == 0:
        return np.zeros(0), np.zeros(0)
    ticks = np.floor(recording.joint_t[inside] * TF_RATE_HZ + 1e-6)
    _, first_of_tick = np.unique(ticks, return_index=True)
    chosen = inside[first_of_tick]
    model = LanderModel()
    z = np.empty(len(chosen))
    for i, k in enumerate(chosen):
        joints = dict(zip(recording.joint_names, recording.joint_positions[k], strict=True))
        z[i] = model.fk(model.q_from(joints), "l_scoop_tip")[2, 3]
    return recording.joint_t[chosen], z


def _steady_start(t: FloatArray, vz: FloatArray, contact_s: float) -> int | None:
    """Index of the first velocity sample of the steady descent that ends at the contact: the
    run of samples before it within :data:`STEADY_FRACTION` of the descent speed (the median
    of the second before the contact)."""
    before = np.flatnonzero((t > contact_s - 1.2) & (t <= contact_s - 0.2))
    if len(before) == 0:
        return None
    speed = float(np.median(vz[before]))
    if speed >= 0:
        return None
    last = int(before[-1])
    k = last
    while k > 0 and abs(vz[k - 1] - speed) <= STEADY_FRACTION * abs(speed):
        k -= 1
    return k


def plot_guarded_move(trace: DetectorTrace, png_path: Path) -> None:
    """The paper's Figure 11: signal, moving average, threshold and the detection instant."""
    plt = _pyplot()
    scale, unit = (1000.0, "mm/s") if trace.unit == "m/s" else (1.0, trace.unit)
    t0 = float(trace.t_s[0])
    t = trace.t_s - t0
    fig, ax = plt.subplots(figsize=(9, 4.2), dpi=110)
    signal_label = "scoop tip z velocity" if trace.detector == "velocity" else "wrist force rise"
    ax.plot(t, trace.signal * scale, ".", ms=3, color="0.45", label=signal_label)
    ax.plot(t, trace.moving_average * scale, color="tab:blue", lw=1.5, label="moving average")
    ax.plot(t, trace.threshold * scale, color="tab:red", lw=1.2, ls="--", label="threshold")
    if trace.contact_s is not None:
        ax.axvline(
            trace.contact_s - t0,
            color="k",
            lw=1.2,
            label=f"detected ({trace.source}) t = {trace.contact_s:.2f} s",
        )
    if trace.result_s is not None and trace.result_s != trace.contact_s:
        ax.axvline(
            trace.result_s - t0,
            color="tab:green",
            lw=1.0,
            ls=":",
            label=f"arm services' contact (/guarded_move_result) t = {trace.result_s:.2f} s",
        )
    ax.set_xlabel(f"simulation time since {t0:.2f} s [s]")
    ax.set_ylabel(f"{signal_label} [{unit}]")
    source = (
        "recorded /arm/ground_detector"
        if trace.source == "recorded"
        else "replayed offline: the paper's detector on the scoop tip z velocity "
        f"(FK of /joint_states at {TF_RATE_HZ:g} Hz)"
    )
    ax.set_title(f"Guarded move ground detection (the paper's Figure 11)\n{source}", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(png_path, dpi=fig.dpi)  # not rcParams: progpy.visualize sets 300 on import
    plt.close(fig)
