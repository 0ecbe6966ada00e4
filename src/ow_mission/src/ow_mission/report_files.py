"""A run's ``report.json`` and ``report.md``: what the report links (:class:`Figures`), the
Markdown of the report and its step table, and writing both files whole. No ROS; the report's
figures and numbers come from :mod:`ow_mission.report`."""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


def draw_command(run_dir: Path | str) -> str:
    """The command that draws the figures of run ``run_dir`` from its bags."""
    return f"python -m ow_mission.figures {run_dir}"


def left_to_draw(document: Mapping[str, Any]) -> bool:
    """Whether the mission of ``document`` left its figures to whoever wants them
    (``figures: none``)."""
    return bool((document.get("config") or {}).get("figures") == "none")


@dataclass
class Figures:
    """What the report links, by role: file names relative to the run directory, and notes for
    figures that could not be made."""

    files: dict[str, str] = field(default_factory=dict)
    captions: dict[str, str] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    #: False: work out the numbers the figures show (into the document) without drawing them.
    draw: bool = True


def write_report_files(run_dir: Path, document: Mapping[str, Any], markdown_text: str) -> None:
    """``report.json`` and ``report.md``, each replaced at once (written aside, then renamed):
    a reader never sees half a file, even while the figures' process rewrites them."""
    for name, text in (
        ("report.json", json.dumps(document, indent=2, default=_jsonable) + "\n"),
        ("report.md", markdown_text),
    ):
        part = run_dir / f".{name}.part"
        part.write_text(text)
        os.replace(part, run_dir / name)


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    msg = f"{value!r} is not JSON serialisable"
    raise TypeError(msg)


def _number(value: Any, fmt: str) -> str:
    return (
        "-"
        if value is None or (isinstance(value, float) and math.isnan(value))
        else format(value, fmt)
    )


