"""The live DEM figure of a ``terrain_forces: yade`` mission, like the seed paper's Figure 19: each
dig's scoop force components from the live DEM, with those the shipped table and Balovnev give
for the same recorded states (no ROS; :mod:`ow_mission.live_dem_report` makes the series)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ow_dem_bridge.api import FloatArray
from ow_dem_bridge.comparison import COMPONENTS
from ow_mission.plots import _pyplot

#: Line style per series: the live DEM solid and dark, the offline models dashed and dotted.
STYLES: dict[str, dict[str, object]] = {
    "live DEM": {"color": "k", "lw": 1.3, "ls": "-"},
    "table": {"color": "tab:blue", "lw": 1.1, "ls": "--"},
    "balovnev": {"color": "tab:red", "lw": 1.1, "ls": ":"},
}


def plot_live_dem(
    digs: Sequence[tuple[str, FloatArray, FloatArray, Mapping[str, FloatArray]]],
    nrmsd: Sequence[Mapping[str, Mapping[str, float]]],
    png_path: Path,
) -> None:
    """Draw one row per dig, one column per force component (Fx, Fy, Fz, l_scoop frame, N)
    against the dig's sim time: the live DEM's and each compared model's, with the model's NRMSD
    against the live DEM in the legend.

    Args:
        digs: per dig, (step name, (N,) s of sim time, (N, >=3) live wrench rows, {model: its
            (N, >=3) rows for the same states}).
        nrmsd: per dig, {model: {component: NRMSD}} (NaN where the live component is flat).
        png_path: where the PNG goes.

    Raises:
        ValueError: no dig, or ``nrmsd`` not one per dig.
    """
    if not digs:
        raise ValueError("no dig to draw")
    if len(nrmsd) != len(digs):
        msg = f"{len(nrmsd)} NRMSD entries for {len(digs)} digs"
        raise ValueError(msg)
    plt = _pyplot()
    rows = len(digs)
    fig, axes = plt.subplots(
        rows, len(COMPONENTS), figsize=(13, 3.0 * rows + 0.8), dpi=100, squeeze=False
    )
    for r, ((step, times, live, models), scores) in enumerate(zip(digs, nrmsd, strict=True)):
        t = np.asarray(times, dtype=np.float64) - float(times[0])
        for k, component in enumerate(COMPONENTS):
            ax = axes[r][k]
            ax.plot(t, np.asarray(live)[:, k], label="live DEM", **STYLES["live DEM"])
            for name, rows_n in models.items():
                score = scores.get(name, {}).get(component, float("nan"))
                text = "-" if not np.isfinite(score) else f"{score:.2f}"
                style = STYLES.get(name, {"lw": 1.0})
                ax.plot(t, np.asarray(rows_n)[:, k], label=f"{name} (NRMSD {text})", **style)
            ax.set_title(f"{step}: {component}", fontsize=9)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="best")
            if k == 0:
                ax.set_ylabel("force [N]")
            if r == rows - 1:
                ax.set_xlabel(f"s from the dig's first sample at {float(times[0]):.1f} s")
    fig.suptitle(
        "The scoop's force in the ground: live DEM against the shipped table and Balovnev for "
        "the same states (the seed's Figure 19 for our scoop)",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(png_path, dpi=fig.dpi)  # not rcParams: progpy.visualize sets 300 on import
    plt.close(fig)
