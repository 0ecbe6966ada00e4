"""Regenerate the default force table with YADE: ``python -m ow_dem_bridge.make_tables``.

``make dem-tables`` runs this module. It

1. settles one granular bed per material (YADE, saved once and reloaded by every dig),
2. digs each bed with the scoop (paper Table 4 motion) and with the grinder at several depths,
   one YADE process per core, all seeded,
3. averages each run's wrench samples into progress bins and writes the table in the
   ``ow_dem_bridge`` format (:mod:`ow_dem_bridge.table`), a provenance JSON (scenario, YADE version,
   wall times) next to it, and a plot of the force components along the dig (paper Figure 19).

The scenario (materials, particle scaling, depths, motion) is :func:`default_scenario`; see
docs/dem.md for the reasons behind each number.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import csv
import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ow_dem_bridge.balovnev import BalovnevParams, balovnev_forces
from ow_dem_bridge.errors import DemRunError
from ow_dem_bridge.geometry import ToolGeometry, load_tool
from ow_dem_bridge.table import FORCE_COLUMNS, ForceTable, Series, write_table
from ow_description.description import EUROPA_GRAVITY, URDF_PATH

#: The YADE scenario script, run as a subprocess.
YADE_SCRIPT = Path(__file__).with_name("yade_dig.py")
#: The package's data directory (default table, its provenance and plot).
DATA_DIR = Path(__file__).resolve().parents[2] / "data"
DEFAULT_TABLE = DATA_DIR / "default_table.csv"


@dataclass(frozen=True)
class Soil:
    """A DEM material (paper Table 5 style), SI units.

    Attributes:
        name: short name for the docs and the plot.
        shear_modulus: Pa.
        poisson: Poisson ratio.
        static_friction: particle-particle (and particle-tool, the smaller wins) Coulomb friction.
        rolling_friction: rolling friction coefficient (moment cap mu_r R F_n).
        restitution: coefficient of restitution.
        density: kg/m3, solid density of a particle.
        source: where the numbers come from.
    """

    name: str
    shear_modulus: float
    poisson: float
    static_friction: float
    rolling_friction: float
    restitution: float
    density: float
    source: str


#: Paper Table 5: sand, elastic, non-cohesive.
SAND = Soil("sand", 1e7, 0.25, 0.35, 0.05, 0.88, 1600.0, "paper Table 5")
#: OceanWATERS CosimulationPlugin example particle set (EDEM), a light, high-friction granular
#: material (E 2.72e7 Pa and Poisson 0.36 give G = 1.0e7 Pa).
SNOW = Soil("snow", 1.0e7, 0.36, 0.58, 0.05, 0.88, 300.0, "OceanWATERS CosimulationPlugin example")
#: Aluminium tool and container walls (CosimulationPlugin example link: E 6.9e10 Pa, Poisson 0.33,
#: static friction 0.58).
ALUMINIUM = Soil(
    "aluminium", 6.9e10 / (2 * 1.33), 0.33, 0.58, 0.05, 0.7, 2700.0, "CosimulationPlugin"
)


@dataclass(frozen=True)
class Scenario:
    """Everything that defines a regeneration (all SI units).

    Attributes:
        materials: table material id -> soil.
        scoop_depths: m, cut depths of the scoop runs.
        grinder_depths: m, plunge depths of the grinder runs.
        particle_radius: m, mean sphere radius (scaled up from the paper's 1.75 mm).
        radius_fuzz: relative spread of the radii (uniform).
        gravity: m/s2 during the digs (Europa's, ``ow_description.description.EUROPA_GRAVITY``).
        dt_safety: time step as a fraction of the Rayleigh step.
        read_steps: DEM steps between two reads of the wrench.
        reads_per_row: reads averaged into one recorded sample.
        progress_step: m, width of the progress bins of the table.
        scoop_bed: m, (length, width, depth) of the scoop bed.
        grinder_bed: m, (length, width, depth) of the grinder bed.
        scoop_motion: the Table 4 motion (see yade_dig.py).
        grinder_motion: plunge and drag of the grinder.
        seed: random seed of the sphere clouds.
        settle_time_max: s of simulated settling at most.
    """

    materials: dict[int, Soil] = field(default_factory=lambda: {1: SAND, 2: SNOW})
    scoop_depths: tuple[float, ...] = (0.02, 0.04)
    grinder_depths: tuple[float, ...] = (0.02, 0.05)
    particle_radius: float = 0.01
    radius_fuzz: float = 0.15
    gravity: float = EUROPA_GRAVITY
    dt_safety: float = 0.3
    read_steps: int = 5
    reads_per_row: int = 4
    progress_step: float = 0.01
    scoop_bed: tuple[float, float, float] = (0.66, 0.18, 0.09)
    grinder_bed: tuple[float, float, float] = (0.3, 0.18, 0.1)
    scoop_motion: dict[str, float] = field(
        default_factory=lambda: {
            "x_cut": 0.22,
            "pivot_height": 0.36,
            "rotation_deg": 90.0,
            "rotation_rate_deg": 30.0,
            "linear_speed": 0.1,
            "linear_length": 0.3,
        }
    )
    grinder_motion: dict[str, float] = field(
        default_factory=lambda: {
            "x_cut": 0.09,
            "plunge_speed": 0.05,
            "linear_speed": 0.1,
            "linear_length": 0.12,
        }
    )
    seed: int = 1
    settle_time_max: float = 1.5


def smoke_scenario() -> Scenario:
    """A tiny scenario (a few hundred large spheres, short motions) for the test suite."""
    return Scenario(
        materials={1: SAND},
        scoop_depths=(0.02,),
        grinder_depths=(),
        particle_radius=0.012,
        dt_safety=0.35,
        scoop_bed=(0.4, 0.16, 0.05),
        scoop_motion={**Scenario().scoop_motion, "x_cut": 0.2, "linear_length": 0.05},
        settle_time_max=0.4,
    )


@dataclass(frozen=True)
class Job:
    """One YADE process: its JSON job file and what it produces."""

    name: str
    path: Path
    summary: Path
    out_csv: Path | None = None
    tool: str = ""
    material: int = 0
    depth: float = 0.0


def _soil_json(soil: Soil) -> dict[str, Any]:
    return asdict(soil)


def _job_base(scenario: Scenario, soil: Soil, bed: tuple[float, float, float]) -> dict[str, Any]:
    return {
        "seed": scenario.seed,
        "soil": _soil_json(soil),
        "tool_material": _soil_json(ALUMINIUM),
        "particle_radius": scenario.particle_radius,
        "radius_fuzz": scenario.radius_fuzz,
        "dt_safety": scenario.dt_safety,
        "bed": {"length": bed[0], "width": bed[1], "depth": bed[2]},
        "settle_time_max": scenario.settle_time_max,
    }


def _write_job(path: Path, job: dict[str, Any]) -> None:
    path.write_text(json.dumps(job, indent=1))


def plan_jobs(
    scenario: Scenario, workdir: Path, tools: dict[str, ToolGeometry]
) -> tuple[list[Job], list[Job]]:
    """Write the job files of a regeneration.

    Args:
        scenario: what to simulate.
        workdir: directory for job files, beds and raw samples.
        tools: "scoop" / "grinder" -> geometry.

    Returns:
        (settle jobs, dig jobs); every dig needs its bed's settle job to have run.
    """
    settles: list[Job] = []
    digs: list[Job] = []
    plans = [("scoop", scenario.scoop_bed, scenario.scoop_depths, scenario.scoop_motion)]
    if scenario.grinder_depths:
        plans.append(
            ("grinder", scenario.grinder_bed, scenario.grinder_depths, scenario.grinder_motion)
        )
    for material, soil in scenario.materials.items():
        for tool, bed, depths, motion in plans:
            base = _job_base(scenario, soil, bed)
            bed_file = workdir / f"bed_{tool}_m{material}.yade.gz"
            name = f"settle_{tool}_m{material}"
            settle = {**base, "mode": "settle", "bed_file": str(bed_file)}
            settle["summary"] = str(workdir / f"{name}.summary.json")
            _write_job(workdir / f"{name}.json", settle)
            settles.append(Job(name, workdir / f"{name}.json", Path(settle["summary"])))
            geometry = tools[tool]
            for depth in depths:
                name = f"dig_{tool}_m{material}_d{depth * 1000:.0f}mm"
                out_csv = workdir / f"{name}.csv"
                dig = {
                    **base,
                    "mode": "dig",
                    "bed_file": str(bed_file),
                    "gravity": scenario.gravity,
                    "depth": depth,
                    "tool": {
                        "kind": tool,
                        "facets": [list(map(list, tri)) for tri in geometry.facets],
                        "com": geometry.com.tolist(),
                        "tip": geometry.tip.tolist(),
                    },
                    "motion": motion,
                    "read_steps": scenario.read_steps,
                    "reads_per_row": scenario.reads_per_row,
                    "out_csv": str(out_csv),
                    "summary": str(workdir / f"{name}.summary.json"),
                }
                _write_job(workdir / f"{name}.json", dig)
                digs.append(
                    Job(
                        name,
                        workdir / f"{name}.json",
                        Path(dig["summary"]),
                        out_csv,
                        tool,
                        material,
                        depth,
                    )
                )
    return settles, digs


def yade_executable() -> str:
    """Path of the ``yade`` launcher.

    Raises:
        DemRunError: YADE is not installed (``apt-get install yade``, part of ``make setup``).
    """
    exe = shutil.which("yade")
    if exe is None:
        msg = "the 'yade' executable is not on PATH; install the Debian package 'yade' (make setup)"
        raise DemRunError(msg)
    return exe


def run_yade(job: Job, timeout_s: float = 3600.0) -> dict[str, Any]:
    """Run one job in its own YADE process (one core); return its summary.

    Raises:
        DemRunError: YADE failed, timed out, or wrote no summary (the message has its log tail).
    """
    log = job.path.with_suffix(".log")
    cmd = [yade_executable(), "-n", "-x", "-j1", str(YADE_SCRIPT), str(job.path)]
    # YADE runs on the system Python; the venv's variables only make it warn.
    env = {k: v for k, v in os.environ.items() if k != "VIRTUAL_ENV"}
    env["OMP_NUM_THREADS"] = "1"
    with log.open("wb") as fh:
        try:
            proc = subprocess.run(
                cmd, stdout=fh, stderr=subprocess.STDOUT, timeout=timeout_s, env=env, check=False
            )
        except subprocess.TimeoutExpired as exc:
            msg = f"YADE job {job.name} did not finish within {timeout_s} s (log {log})"
            raise DemRunError(msg) from exc
    if proc.returncode != 0 or not job.summary.exists():
        tail = "\n".join(log.read_text(errors="replace").splitlines()[-15:])
        msg = f"YADE job {job.name} failed with exit code {proc.returncode}:\n{tail}"
        raise DemRunError(msg)
    return dict(json.loads(job.summary.read_text()))


def run_all(jobs: Sequence[Job], workers: int) -> dict[str, dict[str, Any]]:
    """Run jobs, ``workers`` YADE processes at a time; return summaries by job name."""
    with concurrent.futures.ThreadPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(run_yade, job): job for job in jobs}
        return {futures[f].name: f.result() for f in concurrent.futures.as_completed(futures)}


def read_samples(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A dig's samples: (progress (n,) m, wrench (n, 6) N and N m in the link frame)."""
    progress: list[float] = []
    wrench: list[list[float]] = []
    with path.open(newline="") as fh:
        for row in csv.DictReader(fh):
            progress.append(float(row["progress_m"]))
            wrench.append(
                [float(row[k]) for k in ("Fx_N", "Fy_N", "Fz_N", "Tx_Nm", "Ty_Nm", "Tz_Nm")]
            )
    return np.asarray(progress), np.asarray(wrench).reshape(-1, 6)


def bin_samples(
    progress: np.ndarray, wrench: np.ndarray, step: float
) -> tuple[np.ndarray, np.ndarray]:
    """Average samples into progress bins of ``step`` m; keys are the bins' mean progress.

    A key at progress 0 with a zero wrench starts the series, so that the table rises from zero
    as a tool enters the ground.

    Returns:
        (keys (k,) m strictly increasing, wrench (k, 6)).
    """
    keys: list[float] = [0.0]
    values: list[np.ndarray] = [np.zeros(6)]
    if progress.size:
        index = np.floor(progress / step).astype(int)
        for b in np.unique(index):
            mask = index == b
            key = float(progress[mask].mean())
            if key > keys[-1]:
                keys.append(key)
                values.append(wrench[mask].mean(axis=0))
    return np.asarray(keys), np.asarray(values)


def build_table(digs: Iterable[Job], progress_step: float) -> ForceTable:
    """The force table of a set of finished digs (one series per tool, material and depth)."""
    series: list[Series] = []
    for job in digs:
        assert job.out_csv is not None
        progress, wrench = read_samples(job.out_csv)
        keys, values = bin_samples(progress, wrench, progress_step)
        series.append(Series(job.tool, job.material, job.depth, keys, values))
    return ForceTable.from_series(series)


def phase_mean(path: Path, phase: str) -> np.ndarray:
    """(6,) mean wrench of a dig's samples in one motion phase ("linear", "rotate_in", ...)."""
    with path.open(newline="") as fh:
        rows = [
            [float(r[k]) for k in ("Fx_N", "Fy_N", "Fz_N", "Tx_Nm", "Ty_Nm", "Tz_Nm")]
            for r in csv.DictReader(fh)
            if r["phase"] == phase
        ]
    return np.asarray(rows).mean(axis=0) if rows else np.zeros(6)


def balovnev_comparison(digs: Iterable[Job], scenario: Scenario) -> list[dict[str, Any]]:
    """DEM vs Balovnev for the same cut: mean scoop force over the straight part of each dig.

    Balovnev is evaluated at the dig's depth and gravity twice: with the OceanWATERS constants
    (soil 1700 kg/m3) and with the bulk density of the DEM bed (particle density times 0.6).

    Returns:
        One record per scoop dig: material, depth m, DEM (-Fx, Fz) N, Balovnev (H, V) N.
    """
    out = []
    for job in digs:
        if job.tool != "scoop" or job.out_csv is None:
            continue
        mean = phase_mean(job.out_csv, "linear")
        soil = scenario.materials[job.material]
        base = BalovnevParams(gravity=scenario.gravity)
        bulk = replace(base, soil_density=0.6 * soil.density)
        out.append(
            {
                "material": job.material,
                "depth_m": job.depth,
                "dem_resisting_N": round(float(-mean[0]), 3),
                "dem_vertical_N": round(float(mean[2]), 3),
                "balovnev_H_V_N": [round(v, 3) for v in balovnev_forces(job.depth, base)],
                "balovnev_bulk_density_H_V_N": [
                    round(v, 3) for v in balovnev_forces(job.depth, bulk)
                ],
            }
        )
    return sorted(out, key=lambda r: (r["material"], r["depth_m"]))


def yade_version() -> str:
    """The installed YADE version string (empty if unknown)."""
    try:
        out = subprocess.run(
            [yade_executable(), "--version"],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        ).stdout
    except (DemRunError, OSError, subprocess.TimeoutExpired):
        return ""
    lines = [line for line in out.splitlines() if "version:" in line.lower()]
    return lines[-1].split(":", 1)[1].strip() if lines else ""


def plot_table(table: ForceTable, materials: dict[int, Soil], path: Path) -> None:
    """Plot Fx, Fy, Fz of every scoop series along the dig (like the paper's Figure 19)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mats = sorted({s.material for s in table.series if s.tool == "scoop"})
    fig, axes = plt.subplots(3, len(mats), figsize=(5 * len(mats), 7), sharex=True, squeeze=False)
    for col, material in enumerate(mats):
        for s in table.series:
            if s.tool != "scoop" or s.material != material:
                continue
            for row in range(3):
                axes[row][col].plot(
                    s.progress, s.wrench[:, row], label=f"d = {s.depth * 1000:.0f} mm"
                )
        name = materials[material].name if material in materials else f"m{material}"
        axes[0][col].set_title(f"scoop, material {material} ({name})")
        for row, comp in enumerate(FORCE_COLUMNS[:3]):
            axes[row][col].set_ylabel(f"{comp} (N, l_scoop frame)")
            axes[row][col].grid(True, alpha=0.3)
        axes[2][col].set_xlabel("progress: tip path below the surface (m)")
        axes[0][col].legend(fontsize=8)
    fig.suptitle("YADE, paper Table 4 motion, Europa gravity: force on the scoop along the dig")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def regenerate(
    scenario: Scenario,
    out_table: Path,
    workdir: Path,
    workers: int = 2,
    urdf: Path | None = None,
    plot: Path | None = None,
) -> dict[str, Any]:
    """Run the whole pipeline; write the table, its provenance JSON and optionally the plot.

    Args:
        scenario: what to simulate.
        out_table: path of the table CSV to write; the provenance goes to ``<stem>.json``.
        workdir: scratch directory for job files, beds, logs and raw samples.
        workers: YADE processes at a time (one per core).
        urdf: lander URDF (default: ow_lander's).
        plot: PNG to write, or None.

    Returns:
        The provenance record (also written as JSON).

    Raises:
        DemRunError: YADE is missing or a run failed.
    """
    start = time.monotonic()
    if urdf is None:
        urdf = URDF_PATH
    workdir.mkdir(parents=True, exist_ok=True)
    tools = {"scoop": load_tool(urdf, "l_scoop"), "grinder": load_tool(urdf, "l_grinder")}
    settles, digs = plan_jobs(scenario, workdir, tools)
    t0 = time.monotonic()
    settle_summaries = run_all(settles, workers)
    t1 = time.monotonic()
    # Longest first (light materials need smaller steps; the scoop bed is the biggest), so that
    # the two workers finish together.
    soils = scenario.materials
    order = sorted(digs, key=lambda j: (j.tool != "scoop", soils[j.material].density, -j.depth))
    dig_summaries = run_all(order, workers)
    t2 = time.monotonic()
    table = build_table(digs, scenario.progress_step)
    header = [
        "ow_dem_bridge force table, made by `make dem-tables` "
        "(python -m ow_dem_bridge.make_tables)",
        f"YADE {yade_version()}, particle radius {scenario.particle_radius} m, "
        f"gravity {scenario.gravity} m/s2",
        "materials: "
        + "; ".join(f"{m} = {s.name} ({s.source})" for m, s in scenario.materials.items()),
    ]
    out_table.parent.mkdir(parents=True, exist_ok=True)
    write_table(table, out_table, header)
    if plot is not None:
        plot_table(table, scenario.materials, plot)
    record = {
        "table": out_table.name,
        "yade": yade_version(),
        "workers": workers,
        "cpu_count": os.cpu_count(),
        "wall_time_s": round(time.monotonic() - start, 1),
        "settle_wall_time_s": round(t1 - t0, 1),
        "dig_wall_time_s": round(t2 - t1, 1),
        "scenario": {
            **{k: v for k, v in asdict(scenario).items() if k != "materials"},
            "materials": {str(m): asdict(s) for m, s in scenario.materials.items()},
        },
        "runs": {**settle_summaries, **dig_summaries},
        "dem_vs_balovnev": balovnev_comparison(digs, scenario),
    }
    out_table.with_suffix(".json").write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    return record


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: regenerate the default table (or a smoke-size one with ``--smoke``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_TABLE, help="table CSV to write")
    parser.add_argument("--plot", type=Path, default=None, help="plot PNG (default: next to --out)")
    parser.add_argument(
        "--workdir", type=Path, default=None, help="scratch dir (default: build/dem)"
    )
    parser.add_argument("--workers", type=int, default=2, help="YADE processes at a time")
    parser.add_argument("--smoke", action="store_true", help="tiny scenario (seconds)")
    parser.add_argument("--depths", type=float, nargs="*", help="override scoop depths, m")
    args = parser.parse_args(argv)
    scenario = smoke_scenario() if args.smoke else Scenario()
    if args.depths:
        scenario = replace(scenario, scoop_depths=tuple(args.depths))
    workdir = args.workdir or Path.cwd() / "build" / "dem"
    plot = args.plot or args.out.with_suffix(".png")
    try:
        record = regenerate(scenario, args.out, workdir, args.workers, plot=plot)
    except DemRunError as exc:
        print(f"make_tables: {exc}", file=sys.stderr)
        return 1
    print(
        f"wrote {args.out} ({len(record['runs'])} YADE runs, {record['wall_time_s']} s wall, "
        f"{args.workers} workers) and {plot}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
