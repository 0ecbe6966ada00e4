"""ow_materials against OceanWATERS' definitions at HEAD (nasa/ow_simulator bdcabec0,
ow_materials/msg/): the same fields, so the same MD5 sums, which genmsg computes here from the
published field lists; and a bulk as the BulkExcavation /ground_truth/material_ingested carries."""

from __future__ import annotations

from fractions import Fraction

import genmsg
import genmsg.gentools
import genmsg.msg_loader
import pytest

from ow_materials.msg import BulkExcavation, MaterialConcentration
from ow_regolith.conversions import bulk_excavation
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
