"""Bulks as OceanWATERS' ``ow_materials/BulkExcavation`` messages (what
``/ground_truth/material_ingested`` carries)."""

from __future__ import annotations

from typing import Any

from ow_materials.msg import BulkExcavation, MaterialConcentration
from ow_regolith.materials import Bulk, MaterialDatabase


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
