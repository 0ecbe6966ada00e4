"""The campaign report: per-operation statistics and pass rule, success rate, ground-detection
error, the delivered samples' volumes and top-layer shares, energies, plots and the failed
missions with the command that replays each (no ROS).

Statistics follow OceanWATERS' action tests: for each operation (mission step), the mean, the
standard deviation (sample, n - 1; 0 for one sample) and n of the simulated duration and of the
tool's final position, over the steps that succeeded. Its pass rule: a step passes when its
duration is below ``mean + max(4 std, 10 s)`` and each coordinate of its final position is within
``max(4 std, 1 cm)`` of the mean. The report checks each mission's steps against the
statistics of the other missions (leave one out).
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ow_mission.report_files import draw_command

#: s, least margin of the duration rule; m, least position tolerance per coordinate.
MIN_DURATION_MARGIN_S = 10.0
MIN_POSITION_TOLERANCE_M = 0.01
#: How many standard deviations the pass rule allows.
STD_FACTOR = 4.0
#: Other missions' steps an operation needs before a step is checked against them.
MIN_REFERENCE = 2


def _std(values: np.ndarray) -> Any:
    return np.std(values, axis=0, ddof=1) if len(values) > 1 else np.zeros_like(values[0])


@dataclass(frozen=True)
class OperationStats:
    """One operation's statistics over the steps that succeeded.

    Attributes:
        step: the mission step (operation) name.
        n: how many steps succeeded.
        duration_mean_s: s, mean simulated duration.
        duration_std_s: s, its sample standard deviation.
        position_mean: (3,) m, mean final tool position in base_link (None without positions).
        position_std: (3,) m, its sample standard deviation per coordinate.
        energy_mean_wh: Wh, mean energy with P0.
        energy_std_wh: Wh.
    """

    step: str
    n: int
    duration_mean_s: float
    duration_std_s: float
    position_mean: tuple[float, float, float] | None
    position_std: tuple[float, float, float] | None
    energy_mean_wh: float
    energy_std_wh: float

    @property
    def duration_limit_s(self) -> float:
        """s, the longest duration that passes: mean + max(4 std, 10 s)."""
        return self.duration_mean_s + max(STD_FACTOR * self.duration_std_s, MIN_DURATION_MARGIN_S)

    @property
    def position_tolerance_m(self) -> tuple[float, float, float] | None:
        """m per coordinate: max(4 std, 1 cm)."""
        if self.position_std is None:
            return None
        x, y, z = (max(STD_FACTOR * s, MIN_POSITION_TOLERANCE_M) for s in self.position_std)
        return (x, y, z)

    def check(self, step: Mapping[str, Any]) -> list[str]:
        """Why a step fails the pass rule (empty when it passes)."""
        reasons = []
        if float(step["sim_time_s"]) >= self.duration_limit_s:
            reasons.append(
                f"duration {float(step['sim_time_s']):.1f} s >= {self.duration_limit_s:.1f} s"
            )
        tolerance = self.position_tolerance_m
        position = step.get("final_tool_position")
        if tolerance is not None and self.position_mean is not None and position is not None:
            for axis, p, m, tol in zip("xyz", position, self.position_mean, tolerance, strict=True):
                if abs(p - m) > tol:
                    reasons.append(f"final {axis} {p:.4f} m is {abs(p - m):.4f} m from {m:.4f} m")
        return reasons

    def to_json(self) -> dict[str, Any]:
        """The statistics with the pass rule's limits."""
        return {
            **asdict(self),
            "duration_limit_s": self.duration_limit_s,
            "position_tolerance_m": self.position_tolerance_m,
        }


def _successful_steps(
    records: Sequence[Mapping[str, Any]],
) -> dict[str, list[tuple[int, Mapping[str, Any]]]]:
    """Operation -> (mission index, step) of every step that succeeded, in step order."""
    by_step: dict[str, list[tuple[int, Mapping[str, Any]]]] = {}
    for record in records:
        for step in record.get("steps", []):
            if step["success"]:
                by_step.setdefault(step["step"], []).append((int(record["index"]), step))
    return by_step


def stats_of(name: str, steps: Sequence[Mapping[str, Any]]) -> OperationStats:
    """One operation's statistics over ``steps`` (at least one)."""
    durations = np.array([float(s["sim_time_s"]) for s in steps])
    energies = np.array([float(s["energy_wh"]) for s in steps])
    positions = [s["final_tool_position"] for s in steps if s.get("final_tool_position")]
    mean = std = None
    if positions:
        array = np.array(positions, dtype=float)
        mx, my, mz = (float(v) for v in array.mean(axis=0))
        sx, sy, sz = (float(v) for v in _std(array))
        mean, std = (mx, my, mz), (sx, sy, sz)
    return OperationStats(
        name,
        len(steps),
        float(durations.mean()),
        float(_std(durations)),
        mean,
        std,
        float(energies.mean()),
        float(_std(energies)),
    )


def operation_stats(records: Sequence[Mapping[str, Any]]) -> list[OperationStats]:
    """Each operation's statistics, in the missions' step order, over its successful steps."""
    return [
        stats_of(name, [s for _, s in steps]) for name, steps in _successful_steps(records).items()
    ]


