"""Materials, layer columns and bulks: exact volumes, cuts through layer boundaries in closed
form, and clear errors."""

from __future__ import annotations

import math
import random
from fractions import Fraction

import pytest

from ow_regolith.config import DEFAULT_COLUMN
from ow_regolith.errors import MaterialError
from ow_regolith.materials import (
    UNITS_PER_M3,
    Bulk,
    Layer,
    LayerColumn,
    MaterialDatabase,
    apportion,
    summarize,
    units_from_m3,
)

DATABASE = MaterialDatabase({"SALT": 2160.0, "ICE": 997.0, "MG_HYDRATES": 2660.0})
#: m^2, a 4 cm cell.
AREA = 0.04**2


def test_ids_follow_the_names_alphabetically_as_in_oceanwaters():
    assert [(m.name, m.id) for m in DATABASE.materials] == [
        ("ICE", 0),
        ("MG_HYDRATES", 1),
        ("SALT", 2),
    ]
    assert DATABASE["SALT"].density_kg_m3 == 2160.0


def test_an_unknown_material_is_named_with_the_known_ones():
    with pytest.raises(MaterialError, match=r"unknown material 'SAND'; .* ICE, MG_HYDRATES, SALT"):
        DATABASE["SAND"]


@pytest.mark.parametrize("densities", [{}, {"ICE": 0.0}, {"ICE": math.nan}, {"": 1.0}])
def test_a_bad_database_is_refused(densities):
    with pytest.raises(MaterialError):
        MaterialDatabase(densities)


def test_apportion_is_exact_close_to_proportional_and_never_overdraws():
    rng = random.Random(7)
    for _ in range(500):
        weights = [rng.randrange(0, 10 ** rng.randrange(1, 16)) for _ in range(rng.randrange(1, 7))]
        if not sum(weights):
            continue
        amount = rng.randrange(0, sum(weights) + 1)
        parts = apportion(amount, weights)
        assert sum(parts) == amount
        for part, weight in zip(parts, weights, strict=True):
            assert 0 <= part <= weight
            assert abs(part - amount * weight / sum(weights)) < 1.0 + 1e-9 * amount


def test_bulks_add_subtract_take_and_split_exactly():
    a = Bulk({("irradiated", "ICE"): 850, ("irradiated", "SALT"): 50, ("pristine", "ICE"): 101})
    b = Bulk.of("pristine", "ICE", 9)
    assert (a + b).units == 1010
    assert (a + b) - b == a
    taken, rest = a.take(333)
    assert taken.units == 333 and taken + rest == a
    assert taken.parts[("irradiated", "ICE")] == pytest.approx(333 * 850 / 1001, abs=1)
    parts = a.split(7)
    assert sum(p.units for p in parts) == a.units
    assert max(p.units for p in parts) - min(p.units for p in parts) <= 1
    assert sum(parts, Bulk()) == a


def test_taking_more_than_a_bulk_holds_says_how_much_it_holds():
    bulk = Bulk.of("pristine", "ICE", 10)
    with pytest.raises(MaterialError, match="cannot take 11 units from a bulk of 10 units"):
        bulk.take(11)
    with pytest.raises(MaterialError, match="cannot take 12 units of ICE from layer 'pristine'"):
        bulk - Bulk.of("pristine", "ICE", 12)


def test_a_cut_through_the_layer_boundary_has_the_closed_form_composition():
    # From 6 cm to 16 cm below the surface: 4 cm of the irradiated layer (ICE 0.85, MG 0.10,
    # SALT 0.05), then 6 cm of pristine ice.
    bulk = DEFAULT_COLUMN.bulk_between(0.06, 0.16, AREA)
    top, below = 0.04 * AREA * UNITS_PER_M3, 0.06 * AREA * UNITS_PER_M3
    assert bulk.units == round(0.16 * AREA * UNITS_PER_M3) - round(0.06 * AREA * UNITS_PER_M3)
    assert bulk.by_layer()["irradiated"] == pytest.approx(top, abs=1)
    assert bulk.by_layer()["pristine"] == pytest.approx(below, abs=1)
    materials = bulk.by_material()
    assert materials["ICE"] == pytest.approx(0.85 * top + below, abs=2)
    assert materials["MG_HYDRATES"] == pytest.approx(0.10 * top, abs=1)
    assert materials["SALT"] == pytest.approx(0.05 * top, abs=1)
    assert bulk.layer_share("irradiated") == pytest.approx(0.4, abs=1e-12)
    summary = summarize(bulk, DATABASE, DEFAULT_COLUMN)
    assert summary.top_layer == "irradiated"
    assert summary.top_layer_share == pytest.approx(0.4, abs=1e-12)
    assert summary.composition["ICE"] == pytest.approx(0.4 * 0.85 + 0.6, abs=1e-12)
    assert summary.volume_m3 == pytest.approx(0.10 * AREA, rel=1e-12)
    expected_kg = (0.4 * (0.85 * 997 + 0.10 * 2660 + 0.05 * 2160) + 0.6 * 997) * 0.10 * AREA
    assert summary.mass_kg == pytest.approx(expected_kg, rel=1e-9)


def test_successive_cuts_add_up_to_one_cut_exactly():
    rng = random.Random(3)
    depths = sorted(rng.uniform(0.0, 0.3) for _ in range(40))
    steps = [
        DEFAULT_COLUMN.bulk_between(a, b, AREA)
        for a, b in zip([0.0, *depths[:-1]], depths, strict=True)
    ]
    whole = DEFAULT_COLUMN.bulk_between(0.0, depths[-1], AREA)
    summed = sum(steps, Bulk())
    assert summed.units == whole.units
    assert summed.by_layer() == whole.by_layer()


@pytest.mark.parametrize(
    ("layers", "match"),
    [
        ((), "at least one layer"),
        (
            (
                Layer("a", 0.0, 0.1, (("ICE", Fraction(1)),)),
                Layer("b", 0.2, math.inf, (("ICE", Fraction(1)),)),
            ),
            r"layer 'b' spans 0.2..inf m: .* beginning at 0.1 m",
        ),
        ((Layer("a", 0.0, 0.1, (("ICE", Fraction(1)),)),), "'a', must reach down"),
        (
            (Layer("a", 0.0, math.inf, (("ICE", Fraction(1, 2)),)),),
            r"layer 'a': composition .* summing to 1",
        ),
    ],
)
def test_a_bad_column_is_refused_with_the_reason(layers, match):
    with pytest.raises(MaterialError, match=match):
        LayerColumn(layers)


def test_volumes_round_to_the_nearest_unit_and_refuse_negative_ones():
    assert units_from_m3(1.4e-18) == 1
    assert units_from_m3(0.5e-3) == 5 * 10**14
    with pytest.raises(MaterialError, match="finite number >= 0"):
        units_from_m3(-1e-9)
