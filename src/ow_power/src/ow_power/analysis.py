"""Energy per arm operation from recorded bags, free of ROS (rosbags, pandas, matplotlib).

Example::

    from ow_power.analysis import analyze, plot_power

    result = analyze(["runs/ow_2025-01-01-12-00-00_0000.bag"])
    print(result.summary[["name", "duration_s", "mechanical_energy_j", "energy_wh"]])
    plot_power(result, "power.png")

Power comes from ``/power`` (the power node) or, when a bag has none or ``recompute`` is set,
from ``/joint_states`` through the same :class:`~ow_power.model.PowerIntegrator`. Operations come
from the START/END markers on ``/arm/operation``. Every energy is eq. 4 with the power of a
sample held over the interval that ends at it (dt from the stamps, intervals longer than
``max_dt_s`` skipped), and an interval straddling an operation's start or end is split at it.

:func:`analyze` reads the bags itself (:func:`ow_power.bagread.read_messages`);
:func:`analyze_messages` takes the messages of :data:`TOPICS` read already, so that a caller
needing other topics of the same bags (the mission report) reads them all in one pass.
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ow_power.bagread import read_messages
from ow_power.config import PowerConfig
from ow_power.errors import AnalysisError, BagReadError, PowerError
from ow_power.model import PowerIntegrator, intervals_s
from ow_runtime.names import ARM_OPERATION, GUARDED_MOVE_RESULT, JOINT_STATES, POWER

POWER_TOPIC = POWER
JOINT_STATES_TOPIC = JOINT_STATES
OPERATION_TOPIC = ARM_OPERATION
GUARDED_MOVE_RESULT_TOPIC = GUARDED_MOVE_RESULT
#: The topics :func:`analyze_messages` uses.
TOPICS = (POWER_TOPIC, JOINT_STATES_TOPIC, OPERATION_TOPIC, GUARDED_MOVE_RESULT_TOPIC)

#: Columns of :attr:`Analysis.power`.
POWER_COLUMNS = (
    "t_s",
    "mechanical_power_w",
    "mechanical_power_abs_w",
    "total_power_w",
    "electrical_power_w",
    "dt_s",
)
#: Columns of :attr:`Analysis.summary`, one row per operation.
SUMMARY_COLUMNS = (
    "id",
    "name",
    "success",
    "complete",
    "start_s",
    "end_s",
    "duration_s",
    "mechanical_energy_j",
    "mechanical_energy_abs_j",
    "energy_wh",
    "electrical_energy_wh",
    "peak_power_w",
    "mean_power_w",
    "message",
    "parameters",
)
_J_PER_WH = 3600.0


@dataclass
class Analysis:
    """What :func:`analyze` found in a run.

    Attributes:
        bags: the bag files read, in order.
        power: one row per power sample (:data:`POWER_COLUMNS`): ``t_s`` (s, simulation time),
            powers (W) and ``dt_s`` (s, the interval each sample is integrated over).
        operations: one row per operation: ``id``, ``name``, ``start_s``, ``end_s`` (s),
            ``success``, ``complete`` (both markers seen), ``message``, ``parameters`` (JSON).
        summary: one row per operation (:data:`SUMMARY_COLUMNS`); energies in J and Wh, powers
            in W. ``peak_power_w`` and ``mean_power_w`` are of the absolute-value mechanical
            power (what the motors deliver); ``energy_wh`` includes P0.
        total: the same figures as ``summary`` for the whole recording.
        contacts_s: s, stamps of successful ``/guarded_move_result`` messages.
        source: ``/power`` or ``/joint_states`` (recomputed).
        auxiliary_power_w: W, P0 of the samples.
    """

    bags: list[Path]
    power: pd.DataFrame
    operations: pd.DataFrame
    summary: pd.DataFrame
    total: pd.Series
    contacts_s: list[float] = field(default_factory=list)
    source: str = POWER_TOPIC
    auxiliary_power_w: float = 0.0


def expand_bag_paths(paths: Iterable[Path | str]) -> list[Path]:
    """Files as given, directories as their ``*.bag`` files in name (= recording) order.

    Raises:
        AnalysisError: a path does not exist, or nothing is left.
    """
    bags: list[Path] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            bags.extend(sorted(path.glob("*.bag")))
        elif path.is_file():
            bags.append(path)
        else:
            msg = f"{path} does not exist"
            raise AnalysisError(msg)
    if not bags:
        msg = f"no .bag files in {[str(p) for p in paths]}"
        raise AnalysisError(msg)
    return bags


def _stamp_s(msg: Any) -> float:
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


@dataclass
class _BagContents:
    power: list[tuple[float, float, float, float, float, float]] = field(default_factory=list)
    joint_states: list[tuple[float, list[str], NDArray[np.float64], NDArray[np.float64]]] = field(
        default_factory=list
    )
    markers: list[dict[str, Any]] = field(default_factory=list)
    contacts_s: list[float] = field(default_factory=list)


def _contents(messages: Mapping[str, Sequence[tuple[int, Any]]]) -> _BagContents:
    contents = _BagContents()
    for _, msg in messages.get(POWER_TOPIC, ()):
        contents.power.append(
            (
                _stamp_s(msg),
                msg.mechanical_power,
                msg.mechanical_power_abs,
                msg.total_power,
                msg.electrical_power,
                msg.auxiliary_power,
            )
        )
    for _, msg in messages.get(JOINT_STATES_TOPIC, ()):
        contents.joint_states.append((_stamp_s(msg), list(msg.name), msg.velocity, msg.effort))
    for _, msg in messages.get(OPERATION_TOPIC, ()):
        contents.markers.append(
            {
                "stamp_s": _stamp_s(msg),
                "id": int(msg.id),
                "name": msg.name,
                "event": int(msg.event),
                "parameters": msg.parameters,
                "success": bool(msg.success),
                "message": msg.message,
            }
        )
    contents.contacts_s = [
        _stamp_s(msg) for _, msg in messages.get(GUARDED_MOVE_RESULT_TOPIC, ()) if msg.success
    ]
    return contents


def _power_frame(rows: Sequence[tuple[float, ...]], max_dt_s: float) -> pd.DataFrame:
    frame = pd.DataFrame(
        rows,
        columns=[
            "t_s",
            "mechanical_power_w",
            "mechanical_power_abs_w",
            "total_power_w",
            "electrical_power_w",
            "auxiliary_power_w",
        ],
    )
    frame = frame.sort_values("t_s", kind="stable").reset_index(drop=True)
    frame["dt_s"] = intervals_s(frame["t_s"].to_numpy(), max_dt_s)
    return frame


def power_from_joint_states(
    joint_states: Iterable[tuple[float, Sequence[str], Any, Any]], config: PowerConfig
) -> pd.DataFrame:
    """Recompute the power samples from joint states with :class:`PowerIntegrator`.

    Args:
        joint_states: ``(stamp_s, names, velocity (n,) rad/s, effort (n,) N m)`` per message.
        config: P0, efficiency, joints, ``max_dt_s``.

    Returns:
        One row per usable joint state (:data:`POWER_COLUMNS` plus ``auxiliary_power_w``);
        messages without velocity or effort for the configured joints are skipped.
    """
    integrator = PowerIntegrator(config)
    rows = []
    for stamp_s, names, velocity, effort in sorted(joint_states, key=lambda m: m[0]):
        try:
            s = integrator.update(stamp_s, names, velocity, effort)
        except PowerError:
            continue
        rows.append(
            (
                s.stamp_s,
                s.mechanical_power_w,
                s.mechanical_power_abs_w,
                s.total_power_w,
                s.electrical_power_w,
                s.auxiliary_power_w,
            )
        )
    return _power_frame(rows, config.max_dt_s)


def pair_operations(
    markers: Iterable[dict[str, Any]], t_first: float, t_last: float
) -> pd.DataFrame:
    """Pair START and END markers by id into operations.

    Args:
        markers: dicts with ``stamp_s``, ``id``, ``name``, ``event`` (0 START, 1 END),
            ``parameters``, ``success``, ``message``.
        t_first: s, start of the recording: the start of an operation whose START is missing.
        t_last: s, end of the recording: the end of an operation whose END is missing.

    Returns:
        One row per operation, ordered by start time.
    """
    open_ops: dict[int, dict[str, Any]] = {}
    ops: list[dict[str, Any]] = []

    def new(marker: dict[str, Any], start: float) -> dict[str, Any]:
        return {
            "id": marker["id"],
            "name": marker["name"],
            "start_s": start,
            "end_s": t_last,
            "success": None,
            "complete": False,
            "message": "",
            "parameters": marker["parameters"],
        }

    for marker in sorted(markers, key=lambda m: m["stamp_s"]):
        if marker["event"] == 0:
            previous = open_ops.pop(marker["id"], None)
            if previous is not None:  # restarted id without an END: ends where the next begins
                previous["end_s"] = marker["stamp_s"]
                ops.append(previous)
            open_ops[marker["id"]] = new(marker, marker["stamp_s"])
        else:
            op = open_ops.pop(marker["id"], None)
            if op is None:
                op = new(marker, t_first)
            else:
                op["complete"] = True
            op.update(end_s=marker["stamp_s"], success=marker["success"], message=marker["message"])
            if not op["parameters"]:
                op["parameters"] = marker["parameters"]
            ops.append(op)
    ops.extend(open_ops.values())
    columns = ["id", "name", "start_s", "end_s", "success", "complete", "message", "parameters"]
    frame = pd.DataFrame(ops, columns=columns)
    return frame.sort_values("start_s", kind="stable").reset_index(drop=True)


def window_figures(power: pd.DataFrame, start_s: float, end_s: float) -> dict[str, float]:
    """Energies and powers of the samples within [start_s, end_s].

    Each sample's power is held over ``[t_s - dt_s, t_s]``; only the part of that interval
    inside the window counts, so back-to-back windows add up to the whole.

    Args:
        power: samples as in :attr:`Analysis.power`.
        start_s: s, window start.
        end_s: s, window end.

    Returns:
        ``duration_s``, ``mechanical_energy_j``, ``mechanical_energy_abs_j``, ``energy_wh``,
        ``electrical_energy_wh``, ``peak_power_w`` (of the absolute-value mechanical power,
        without P0), ``peak_total_power_w`` (of the total power, with P0), ``mean_power_w``
        (NaN without samples).
    """
    t = power["t_s"].to_numpy()
    dt = power["dt_s"].to_numpy()
    overlap = np.clip(np.minimum(t, end_s) - np.maximum(t - dt, start_s), 0.0, None)
    duration = max(end_s - start_s, 0.0)

    def energy(column: str) -> float:
        return float(np.sum(power[column].to_numpy() * overlap))

    # Peak over the samples whose held interval overlaps the window (a lone sample counts too).
    inside = (overlap > 0.0) | ((dt == 0.0) & (t >= start_s) & (t <= end_s))
    abs_energy = energy("mechanical_power_abs_w")

    def peak(column: str) -> float:
        return float(power[column].to_numpy()[inside].max()) if inside.any() else math.nan

    return {
        "duration_s": duration,
        "mechanical_energy_j": energy("mechanical_power_w"),
        "mechanical_energy_abs_j": abs_energy,
        "energy_wh": energy("total_power_w") / _J_PER_WH,
        "electrical_energy_wh": energy("electrical_power_w") / _J_PER_WH,
        "peak_power_w": peak("mechanical_power_abs_w"),
        "peak_total_power_w": peak("total_power_w"),
        "mean_power_w": abs_energy / duration if duration > 0 else math.nan,
    }


def analyze(
    bags: Iterable[Path | str],
    recompute: bool = False,
    config: PowerConfig | None = None,
) -> Analysis:
    """Read a run's bags and compute the energy of every operation.

    Args:
        bags: bag files or directories of them (one run, possibly split into several files).
        recompute: compute power from ``/joint_states`` even when ``/power`` was recorded.
        config: power model for recomputing and the longest integrated interval (default
            :class:`PowerConfig` defaults: P0 43.0 W, efficiency 0.9, max_dt_s 1.0 s).

    Returns:
        The power samples, operations and per-operation figures.

    Raises:
        AnalysisError: a bag is missing or unreadable, or there is no power to analyse.
    """
    paths = expand_bag_paths(bags)
    try:
        messages = read_messages(paths, TOPICS)
    except BagReadError as exc:
        msg = f"cannot read {[str(p) for p in paths]}: {exc}"
        raise AnalysisError(msg) from exc
    return analyze_messages(messages, paths, recompute, config)


def analyze_messages(
    messages: Mapping[str, Sequence[tuple[int, Any]]],
    bags: Sequence[Path],
    recompute: bool = False,
    config: PowerConfig | None = None,
) -> Analysis:
    """:func:`analyze` of messages read already, e.g. with the other topics a report needs.

    Args:
        messages: topic -> (bag time ns, message) in time order, as
            :func:`ow_power.bagread.read_messages` returns for (at least) :data:`TOPICS`.
        bags: the files they were read from, in order (for :attr:`Analysis.bags` and messages).
        recompute: compute power from ``/joint_states`` even when ``/power`` was recorded.
        config: as for :func:`analyze`.

    Returns:
        The power samples, operations and per-operation figures.

    Raises:
        AnalysisError: there is no power to analyse.
    """
    config = config or PowerConfig()
    paths = list(bags)
    contents = _contents(messages)
    if contents.power and not recompute:
        power = _power_frame(contents.power, config.max_dt_s)
        source = POWER_TOPIC
    else:
        power = power_from_joint_states(contents.joint_states, config)
        source = JOINT_STATES_TOPIC
    if power.empty:
        msg = (
            f"no power samples in {[str(p) for p in paths]}: record {POWER_TOPIC} or "
            f"{JOINT_STATES_TOPIC} with velocity and effort"
        )
        raise AnalysisError(msg)
    t_first, t_last = float(power["t_s"].iloc[0]), float(power["t_s"].iloc[-1])
    operations = pair_operations(contents.markers, t_first, t_last)
    rows = []
    for op in operations.itertuples(index=False):
        figures = window_figures(power, float(op.start_s), float(op.end_s))
        rows.append(
            {
                "id": op.id,
                "name": op.name,
                "success": op.success,
                "complete": op.complete,
                "start_s": op.start_s,
                "end_s": op.end_s,
                **figures,
                "message": op.message,
                "parameters": op.parameters,
            }
        )
    summary = pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS))
    total = pd.Series(
        {
            "name": "(whole run)",
            "start_s": t_first,
            "end_s": t_last,
            **window_figures(power, t_first, t_last),
        }
    )
    return Analysis(
        bags=paths,
        power=power,
        operations=operations,
        summary=summary,
        total=total,
        contacts_s=sorted(contents.contacts_s),
        source=source,
        auxiliary_power_w=float(power["auxiliary_power_w"].iloc[0]),
    )


def format_table(result: Analysis) -> str:
    """The per-operation table the ``analyze`` command prints, with a whole-run line."""
    header = (
        f"{'id':>4} {'operation':<16} {'ok':<4} {'t0 s':>9} {'dur s':>8} {'E_mech J':>10} "
        f"{'E_|mech| J':>10} {'E+P0 Wh':>9} {'peak W':>8} {'mean W':>8}"
    )
    lines = [header, "-" * len(header)]

    def line(ident: str, name: str, ok: str, fig: Any) -> str:
        return (
            f"{ident:>4} {name[:16]:<16} {ok:<4} {fig['start_s']:>9.2f} {fig['duration_s']:>8.2f} "
            f"{fig['mechanical_energy_j']:>10.2f} {fig['mechanical_energy_abs_j']:>10.2f} "
            f"{fig['energy_wh']:>9.4f} {fig['peak_power_w']:>8.2f} {fig['mean_power_w']:>8.2f}"
        )

    for _, row in result.summary.iterrows():
        ok = (
            "-"
            if row["success"] is None or pd.isna(row["success"])
            else ("yes" if row["success"] else "no")
        )
        if not row["complete"]:
            ok += "*"
        lines.append(line(str(row["id"]), str(row["name"]), ok, row))
    lines.append("-" * len(header))
    lines.append(line("", "(whole run)", "", result.total))
    notes = [
        f"power from {result.source}; P0 = {result.auxiliary_power_w:.1f} W is in E+P0 only;"
        " peak and mean are of sum |tau*omega|.",
    ]
    if not result.summary.empty and not result.summary["complete"].all():
        notes.append("* operation cut by the start or end of the recording.")
    return "\n".join([*lines, *notes])


def write_summary(result: Analysis, csv_path: Path | str, json_path: Path | str) -> None:
    """Write the per-operation figures as CSV and, with the whole-run line, as JSON.

    Args:
        result: output of :func:`analyze`.
        csv_path: CSV file, one row per operation (:data:`SUMMARY_COLUMNS`).
        json_path: JSON file ``{"bags", "source", "auxiliary_power_w", "operations", "total"}``.
    """
    result.summary.to_csv(csv_path, index=False)
    document = {
        "bags": [str(b) for b in result.bags],
        "source": result.source,
        "auxiliary_power_w": result.auxiliary_power_w,
        "operations": json.loads(result.summary.to_json(orient="records")),
        "total": json.loads(result.total.to_json()),
    }
    Path(json_path).write_text(json.dumps(document, indent=2) + "\n")


@dataclass(frozen=True)
class PlotLabel:
    """A window the power plot shades and labels, with the figures its label shows.

    Attributes:
        name: step or operation name.
        start_s: s, simulation time of its start.
        end_s: s, of its end.
        mechanical_energy_j: J, signed mechanical energy (eq. 4 without P0).
        mechanical_energy_abs_j: J, absolute-value mechanical energy, sum |tau*omega| dt.
        peak_power_w: W, peak of sum |tau*omega| (without P0).
        peak_total_power_w: W, peak of the total power (with P0).
        text: the label as drawn.
    """

    name: str
    start_s: float
    end_s: float
    mechanical_energy_j: float
    mechanical_energy_abs_j: float
    peak_power_w: float
    peak_total_power_w: float
    text: str


def energy_label(name: str, signed_j: float, abs_j: float) -> str:
    """The text the power plot writes over a window (energies in J, one decimal)."""
    return f"{name}\n{signed_j:.1f} J signed\n{abs_j:.1f} J |.|"


def window_labels(
    result: Analysis, windows: Sequence[tuple[str, float, float]] | None = None
) -> list[PlotLabel]:
    """The labels :func:`plot_power` draws, without drawing: each window's energies and peaks
    (:func:`window_figures`) and its text.

    Args:
        result: output of :func:`analyze`.
        windows: (name, start s, end s), e.g. a mission's steps (default: the operations of
            ``/arm/operation``).
    """
    if windows is None:
        windows = [
            (str(op.name), float(op.start_s), float(op.end_s))
            for op in result.summary.itertuples(index=False)
        ]
    labels = []
    for name, start, end in windows:
        figures = window_figures(result.power, start, end)
        labels.append(
            PlotLabel(
                name,
                start,
                end,
                figures["mechanical_energy_j"],
                figures["mechanical_energy_abs_j"],
                figures["peak_power_w"],
                figures["peak_total_power_w"],
                energy_label(
                    name, figures["mechanical_energy_j"], figures["mechanical_energy_abs_j"]
                ),
            )
        )
    return labels


def plot_power(
    result: Analysis,
    png_path: Path | str,
    title: str | None = None,
    windows: Sequence[tuple[str, float, float]] | None = None,
) -> list[PlotLabel]:
    """Power over simulation time with windows shaded and labelled, ground contacts marked.

    The plot of the paper's Figure 18, for a whole run: mechanical power (eq. 2 without P0) and
    the absolute-value variant, in W, against s since the first sample. Each window is labelled
    with its name and both its signed and its absolute-value mechanical energy; labels that
    would overlap are stacked in rows.

    Args:
        result: output of :func:`analyze`.
        png_path: PNG file to write.
        title: plot title (default: how many bags, the first and last names, P0).
        windows: (name, start s, end s) to shade, e.g. a mission's steps (default: the
            operations of ``/arm/operation``).

    Returns:
        The labelled windows with the figures their labels show (see :func:`window_figures`).
    """
    import matplotlib

    matplotlib.use("Agg")
    with warnings.catch_warnings():
        # Debian's python3-matplotlib next to the venv's makes pyplot warn about Axes3D.
        warnings.simplefilter("ignore", UserWarning)
        import matplotlib.pyplot as plt

    labels = window_labels(result, windows)
    t0 = float(result.power["t_s"].iloc[0])
    t = result.power["t_s"].to_numpy() - t0
    fig, ax = plt.subplots(figsize=(12, 5.5), dpi=110)
    ax.plot(
        t,
        result.power["mechanical_power_abs_w"],
        lw=1.0,
        color="tab:red",
        drawstyle="steps-pre",
        label="sum |tau*omega| (absolute-value mechanical power)",
    )
    ax.plot(
        t,
        result.power["mechanical_power_w"],
        lw=0.8,
        color="tab:blue",
        drawstyle="steps-pre",
        label="sum tau*omega (signed, eq. 2 without P0)",
    )
    ax.axhline(0.0, color="0.5", lw=0.5)
    for k, contact in enumerate(result.contacts_s):
        ax.axvline(
            contact - t0, color="k", ls="--", lw=0.8, label="ground contact" if k == 0 else None
        )
    colors = [plt.get_cmap("tab10")(i) for i in range(10)]
    texts = []
    for i, label in enumerate(labels):
        color = colors[i % len(colors)]
        ax.axvspan(label.start_s - t0, label.end_s - t0, color=color, alpha=0.12, lw=0)
        texts.append(
            ax.text(
                (label.start_s + label.end_s) / 2 - t0,
                0.99,
                label.text,
                transform=ax.get_xaxis_transform(),
                ha="center",
                va="top",
                fontsize=7,
                color=color,
            )
        )
    ax.set_xlabel("simulation time since the first sample [s]")
    ax.set_ylabel("mechanical power [W]")
    names = (
        result.bags[0].name
        if len(result.bags) == 1
        else f"{len(result.bags)} bags, {result.bags[0].name} ... {result.bags[-1].name}"
    )
    ax.set_title(
        title or f"Arm power, {names} (P0 = {result.auxiliary_power_w:.1f} W not shown)",
        fontsize=10,
    )
    ax.grid(alpha=0.3)
    # Below the axes: inside, it hid the data wherever it was put.
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=3, fontsize=8)
    stack_labels(fig, ax, texts)
    fig.tight_layout()
    fig.savefig(png_path, dpi=fig.dpi)  # not rcParams: progpy.visualize sets 300 on import
    plt.close(fig)
    return labels


def stack_labels(fig: Any, ax: Any, texts: Sequence[Any]) -> int:
    """Move labels (top-aligned at the top of ``ax``) into rows so that none overlaps another,
    and raise the y limit so that the rows sit above the data; returns the number of rows."""
    fig.tight_layout()
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    axes_height = ax.get_window_extent(renderer).height
    rows: list[list[tuple[float, float]]] = []
    row_height = 0.0
    for text in texts:
        box = text.get_window_extent(renderer)
        row_height = max(row_height, box.height / axes_height + 0.01)
        row = next(
            (
                i
                for i, spans in enumerate(rows)
                if all(box.x1 + 4 < x0 or box.x0 - 4 > x1 for x0, x1 in spans)
            ),
            len(rows),
        )
        if row == len(rows):
            rows.append([])
        rows[row].append((box.x0, box.x1))
        text.set_y(0.99 - row * row_height)
    if texts:
        low, high = ax.get_ylim()
        used = min(0.99 - len(rows) * row_height, 0.9)
        ax.set_ylim(low, low + (high - low) / max(used, 0.3))
    return len(rows)