def step_table(document: Mapping[str, Any]) -> list[str]:
    """The per-step table of ``report.md`` (Markdown), energies as the power plot labels them."""
    lines = [
        "| step | service | plan s | sim s | mech. energy signed J | mech. energy abs J "
        "| energy with P0 Wh | peak mech. W (no P0) | peak total W (with P0) | result |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for s in document["steps"]:
        result = "ok" if s["success"] else f"FAILED: {s['message']}"
        lines.append(
            f"| {s['step']} | `{s['service']}` | {s['planning_time_s']:.3f} "
            f"| {s['sim_end_s'] - s['sim_start_s']:.1f} "
            f"| {_number(s.get('mechanical_energy_j'), '.1f')} "
            f"| {_number(s.get('mechanical_energy_abs_j'), '.1f')} "
            f"| {_number(s.get('energy_wh'), '.4f')} "
            f"| {_number(s.get('peak_mechanical_power_w'), '.1f')} "
            f"| {_number(s.get('peak_power_w'), '.1f')} | {result} |"
        )
    return lines


def markdown(run_dir: Path, document: Mapping[str, Any], figures: Figures) -> str:
    """``report.md``: result, dig verdict, step table, every figure that exists with its
    caption, and a note for each that could not be made."""
    config = document["config"]
    ground = document.get("ground_z")
    lines = [
        f"# Mission report: {config.get('name', 'mission')}",
        "",
        f"Result: **{'success' if document['success'] else 'FAILED'}**"
        + (f": {document['error']}" if document.get("error") else ""),
        "",
        f"Terrain `{config.get('terrain_spec', config['terrain'])}`, trench at "
        f"({config['x']:.3f}, {config['y']:.3f}) m in base_link; ground found at "
        + (f"z = {ground:.4f} m." if ground is not None else "(none)."),
        "",
    ]
    if document.get("recording_note"):
        lines += [f"> Recording: {document['recording_note']}", ""]
    trench = document.get("trench")
    if trench is not None:
        lines += [f"**{trench['verdict']}**", ""]
    lines += [
        f"{document['wall_time_s']:.1f} s wall, {document['sim_time_s']:.1f} s simulated "
        f"(real-time factor {document['real_time_factor']:.1f}x), peak memory "
        f"{document['peak_memory_mb']:.0f} MB.",
        "",
        *step_table(document),
        "",
        "Energies and peaks are from the bags' `/power` over each step's window (the numbers the "
        "power plot labels): *signed* is eq. 4 without P0 (sum tau*omega dt: negative where a "
        "joint brakes a load), *abs* is sum |tau*omega| dt (motors do not regenerate); *energy "
        "with P0* adds the auxiliary power. *Peak mech.* is the peak of sum |tau*omega|, "
        "*peak total* that of the total power with P0.",
        "",
        *sample_lines(document),
        *_live_dem_lines(document),
        *_faults_lines(document),
        "## Figures",
        "",
    ]
    for role, rel in figures.files.items():
        if not (run_dir / rel).is_file():
            continue
        lines += [f"![{role}]({rel})", "", f"*{figures.captions.get(role, rel)}*", ""]
    for note in figures.notes.values():
        lines += [f"> {note}", ""]
    if document.get("figures_pending") and left_to_draw(document):
        lines += [
            "> The figures were not drawn (the mission said `figures: none`): "
            f"`{draw_command('<run dir>')}` draws them from the bags and rewrites "
            "this report with them.",
            "",
        ]
    elif document.get("figures_pending"):
        lines += [
            "> The figures are being made from the bags by a process of their own, started as "
            "the mission exited (its output: `figures.log`); it rewrites this report with them. "
            "`python -m ow_mission.figures --wait <run dir>` waits for it.",
            "",
        ]
    lines += [
        "Files: `bags/` (ROS 1 bags: /power, /joint_states, /arm/operation, /sim/terrain, ...), "
        "`trajectories/` (the planned CSV trajectories), `camera/` (the stereo capture of the "
        "workspace: left image, point cloud), `ros/` (node logs). Rebuild this report "
        "from the bags with `python -m ow_mission.report <run dir>`.",
    ]
    return "\n".join(lines) + "\n"


def sample_lines(document: Mapping[str, Any]) -> list[str]:
    """``report.md``'s sample section: DockIngestSample's outcome and, from the bags' regolith
    budget (``document['sample']``), the ingested volume, its composition, the top layer's
    share and where the rest of the scooped regolith went."""
    ingestion = document.get("ingestion")
    sample = document.get("sample")
    if ingestion is None and sample is None:
        return []
    lines = ["## Sample", ""]
    if ingestion is not None:
        lines += [f"DockIngestSample after the delivery: {ingestion['message'] or '-'}.", ""]
    if sample is None:
        return lines
    if sample["ingested"]:
        composition = ", ".join(
            f"{name} {100 * share:.1f} %" for name, share in sample["composition"].items()
        )
        lines += [
            f"Ingested **{sample['volume_m3']:.3g} m³** ({sample['mass_kg']:.3g} kg): "
            f"{composition}; **{100 * sample['top_layer_share']:.1f} %** of it from the top "
            f"layer `{sample['top_layer']}` (the irradiated layer the first trench removes).",
            "",
        ]
    else:
        lines += ["No regolith was ingested: the dock held none after the delivery.", ""]
    budget = sample["budget_m3"]
    share = sample["dock_share"]
    lines += [
        "Where the scooped regolith went (m³, the simulation's budget at the end): "
        + ", ".join(f"{name.replace('_', ' ')} {volume:.3g}" for name, volume in budget.items())
        + (f"; {100 * share:.1f} % of the excavated volume reached the dock." if share else "."),
        "",
    ]
    return lines


def _live_dem_lines(document: Mapping[str, Any]) -> list[str]:
    from ow_mission.live_dem_report import markdown_lines

    return markdown_lines(document)


def _faults_lines(document: Mapping[str, Any]) -> list[str]:
    from ow_mission.fault_report import markdown_lines

    return markdown_lines(document["faults"]) if "faults" in document else []


def image_links(markdown_text: str) -> list[str]:
    """The targets of the Markdown image links ``![alt](target)`` of ``markdown_text``."""
    return re.findall(r"!\[[^\]]*\]\(([^)]+)\)", markdown_text)
