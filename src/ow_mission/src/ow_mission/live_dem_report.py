"""The live DEM's part of a mission report (``terrain_forces: yade``): the forces of each dig and
the seed paper's comparison (its Table 6 metric) of the table and Balovnev models against them.

A live-DEM mission records the scoop's model state and wrench at every physics step
(:data:`~ow_mission.mission_config.LIVE_DEM_RECORD_TOPICS`): while the scoop digs, each pair is
one DEM exchange, the state the DEM was given and the wrench it answered. For each dig step
(``dig_spoil``, ``dig_sample``) this module takes the pairs with the scoop in the ground, asks the
shipped ``table`` and ``balovnev`` models offline for the same states, and gives the NRMSD of their
Fx, Fy, Fz against the live DEM's (:func:`ow_dem_bridge.comparison.compare_forces`). No ROS:
messages come from the bags (rosbags' classes). The states are those the DEM was given: their
depth is below the top of the DEM's material (the loose layer in a trench included), so the table
and Balovnev are asked where the simulation would not ask them (depth 0 below the height map).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ow_dem_bridge.api import LIVE_MODEL_NAME, FloatArray, TerrainForceModel, ToolState
from ow_dem_bridge.comparison import COMPONENTS, compare_forces, model_wrenches
from ow_power.bagread import TopicMessages
from ow_runtime.names import SIM_DEM_DIGS, SIM_SCOOP_MODEL_STATE, SIM_SCOOP_MODEL_WRENCH

#: The topics the section reads from the bags.
TOPICS: tuple[str, ...] = (SIM_SCOOP_MODEL_STATE, SIM_SCOOP_MODEL_WRENCH, SIM_DEM_DIGS)
#: The models compared with the live DEM (the paper's Table 6 rows for our scoop).
COMPARED: tuple[str, ...] = ("table", "balovnev")
#: The figure (relative to the run directory), its role in the report and its caption.
FIGURE = "live_dem_forces.png"
FIGURE_ROLE = "live_dem"
FIGURE_CAPTION = (
    "The scoop's force in the ground during each dig (l_scoop frame, N, against the dig's sim "
    "time): the live DEM's (solid), and what the shipped table (dashed) and Balovnev (dotted) "
    "give for the same recorded states, with their NRMSD against the live DEM (the seed "
    "paper's Figure 19 and Table 6 for our scoop)."
)
#: The mission's dig steps (names start so).
DIG_STEP_PREFIX = "dig_"


@dataclass(frozen=True)
class DigSeries:
    """The scoop's model states and wrenches of one dig step with the scoop in the ground.

    Attributes:
        step: the mission step.
        times: (N,) s of sim time (the messages' stamps).
        states: the states the model was given (tip velocity in the link frame).
        wrenches: (N, 6) N, N m, the wrench applied (l_scoop frame, about its COM).
    """

    step: str
    times: FloatArray
    states: tuple[ToolState, ...]
    wrenches: FloatArray


def _stamp(msg: Any) -> float:
    stamp = msg.header.stamp
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def dig_series(
    messages: Mapping[str, Sequence[tuple[int, Any]]],
    windows: Sequence[tuple[str, float, float]],
    tip_offset: FloatArray,
) -> list[DigSeries]:
    """The in-ground model states and wrenches of each dig step of ``windows``.

    Args:
        messages: the bags' messages by topic (:data:`TOPICS`; others ignored).
        windows: (step, start s, end s) of the mission's steps.
        tip_offset: (3,) m, the scoop tip in the l_scoop frame (the states' tip velocity).

    Returns:
        One series per dig step with at least one state in the ground, in step order.
    """
    # pinocchio (its quaternions) only in a live-DEM mission's report, not in every report's.
    from ow_dem_bridge.conversions import tool_state_from_msg

    wrenches = {_stamp(m): m for _, m in messages.get(SIM_SCOOP_MODEL_WRENCH, [])}
    paired: list[tuple[float, Any, Any]] = []
    for _, state in messages.get(SIM_SCOOP_MODEL_STATE, []):
        stamp = _stamp(state)
        wrench = wrenches.get(stamp)
        if wrench is not None and state.depth > 0.0:
            paired.append((stamp, state, wrench))
    series = []
    for step, start, end in windows:
        if not step.startswith(DIG_STEP_PREFIX):
            continue
        inside = [p for p in paired if start <= p[0] <= end]
        if not inside:
            continue
        rows = [
            [
                w.wrench.force.x,
                w.wrench.force.y,
                w.wrench.force.z,
                w.wrench.torque.x,
                w.wrench.torque.y,
                w.wrench.torque.z,
            ]
            for _, _, w in inside
        ]
        series.append(
            DigSeries(
                step=step,
                times=np.array([t for t, _, _ in inside]),
                states=tuple(tool_state_from_msg(s, tip_offset) for _, s, _ in inside),
                wrenches=np.asarray(rows, dtype=np.float64),
            )
        )
    return series


def dem_digs(
    messages: Mapping[str, Sequence[tuple[int, Any]]], start_s: float, end_s: float
) -> dict[str, Any]:
    """The DEM digs (``/sim/dem_digs``) that started within a step's ``[start_s, end_s]`` (s,
    sim): how many, the spheres of the last one's bed (loose ones apart), its sample (the spheres
    in the scoop when it ended: what the scoop carries out of the step) and every error."""
    digs = [m for _, m in messages.get(SIM_DEM_DIGS, []) if start_s <= m.start_time <= end_s]
    if not digs:
        return {"digs": 0}
    last = digs[-1]
    return {
        "digs": len(digs),
        "particles": int(last.particles),
        "loose_particles": int(last.loose_particles),
        "sample_particles": int(last.sample_particles),
        "sample_volume_m3": float(last.sample_volume),
        "sample_mass_kg": float(last.sample_mass),
        "errors": [str(m.error) for m in digs if m.error],
    }


def dig_summary(
    series: DigSeries,
    models: Mapping[str, TerrainForceModel],
    others: Mapping[str, FloatArray] | None = None,
) -> dict[str, Any]:
    """The live forces of one dig and the compared models' NRMSD against them (``others``: the
    models' wrench rows for the series' states, when already computed).

    Returns:
        ``step``, ``samples``, ``sim_start_s``, ``sim_end_s``, ``mean_live_n`` and
        ``peak_live_n`` (per component, N; peak of |F| as ``peak_force_n``), ``mean_n``
        ({model: {component: N}}) and ``nrmsd`` ({model: {component: value}}; NaN where the live
        component does not vary).
    """
    live = series.wrenches
    if others is None:
        others = {name: model_wrenches(model, series.states) for name, model in models.items()}
    return {
        "step": series.step,
        "samples": len(series.states),
        "sim_start_s": float(series.times[0]),
        "sim_end_s": float(series.times[-1]),
        "mean_live_n": {c: float(live[:, k].mean()) for k, c in enumerate(COMPONENTS)},
        "peak_live_n": {c: float(np.abs(live[:, k]).max()) for k, c in enumerate(COMPONENTS)},
        "peak_force_n": float(np.linalg.norm(live[:, :3], axis=1).max()),
        "mean_n": {
            name: {c: float(rows[:, k].mean()) for k, c in enumerate(COMPONENTS)}
            for name, rows in others.items()
        },
        "nrmsd": compare_forces(live, others),
    }


def live_dem_section(
    document: dict[str, Any],
    messages: TopicMessages,
    windows: Sequence[tuple[str, float, float]],
    figure_path: Path | None = None,
) -> str | None:
    """``document['live_dem']`` for a ``terrain_forces: yade`` mission (nothing otherwise): the
    digs' live forces and the comparison, the steps' ``windows`` (name, start s, end s: the
    report's ``step_windows``) naming the digs; with ``figure_path``, also the figure there
    (:func:`ow_mission.live_dem_plot.plot_live_dem`; :data:`FIGURE_CAPTION` says what it shows).
    A note when the bags hold no live forces (and no figure)."""
    if document.get("config", {}).get("terrain_forces") != LIVE_MODEL_NAME:
        return None
    from ow_dem_bridge.geometry import load_tool
    from ow_dem_bridge.models import make_model
    from ow_description.description import SCOOP_LINK, URDF_PATH

    tip = load_tool(URDF_PATH, SCOOP_LINK).tip
    series = dig_series(messages, windows, tip)
    models = {name: make_model(name) for name in COMPARED}
    others = [
        {name: model_wrenches(model, s.states) for name, model in models.items()} for s in series
    ]
    summaries = [dig_summary(s, models, o) for s, o in zip(series, others, strict=True)]
    ends = {step: (start, end) for step, start, end in windows}
    for summary in summaries:
        summary["dem"] = dem_digs(messages, *ends[summary["step"]])
    document["live_dem"] = {"digs": summaries}
    if not series:
        return (
            f"no {SIM_SCOOP_MODEL_STATE} / {SIM_SCOOP_MODEL_WRENCH} with the scoop in the ground "
            "during a dig in the bags: no live DEM forces."
        )
    if figure_path is not None:
        from ow_mission.live_dem_plot import plot_live_dem

        plot_live_dem(
            [(s.step, s.times, s.wrenches, o) for s, o in zip(series, others, strict=True)],
            [summary["nrmsd"] for summary in summaries],
            figure_path,
        )
    return None


def _cell(value: float) -> str:
    return "-" if not np.isfinite(value) else f"{value:.2f}"


def markdown_lines(document: Mapping[str, Any]) -> list[str]:
    """``report.md``'s live DEM section (none without ``document['live_dem']``)."""
    live = document.get("live_dem")
    if not live:
        return []
    lines = ["## Live DEM forces (`terrain_forces: yade`)", ""]
    if not live["digs"]:
        return [*lines, "No dig recorded live DEM forces.", ""]
    lines += [
        "Each dig's scoop wrench from the live DEM (l_scoop frame, N), and the NRMSD of the "
        "shipped table's and Balovnev's forces for the same recorded states against it "
        "(RMS(model - live) / (max(live) - min(live)), the seed paper's Table 6 metric).",
        "",
        "| dig | samples | sim s | mean live Fx, Fy, Fz | peak abs F | "
        + " | ".join(f"NRMSD {name} Fx, Fy, Fz" for name in COMPARED)
        + " | sample: spheres, cm³, g |",
        "|---|---:|---|---|---:|" + "---|" * len(COMPARED) + "---|",
    ]
    for dig in live["digs"]:
        mean = ", ".join(f"{dig['mean_live_n'][c]:.2f}" for c in COMPONENTS)
        nrmsd = [", ".join(_cell(dig["nrmsd"][name][c]) for c in COMPONENTS) for name in COMPARED]
        lines.append(
            f"| {dig['step']} | {dig['samples']} | {dig['sim_start_s']:.1f}-"
            f"{dig['sim_end_s']:.1f} | {mean} | {dig['peak_force_n']:.2f} | "
            + " | ".join(nrmsd)
            + f" | {_sample_cell(dig.get('dem', {}))} |"
        )
    lines += [
        "",
        "The sample is the spheres in the scoop when the step's last DEM dig ended "
        "(`/sim/dem_digs`), out of its bed's spheres: their own volume and mass. When the dig "
        "phase ended the dig, the scoop's content in the regolith budget became their bulk "
        "volume (over the bed's solid fraction; the Sample section's figures follow it).",
    ]
    errors = [(d["step"], e) for d in live["digs"] for e in d.get("dem", {}).get("errors", [])]
    lines += [f"- **{step}: the DEM failed**: {error}" for step, error in errors]
    return [*lines, ""]


def _sample_cell(dem: Mapping[str, Any]) -> str:
    if not dem.get("digs"):
        return "-"
    return (
        f"{dem['sample_particles']} of {dem['particles']}, "
        f"{dem['sample_volume_m3'] * 1e6:.1f}, {dem['sample_mass_kg'] * 1e3:.1f}"
    )
