"""Bulks and the budget as messages: OceanWATERS' ``ow_materials/BulkExcavation`` (what
``/ground_truth/material_ingested`` carries) and ``ow_msgs/RegolithBudget`` (``/regolith/
budget``)."""

from __future__ import annotations

from typing import Any

from ow_materials.msg import BulkExcavation, MaterialConcentration
from ow_msgs.msg import RegolithAccount, RegolithBudget
from ow_regolith.budget import Account, BudgetSnapshot
from ow_regolith.materials import UNIT_M3, Bulk, LayerColumn, MaterialDatabase

#: The largest volume a RegolithAccount's ``volume_um3`` (uint64) holds: 18.4 m^3.
MAX_UM3 = 2**64 - 1


def bulk_excavation(bulk: Bulk, database: MaterialDatabase, stamp: Any = None) -> BulkExcavation:
    """``bulk`` as a BulkExcavation: its volume (m^3) and one MaterialConcentration per material
    it holds (id and name from ``database``, share of the volume), in id order.

    Args:
        bulk: the regolith.
        database: the materials (ids are their alphabetical indices).
        stamp: the header's time (a ``rospy.Time``), left zero when None.

    Raises:
        MaterialError: a material the database does not have.
    """
    msg = BulkExcavation()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.volume = bulk.volume_m3
    shares = bulk.composition()
    materials = sorted((database[name] for name in shares), key=lambda m: m.id)
    msg.composition = [
        MaterialConcentration(id=m.id, name=m.name, proportion=float(shares[m.name]))
        for m in materials
    ]
    return msg


def budget_layers(snapshot: BudgetSnapshot, column: LayerColumn) -> list[str]:
    """The layers a budget message lists: ``column``'s top down, then every other layer some
    account holds regolith of (an earlier terrain's), alphabetically."""
    names = [layer.name for layer in column.layers]
    others = {layer for bulk in snapshot.accounts.values() for layer in bulk.by_layer()}
    return names + sorted(others - set(names))


def regolith_budget(
    snapshot: BudgetSnapshot, database: MaterialDatabase, column: LayerColumn, stamp: Any = None
) -> RegolithBudget:
    """The budget ``snapshot`` as a RegolithBudget: each account's volume (m^3 and exactly in
    um^3), mass (kg), and its volume by layer (:func:`budget_layers`) and by material (id order).

    Args:
        snapshot: the accounts.
        database: the materials.
        column: the present terrain's layer column (its top layer is ``top_layer``).
        stamp: the header's time (a ``rospy.Time``), left zero when None.

    Raises:
        MaterialError: a material the database does not have.
    """
    layers = budget_layers(snapshot, column)
    msg = RegolithBudget(layers=layers, top_layer=column.top_layer, materials=list(database.names))
    if stamp is not None:
        msg.header.stamp = stamp
    for account in Account:
        bulk = snapshot.accounts[account]
        by_layer, by_material = bulk.by_layer(), bulk.by_material()
        setattr(
            msg,
            account.value,
            RegolithAccount(
                volume=bulk.volume_m3,
                volume_um3=min(bulk.units, MAX_UM3),
                mass=bulk.mass_kg(database),
                layer_volumes=[by_layer.get(name, 0) * UNIT_M3 for name in layers],
                material_volumes=[by_material.get(name, 0) * UNIT_M3 for name in database.names],
            ),
        )
    return msg