def outside_pass_rule(records: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Each successful step that fails the pass rule of the same operation in the *other*
    missions (leave one out: an outlier does not widen its own limits); an operation needs
    :data:`MIN_REFERENCE` other steps."""
    outside = []
    for name, steps in _successful_steps(records).items():
        for i, (index, step) in enumerate(steps):
            others = [s for j, (_, s) in enumerate(steps) if j != i]
            if len(others) < MIN_REFERENCE:
                continue
            reasons = stats_of(name, others).check(step)
            if reasons:
                outside.append({"index": index, "step": name, "reasons": reasons})
    return sorted(outside, key=lambda o: o["index"])


def distribution(values: Sequence[float]) -> dict[str, Any]:
    """n, mean, std (sample), min, max and the values."""
    array = np.asarray(values, dtype=float)
    if len(array) == 0:
        return {"n": 0, "values": []}
    return {
        "n": len(array),
        "mean": float(array.mean()),
        "std": float(_std(array)),
        "min": float(array.min()),
        "max": float(array.max()),
        "values": array.tolist(),
    }


def summarise(records: Mapping[int, Mapping[str, Any]], missions: int) -> dict[str, Any]:
    """The campaign report's content (``report.json``) from the result lines by mission."""
    ordered = [records[k] for k in sorted(records)]
    stats = operation_stats(ordered)
    outside = outside_pass_rule(ordered)
    failed = [
        {
            "index": r["index"],
            "seed": r["seed"],
            "failed_step": r.get("failed_step"),
            "error": r.get("error", ""),
            "command": r["command"],
            "run_dir": r.get("run_dir"),
        }
        for r in ordered
        if not r.get("success")
    ]
    done = len(ordered)
    return {
        "missions": missions,
        "missions_done": done,
        "missions_succeeded": done - len(failed),
        "missions_failed": len(failed),
        "success_rate": (done - len(failed)) / done if done else 0.0,
        "operations": [s.to_json() for s in stats],
        "outside_pass_rule": outside,
        "ground_error_m": distribution(
            [r["ground_error_m"] for r in ordered if r.get("ground_error_m") is not None]
        ),
        **sample_statistics(ordered),
        "failed": failed,
        "with_faults": _rate([r for r in ordered if r.get("faults")]),
        "without_faults": _rate([r for r in ordered if not r.get("faults")]),
        "wall_time_s": distribution([r["wall_time_s"] for r in ordered if "wall_time_s" in r]),
    }


def sample_statistics(records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The delivered samples over the missions whose report has a sample section (the bags'
    regolith budget, :func:`ow_mission.sample_report.sample_summary`): ``delivered_volume_m3`` (the
    volume ingested from the dock, 0 for a mission that ingested nothing), ``top_layer_share``
    (over the missions that ingested a sample) and ``missions_with_sample``."""
    samples = [r["sample"] for r in records if r.get("sample")]
    return {
        "delivered_volume_m3": distribution([float(s["volume_m3"]) for s in samples]),
        "top_layer_share": distribution(
            [float(s["top_layer_share"]) for s in samples if s["top_layer_share"] is not None]
        ),
        "missions_with_sample": sum(1 for s in samples if s["ingested"]),
    }


def _rate(records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    succeeded = sum(1 for r in records if r.get("success"))
    return {"n": len(records), "succeeded": succeeded}


def markdown(name: str, summary: Mapping[str, Any], figures: Sequence[str]) -> str:
    """``report.md``."""
    lines = [
        f"# Campaign: {name}",
        "",
        f"{summary['missions_done']} of {summary['missions']} missions done; "
        f"{summary['missions_succeeded']} succeeded, {summary['missions_failed']} failed "
        f"(success rate {100 * summary['success_rate']:.1f} %).",
        f"With a fault schedule: {summary['with_faults']['succeeded']} of "
        f"{summary['with_faults']['n']} succeeded; without: "
        f"{summary['without_faults']['succeeded']} of {summary['without_faults']['n']}.",
        "",
        "## Operations (OceanWATERS' statistics: mean, std, n over the steps that succeeded)",
        "",
        "Pass rule: duration < mean + max(4 std, 10 s); each coordinate of the tool's final "
        "position within max(4 std, 1 cm) of its mean.",
        "",
        "| operation | n | duration s (mean +- std) | limit s | final position m (mean) "
        "| std m | tolerance m | energy Wh (mean +- std) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for op in summary["operations"]:
        pos, std, tol = op["position_mean"], op["position_std"], op["position_tolerance_m"]
        lines.append(
            f"| {op['step']} | {op['n']} | {op['duration_mean_s']:.2f} +- "
            f"{op['duration_std_s']:.2f} | {op['duration_limit_s']:.2f} | {_vector(pos)} | "
            f"{_vector(std)} | {_vector(tol)} | {op['energy_mean_wh']:.4f} +- "
            f"{op['energy_std_wh']:.4f} |"
        )
    lines += ["", "### Steps outside the pass rule (against the other missions)", ""]
    lines += [
        f"- mission {o['index']}, {o['step']}: {'; '.join(o['reasons'])}"
        for o in summary["outside_pass_rule"]
    ] or ["None."]
    ground = summary["ground_error_m"]
    lines += ["", "## Ground detection", ""]
    if ground["n"]:
        lines.append(
            f"Ground found minus the terrain's height at the contact, n = {ground['n']}: mean "
            f"{1000 * ground['mean']:.2f} mm, std {1000 * ground['std']:.2f} mm, range "
            f"[{1000 * ground['min']:.2f}, {1000 * ground['max']:.2f}] mm."
        )
    else:
        lines.append("No mission found the ground.")
    lines += ["", "## Delivered sample", ""]
    volume, top = summary["delivered_volume_m3"], summary["top_layer_share"]
    if volume["n"]:
        lines.append(
            f"{summary['missions_with_sample']} of {volume['n']} missions ingested a sample. "
            f"Volume ingested from the dock: mean {volume['mean']:.3g} m³, std "
            f"{volume['std']:.3g} m³, range [{volume['min']:.3g}, {volume['max']:.3g}] m³."
        )
        if top["n"]:
            lines.append(
                f"Share of it from the top layer, n = {top['n']}: mean "
                f"{100 * top['mean']:.1f} %, range [{100 * top['min']:.1f}, "
                f"{100 * top['max']:.1f}] %."
            )
    else:
        lines.append("No mission's report has a sample section.")
    lines += ["", "## Failed missions", ""]
    if summary["failed"]:
        lines += ["| mission | seed | failed step | error | replay |", "|---|---|---|---|---|"]
        lines += [
            f"| {f['index']} | {f['seed']} | {f['failed_step'] or '-'} | "
            f"{str(f['error']).replace('|', '/')[:200]} | `{f['command']}` |"
            for f in summary["failed"]
        ]
        drawable = [f for f in summary["failed"] if f.get("run_dir")]
        if drawable:
            lines += [
                "",
                "Their figures, drawn from their bags when wanted (a campaign's missions draw "
                "none unless it says `figures: inline`):",
                "",
                *(f"- mission {f['index']}: `{draw_command(f['run_dir'])}`" for f in drawable),
            ]
    else:
        lines.append("None.")
    lines += ["", "## Figures", ""]
    lines += [f"![{Path(f).stem}]({f})" for f in figures] or ["None (no mission finished)."]
    return "\n".join(lines) + "\n"


def _vector(v: Sequence[float] | None) -> str:
    return "-" if v is None else "(" + ", ".join(f"{c:.4f}" for c in v) + ")"


def plot(records: Mapping[int, Mapping[str, Any]], summary: Mapping[str, Any], out: Path) -> list:
    """Box plots of duration and energy per operation, the ground-error histogram; the files
    written (relative to ``out``'s parent)."""
    import matplotlib

    matplotlib.use("Agg")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # Debian's matplotlib beside the venv's
        import matplotlib.pyplot as plt

    names = [op["step"] for op in summary["operations"]]
    if not names:
        return []
    out.mkdir(parents=True, exist_ok=True)
    steps = [s for r in records.values() for s in r.get("steps", []) if s["success"]]
    written = []
    for key, label, file in (
        ("sim_time_s", "simulated duration (s)", "durations.png"),
        ("energy_wh", "energy with P0 (Wh)", "energies.png"),
    ):
        fig, ax = plt.subplots(figsize=(10, 4.5))
        ax.boxplot([[s[key] for s in steps if s["step"] == n] for n in names], tick_labels=names)
        ax.set_ylabel(label)
        ax.set_title(f"{label} per operation, {len(records)} missions")
        ax.tick_params(axis="x", rotation=30)
        fig.tight_layout()
        fig.savefig(out / file, dpi=90)
        plt.close(fig)
        written.append(f"{out.name}/{file}")
    errors = summary["ground_error_m"]["values"]
    if errors:
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.hist(1000 * np.asarray(errors), bins=max(5, min(30, len(errors))))
        ax.set_xlabel("ground found - terrain height at the contact (mm)")
        ax.set_ylabel("missions")
        ax.set_title(f"ground-detection error, n = {len(errors)}")
        fig.tight_layout()
        fig.savefig(out / "ground_error.png", dpi=90)
        plt.close(fig)
        written.append(f"{out.name}/ground_error.png")
    return written


def write_campaign_report(
    directory: Path, config: Any, records: Mapping[int, Mapping[str, Any]]
) -> dict[str, Any]:
    """Write ``report.json``, ``report.md`` and ``plots/`` into the campaign directory; the
    summary."""
    Path(directory).mkdir(parents=True, exist_ok=True)
    summary = summarise(records, config.missions)
    figures = plot(records, summary, Path(directory) / "plots")
    summary["name"] = config.name
    summary["seed"] = config.seed
    summary["figures"] = figures
    (Path(directory) / "report.json").write_text(json.dumps(summary, indent=2) + "\n")
    (Path(directory) / "report.md").write_text(markdown(config.name, summary, figures))
    return summary
