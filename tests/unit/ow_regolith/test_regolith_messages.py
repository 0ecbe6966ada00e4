"""ow_materials against OceanWATERS' definitions at HEAD (nasa/ow_simulator bdcabec0,
ow_materials/msg/): the same fields, so the same MD5 sums, which genmsg computes here from the
published field lists; a bulk as the BulkExcavation /ground_truth/material_ingested carries; and
the budget as the ow_msgs/RegolithBudget /regolith/budget carries."""

from __future__ import annotations

from fractions import Fraction

import genmsg
import genmsg.gentools
import genmsg.msg_loader
import pytest

from ow_materials.msg import BulkExcavation, MaterialConcentration
from ow_regolith.budget import HOLDING_ACCOUNTS, Account, RegolithBudget
from ow_regolith.config import DEFAULT_COLUMN
from ow_regolith.conversions import MAX_UM3, bulk_excavation, regolith_budget
from ow_regolith.materials import Bulk, MaterialDatabase

#: message -> its fields (type, name) in declaration order, as published at HEAD.
HEAD_FIELDS = {
    "MaterialConcentration": (("uint8", "id"), ("string", "name"), ("float32", "proportion")),
    "BulkExcavation": (
        ("std_msgs/Header", "header"),
        ("float64", "volume"),
        ("MaterialConcentration[]", "composition"),
    ),
}


def head_md5(name: str) -> str:
    """genmsg's MD5 of the published definition of ow_materials/``name``."""
    context = genmsg.MsgContext.create_default()
    search = {"std_msgs": ["/usr/share/std_msgs/msg"]}
    specs = {}
    for message in ("MaterialConcentration", "BulkExcavation"):
        text = "\n".join(f"{kind} {field}" for kind, field in HEAD_FIELDS[message])
        spec = genmsg.msg_loader.load_msg_from_string(context, text, f"ow_materials/{message}")
        context.register(f"ow_materials/{message}", spec)
        genmsg.msg_loader.load_depends(context, spec, search)
        specs[message] = spec
    return genmsg.gentools.compute_md5(context, specs[name])


@pytest.mark.parametrize("message", [MaterialConcentration, BulkExcavation])
def test_the_messages_are_oceanwaters_field_for_field(message):
    name = message.__name__
    # genpy names a type of the message's own package in full.
    types = [kind.removeprefix("ow_materials/") for kind in message._slot_types]
    assert tuple(zip(types, message.__slots__, strict=True)) == HEAD_FIELDS[name]
    assert message._md5sum == head_md5(name)


def test_the_md5_sums_are_those_genmsg_gives_for_head():
    # Computed once with genmsg_py.py from the two files at HEAD.
    assert BulkExcavation._md5sum == "86878e63871b0570ad6346ddac4dcaa7"
    assert MaterialConcentration._md5sum == "4e6fcc2108dea2e8a30b0c395c6a551c"


def test_a_bulk_becomes_a_bulk_excavation_by_material():
    database = MaterialDatabase({"ICE": 997.0, "MG_HYDRATES": 2660.0, "SALT": 2160.0})
    bulk = (
        Bulk.of("irradiated", "SALT", 10**12)
        + Bulk.of("irradiated", "ICE", 3 * 10**12)
        + Bulk.of("pristine", "ICE", 6 * 10**12)
    )
    msg = bulk_excavation(bulk, database)
    assert msg.volume == pytest.approx(1e-5)
    assert [(c.id, c.name) for c in msg.composition] == [(0, "ICE"), (2, "SALT")]
    assert [c.proportion for c in msg.composition] == pytest.approx([0.9, 0.1])
    assert bulk.composition() == {"ICE": Fraction(9, 10), "SALT": Fraction(1, 10)}
    assert bulk_excavation(Bulk(), database).composition == []


def test_the_budget_becomes_a_regolith_budget_by_account_layer_and_material():
    database = MaterialDatabase({"ICE": 997.0, "MG_HYDRATES": 2660.0, "SALT": 2160.0})
    budget = RegolithBudget()
    budget.excavate(Bulk.of("irradiated", "SALT", 10**12) + Bulk.of("pristine", "ICE", 3 * 10**12))
    budget.excavate(Bulk.of("snow", "ICE", 5))  # a layer of an earlier terrain's column
    budget.pour(Bulk.of("pristine", "ICE", 3 * 10**12), Account.IN_DOCK)
    budget.ingest()
    msg = regolith_budget(budget.snapshot(), database, DEFAULT_COLUMN)
    assert (msg.layers, msg.top_layer) == (["irradiated", "pristine", "snow"], "irradiated")
    assert msg.materials == ["ICE", "MG_HYDRATES", "SALT"]
    assert msg.excavated.volume_um3 == 4 * 10**12 + 5
    assert msg.excavated.volume_um3 == sum(
        getattr(msg, a.value).volume_um3 for a in HOLDING_ACCOUNTS
    )
    assert msg.ingested.layer_volumes == pytest.approx([0.0, 3e-6, 0.0])
    assert msg.ingested.material_volumes == pytest.approx([3e-6, 0.0, 0.0])
    assert msg.in_scoop.layer_volumes == pytest.approx([1e-6, 0.0, 5e-18])
    assert msg.in_scoop.mass == pytest.approx(1e-6 * 2160.0 + 5e-18 * 997.0)
    assert msg.spilled.volume == 0.0 and msg.spilled.layer_volumes == [0.0, 0.0, 0.0]


def test_a_volume_beyond_what_uint64_holds_saturates():
    budget = RegolithBudget()
    budget.excavate(Bulk.of("pristine", "ICE", 2**64 + 7))
    database = MaterialDatabase({"ICE": 997.0})
    msg = regolith_budget(budget.snapshot(), database, DEFAULT_COLUMN)
    assert msg.excavated.volume_um3 == MAX_UM3 == 2**64 - 1
    assert msg.excavated.volume == pytest.approx(18.446744073709553)
