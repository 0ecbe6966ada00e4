"""ow_regolith: regolith from trench to dock, with materials, in an exact volume budget.

Pure cores (no ROS): :mod:`~ow_regolith.materials` (materials, layered columns, bulks),
:mod:`~ow_regolith.config` (validated parameters), :mod:`~ow_regolith.budget` (the ledger of
excavated, in scoop, in dock, ingested, spilled and deposited regolith),
:mod:`~ow_regolith.scoop` (capacity and spilling from the scoop's shapes),
:mod:`~ow_regolith.landing` (where poured regolith lands), :mod:`~ow_regolith.carving_ledger`
(what each carve removed from the terrain, loose material per cell, deposits) and
:mod:`~ow_regolith.tracker` (the hooks a simulation calls). :mod:`~ow_regolith.conversions`
turns a bulk into OceanWATERS' ``ow_materials/BulkExcavation``. The model: docs/regolith.md.
"""
