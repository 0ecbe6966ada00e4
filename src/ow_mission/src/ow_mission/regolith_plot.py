"""The mission report's regolith figure (no ROS): where the excavated regolith is over the
mission, from the bags' ``/regolith/budget`` (``ow_msgs/RegolithBudget``, docs/regolith.md).

The numbers the figure shows are computed by a pure function (:func:`regolith_series`) that the
tests check on budgets they build; :func:`plot_regolith` only draws. The stack is summed in the
budget's exact unit (``volume_um3``, 1 µm³ = 1e-18 m³), so its top is the excavated volume to the
unit wherever the simulation's budget closes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_mission.errors import ReplayError
from ow_mission.plots import _pyplot
from ow_regolith.budget import HOLDING_ACCOUNTS

FloatArray = npt.NDArray[np.float64]
UIntArray = npt.NDArray[np.uint64]

#: The accounts the excavated volume is in (their RegolithBudget fields), stacked in this order.
PARTS = tuple(account.value for account in HOLDING_ACCOUNTS)
#: cm³ per µm³: the figure's unit (1 cm³ = 1e-6 m³) from the budget's exact one (1e-18 m³).
CM3_PER_UM3 = 1e-12
PART_COLOURS = {
    "in_scoop": "tab:orange",
    "in_dock": "tab:cyan",
    "ingested": "tab:green",
    "spilled": "tab:red",
    "deposited": "tab:brown",
}
LAYER_COLOURS = ("tab:olive", "tab:blue", "tab:purple", "tab:gray")


@dataclass(frozen=True)
class RegolithSeries:
    """The budget over the mission: each message holds until the next, the last one until
    ``end_s``.

    Attributes:
        t_s: (N,) s, simulation time of each budget (its bag time).
        parts_um3: (5, N) µm³, each account of :data:`PARTS` in each budget.
        excavated_um3: (N,) µm³, the excavated volume in each budget.
        end_s: s, the end of the time axis: the last step's end, or the last budget when later.
        windows: (step name, start s, end s) of the mission's steps.
        layers: the budget's terrain layers (``RegolithBudget.layers``), top down.
        top_layer: the present terrain's top layer.
        excavated_by_layer_m3: (L,) m³, the last budget's excavated volume by layer.
        ingested_by_layer_m3: (L,) m³, the last budget's ingested volume by layer.
    """

    t_s: FloatArray
    parts_um3: UIntArray
    excavated_um3: UIntArray
    end_s: float
    windows: list[tuple[str, float, float]]
    layers: list[str]
    top_layer: str
    excavated_by_layer_m3: FloatArray
    ingested_by_layer_m3: FloatArray

    @property
    def tops_um3(self) -> UIntArray:
        """(5, N) µm³, the top of each band of the stack: the parts summed in :data:`PARTS`
        order (integers: the last row is the excavated volume exactly when the budget closes)."""
        tops: UIntArray = np.cumsum(self.parts_um3, axis=0, dtype=np.uint64)
        return tops

    @property
    def unbalanced(self) -> int:
        """How many budgets' parts do not sum to their excavated volume to the µm³ (0: the
        budget closed at every message)."""
        return int(np.count_nonzero(self.tops_um3[-1] != self.excavated_um3))

    def final_cm3(self, account: str) -> float:
        """cm³, ``account`` (``excavated`` or one of :data:`PARTS`) in the last budget."""
        um3 = self.excavated_um3 if account == "excavated" else self.parts_um3[PARTS.index(account)]
        return float(um3[-1]) * CM3_PER_UM3

    def layer_shares(self, account: str) -> dict[str, float] | None:
        """The share of the volume of ``account`` (``excavated`` or ``ingested``) in the last
        budget from each layer, top down; None when it is empty."""
        volumes = self.ingested_by_layer_m3 if account == "ingested" else self.excavated_by_layer_m3
        total = float(np.sum(volumes))
        if total <= 0.0:
            return None
        return {name: float(v) / total for name, v in zip(self.layers, volumes, strict=True)}


def regolith_series(
    budgets: Sequence[tuple[int, Any]], windows: Sequence[tuple[str, float, float]]
) -> RegolithSeries:
    """The numbers of the regolith figure.

    Args:
        budgets: (bag time ns, ``ow_msgs/RegolithBudget``) of the bags in time order, as
            :func:`ow_power.bagread.read_messages` gives ``/regolith/budget`` (the generated
            message class has the same fields). The bag time is the receipt on the simulation
            clock: the first, latched budget may carry a zero stamp.
        windows: (step name, start s, end s) of the mission's steps, sim time.

    Raises:
        ReplayError: ``budgets`` is empty.
    """
    if not budgets:
        msg = "no /regolith/budget message: no regolith figure"
        raise ReplayError(msg)
    t_s = np.array([ns * 1e-9 for ns, _ in budgets], dtype=np.float64)
    msgs = [msg for _, msg in budgets]
    last = msgs[-1]
    parts = np.array(
        [[getattr(m, name).volume_um3 for m in msgs] for name in PARTS], dtype=np.uint64
    )
    excavated = np.array([m.excavated.volume_um3 for m in msgs], dtype=np.uint64)
    return RegolithSeries(
        t_s,
        parts,
        excavated,
        max([float(t_s[-1]), *(float(end) for _, _, end in windows)]),
        [(str(name), float(start), float(end)) for name, start, end in windows],
        [str(layer) for layer in last.layers],
        str(last.top_layer),
        np.array(last.excavated.layer_volumes, dtype=np.float64),
        np.array(last.ingested.layer_volumes, dtype=np.float64),
    )


def _shade_steps(ax: Any, windows: Sequence[tuple[str, float, float]]) -> None:
    """Each step shaded (alternate greys) and named above the axes, on two rows so that short
    steps' names do not overlap."""
    for i, (name, start, end) in enumerate(windows):
        ax.axvspan(start, end, color="0.93" if i % 2 else "0.86", lw=0, zorder=0)
        ax.annotate(
            name,
            ((start + end) / 2, 1.01 + 0.045 * (i % 2)),
            xycoords=("data", "axes fraction"),
            ha="center",
            va="bottom",
            fontsize=6,
        )


