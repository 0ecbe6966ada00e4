"""The delivered sample's part of a mission report, from the bags' regolith budget and
OceanWATERS' ingestion ground truth (no ROS: messages come from the bags, rosbags' classes)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ow_power.bagread import TopicMessages
from ow_regolith.budget import Account
from ow_runtime.names import MATERIAL_INGESTED, REGOLITH_BUDGET

#: The regolith's topics the sample section reads: the budget (latched, at each change) and the
#: ground truth of each ingestion (OceanWATERS' ow_materials/BulkExcavation).
SAMPLE_TOPICS = (REGOLITH_BUDGET, MATERIAL_INGESTED)


def sample_summary(messages: TopicMessages) -> dict[str, Any] | None:
    """The delivered sample, from the last ``/regolith/budget`` of the bags' ``messages`` (None
    when they have none): what was ingested from the dock (``volume_m3``, ``mass_kg``, the
    share of the volume of each material in ``composition`` and of each terrain layer in
    ``layers``, ``top_layer`` and ``top_layer_share``; shares None when nothing was ingested),
    ``budget_m3`` (where every volume the scoop took went: the six accounts) and
    ``dock_share`` (the part of the excavated volume that reached the dock: ingested + in the
    dock, over excavated). ``ground_truth`` is the last ``/ground_truth/material_ingested``:
    OceanWATERS' BulkExcavation (volume m^3, composition by material), or None.
    """
    budgets = messages.get(REGOLITH_BUDGET, [])
    if not budgets:
        return None
    last = budgets[-1][1]
    accounts = {a.value: getattr(last, a.value) for a in Account}  # RegolithBudget's fields
    ingested = accounts["ingested"]
    volume = float(ingested.volume)

    def shares(names: Sequence[str], volumes: Sequence[float]) -> dict[str, float] | None:
        if volume <= 0.0:
            return None
        return {str(n): float(v) / volume for n, v in zip(names, volumes, strict=True)}

    layers = shares(list(last.layers), list(ingested.layer_volumes))
    excavated = float(accounts["excavated"].volume)
    summary: dict[str, Any] = {
        "ingested": volume > 0.0,
        "volume_m3": volume,
        "mass_kg": float(ingested.mass),
        "composition": shares(list(last.materials), list(ingested.material_volumes)),
        "layers": layers,
        "top_layer": str(last.top_layer),
        "top_layer_share": None if layers is None else layers.get(str(last.top_layer), 0.0),
        "budget_m3": {name: float(a.volume) for name, a in accounts.items()},
        "dock_share": (
            (volume + float(accounts["in_dock"].volume)) / excavated if excavated > 0.0 else None
        ),
        "ground_truth": None,
    }
    truths = messages.get(MATERIAL_INGESTED, [])
    if truths:
        truth = truths[-1][1]
        summary["ground_truth"] = {
            "volume_m3": float(truth.volume),
            "composition": {str(c.name): float(c.proportion) for c in truth.composition},
            "stamp_s": float(truth.header.stamp.sec) + 1e-9 * float(truth.header.stamp.nanosec),
        }
    return summary


def sample_section(document: dict[str, Any], messages: TopicMessages) -> str | None:
    """``document['sample']`` (:func:`sample_summary`); a note when the bags hold no budget."""
    document["sample"] = sample_summary(messages)
    if document["sample"] is None:
        return f"no {REGOLITH_BUDGET} in the bags: no sample section."
    return None