def _plot_layers(ax: Any, series: RegolithSeries) -> None:
    """100 % bars of the ingested sample and of all that was excavated, by terrain layer."""
    rows = [
        (label, shares)
        for label, shares in (
            ("ingested", series.layer_shares("ingested")),
            ("excavated", series.layer_shares("excavated")),
        )
        if shares is not None
    ]
    for y, (_, shares) in enumerate(rows):
        left = 0.0
        for k, (layer, share) in enumerate(shares.items()):
            colour = LAYER_COLOURS[k % len(LAYER_COLOURS)]
            ax.barh(y, 100 * share, left=left, color=colour, height=0.6, label=None if y else layer)
            if share >= 0.08:  # narrower bands leave their share to the legend's reader
                text = f"{100 * share:.1f} %"
                ax.text(left + 50 * share, y, text, ha="center", va="center", fontsize=7, color="w")
            left += 100 * share
    names = [f"{label}\n{series.final_cm3(label):.4g} cm³" for label, _ in rows]
    ax.set_yticks(range(len(rows)), names, fontsize=8)
    ax.set_ylim(len(rows) - 0.5, -0.5)
    ax.set_xlim(0, 100)
    ax.set_xlabel("share of the volume [%]")
    ax.set_title(f"by terrain layer at the end\n(top layer: {series.top_layer})", fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2)


def plot_regolith(series: RegolithSeries, png_path: Path) -> None:
    """Draw where the excavated regolith is over the mission (left: the accounts stacked, the
    excavated volume on top, cm³) and the composition by terrain layer of the ingested sample
    and of all that was excavated (right, when anything was excavated)."""
    plt = _pyplot()
    layers = series.layer_shares("excavated") is not None
    if layers:
        fig, (ax, ax_layers) = plt.subplots(1, 2, figsize=(12, 5), dpi=110, width_ratios=(3.2, 1))
    else:
        fig, ax = plt.subplots(figsize=(9, 5), dpi=110)
    _shade_steps(ax, series.windows)
    # Each budget holds until the next; the last one until the end of the axis.
    t = np.append(series.t_s, series.end_s)
    tops = np.concatenate([series.tops_um3, series.tops_um3[:, -1:]], axis=1) * CM3_PER_UM3
    bottom = np.zeros_like(t)
    for k, name in enumerate(PARTS):
        ax.fill_between(
            t,
            bottom,
            tops[k],
            step="post",
            color=PART_COLOURS[name],
            alpha=0.75,
            lw=0,
            label=f"{name.replace('_', ' ')} ({series.final_cm3(name):.4g} cm³ at the end)",
        )
        bottom = tops[k]
    ax.plot(
        t,
        np.append(series.excavated_um3, series.excavated_um3[-1]) * CM3_PER_UM3,
        color="k",
        lw=1.2,
        ls="--",
        drawstyle="steps-post",
        label=f"excavated ({series.final_cm3('excavated'):.4g} cm³ at the end)",
    )
    ax.set_xlim(min([t[0], *(start for _, start, _ in series.windows)]), t[-1])
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel("simulation time [s]")
    ax.set_ylabel("regolith volume [cm³] (1 cm³ = 1e-6 m³)")
    ax.grid(alpha=0.3)
    # Below the axes, as the power plot's: inside, it hid the stack wherever it was put.
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=3)
    n = len(series.t_s)
    # No message count: the recorder repeats the latest budget at the start of each bag file,
    # and where the files start is not a function of the run.
    closes = (
        "the parts sum to the excavated volume to the µm³ in every budget"
        if series.unbalanced == 0
        else f"the parts do NOT sum to the excavated volume in {series.unbalanced} of {n} budgets"
    )
    if layers:
        _plot_layers(ax_layers, series)
    fig.suptitle(
        f"Where the excavated regolith is (/regolith/budget, stacked): {closes}", fontsize=10
    )
    fig.tight_layout()
    fig.savefig(png_path, dpi=fig.dpi)  # not rcParams: progpy.visualize sets 300 on import
    plt.close(fig)
