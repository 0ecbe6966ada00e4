"""The scoop as a container and where its regolith lands: capacity against the closed-form
volume of its boxes, the spill rule at tilts 0, 45, +-90 and 180 degrees, the dock."""

from __future__ import annotations

import math

import numpy as np
import pytest
from regolith_scenes import BOTTOM_DOWN, GROUND_Z, field_terrain, pose, scoop_pouring_at

from ow_description.shapes import link_shapes
from ow_regolith.budget import Account
from ow_regolith.errors import GeometryError
from ow_regolith.landing import Landing
from ow_regolith.materials import UNIT_M3, Bulk
from ow_regolith.polytope import Halfspace, volume
from ow_regolith.scoop import ScoopGeometry, ScoopShapes


def closed_form() -> dict[str, float]:
    """The scoop's cavity from its boxes by hand. Every plate of the scoop is pitched by the
    bottom's pitch (the back by a further -90 degrees) and the side walls stand across y, so the
    cavity is a box in the pitched axes u (along the bottom) and w (towards the bottom): from the
    back plate's inner face to the side walls' front ends, from the top plate's inner face to the
    bottom plate's, between the side walls' inner faces."""
    shapes = {s.name: s for s in link_shapes("l_scoop")}
    pitch = shapes["bottom"].rpy[1]
    u = np.array([math.cos(pitch), 0.0, -math.sin(pitch)])
    w = np.array([math.sin(pitch), 0.0, math.cos(pitch)])

    def centre(name: str) -> np.ndarray:
        return np.array(shapes[name].xyz)

    side = shapes["left"]
    u_back = max(
        centre("back") @ u + shapes["back"].size[2] / 2,  # the back plate's inner face
        centre("left") @ u - side.size[0] / 2,  # the side walls' back ends
    )
    u_front = centre("left") @ u + side.size[0] / 2
    w_top = max(
        centre("top") @ w + shapes["top"].size[2] / 2, centre("left") @ w - side.size[1] / 2
    )
    w_bottom = min(
        centre("bottom") @ w - shapes["bottom"].size[2] / 2, centre("left") @ w + side.size[1] / 2
    )
    width = 2 * abs(side.xyz[1]) - side.size[2]
    rim_front = centre("top") @ u + shapes["top"].size[0] / 2
    return {
        "length": u_front - u_back,
        "depth": w_bottom - w_top,
        "width": width,
        "rim_front": rim_front - u_back,
    }


def test_capacity_is_the_closed_form_volume_of_the_boxes(geometry):
    box = closed_form()
    capacity = box["length"] * box["depth"] * box["width"]
    assert geometry.capacity_m3 == pytest.approx(capacity, rel=1e-4)
    # About 0.67 l: the Phoenix-like scoop, 11.5 x 8 x 7.3 cm inside.
    assert geometry.capacity_m3 == pytest.approx(6.68e-4, rel=1e-3)
    assert geometry.width == pytest.approx(box["width"], rel=1e-6)
    assert geometry.capacity_units * UNIT_M3 == pytest.approx(geometry.capacity_m3, rel=1e-12)


@pytest.mark.parametrize(
    ("tilt_deg", "fraction"),
    [
        (0.0, lambda b: 1.0),
        # Mouth edge down: the mouth's front corner is the cavity's lowest point.
        (90.0, lambda b: 0.0),
        (180.0, lambda b: 0.0),
        (-180.0, lambda b: 0.0),
        # Edge up: what lies behind the level of the rim plate's free edge stays.
        (-90.0, lambda b: b["rim_front"] / b["length"]),
        # Half way over the edge: the triangle of the cross-section below the mouth's corner.
        (45.0, lambda b: b["depth"] ** 2 / 2 / (b["length"] * b["depth"])),
    ],
)
def test_what_the_scoop_keeps_at_a_tilt(geometry, tilt_deg, fraction):
    kept = geometry.retained_m3(geometry.tilted(math.radians(tilt_deg)))
    assert kept == pytest.approx(fraction(closed_form()) * geometry.capacity_m3, abs=1e-12)


def test_carried_bottom_down_the_scoop_keeps_nearly_all(geometry):
    # The lander carries the scoop bottom down; the lip plane is pitched 2 degrees, so the thin
    # wedge above the level of its front edge spills.
    kept = geometry.retained_m3(BOTTOM_DOWN)
    assert 0.95 * geometry.capacity_m3 < kept < geometry.capacity_m3


@pytest.mark.parametrize("tilt_deg", [0.0, 90.0, 180.0])
def test_a_full_scoop_spills_the_excess_onto_the_terrain(tracker, geometry, tilt_deg):
    full = Bulk.of("pristine", "ICE", geometry.capacity_units)
    tracker.budget.excavate(full)
    R = geometry.tilted(math.radians(tilt_deg))
    kept = geometry.retained_units(R)
    heights = field_terrain().heights.copy()
    change = tracker.scoop_moved(scoop_pouring_at(geometry, R, [1.8, 0.0, GROUND_Z + 0.3]), False)
    change.apply(heights)
    budget = tracker.budget
    assert budget.in_scoop.units == kept
    assert budget[Account.DEPOSITED].units == geometry.capacity_units - kept
    assert budget[Account.SPILLED].is_empty and budget[Account.IN_DOCK].is_empty
    # The terrain rose by the deposited volume, around where it fell.
    risen_m3 = float(np.sum(heights - GROUND_Z)) * tracker.ledger.area_m2
    assert risen_m3 == pytest.approx(budget[Account.DEPOSITED].volume_m3, rel=1e-9, abs=1e-15)
    if tilt_deg:
        assert tracker.last_landing is Landing.TERRAIN
        assert np.all(change.raise_m > 0.0)
    budget.check()


def test_the_pour_point_is_the_middle_of_the_mouths_lowest_edge(geometry):
    X = pose(geometry.tilted(math.radians(90.0)), np.zeros(3))
    point = geometry.pour_point(X)
    mouth = geometry.mouth @ X[:3, :3].T
    assert point[2] == pytest.approx(mouth[:, 2].min(), abs=1e-12)
    assert point[1] == pytest.approx(0.0, abs=1e-6)


def test_the_dock_is_the_urdf_box_in_base_link(targets):
    # spec 14.6: in base_link the box spans 0.095 (x) by 0.30 (y) by 0.05 (z) around the dock
    # centre; our dock joint is at the paper-era x = 0.53, so the centre is (0.555, -0.35, 0.65).
    assert targets.dock.vertical_span(0.555, -0.35) == pytest.approx((0.625, 0.675), abs=1e-4)
    assert targets.dock.vertical_span(0.51, -0.49) is not None
    for x, y in [(0.505, -0.35), (0.605, -0.35), (0.555, -0.505), (0.555, -0.195)]:
        assert targets.dock.vertical_span(x, y) is None


@pytest.mark.parametrize(
    ("point", "landing"),
    [
        ((0.555, -0.35, 0.9), Landing.DOCK),
        ((0.555, -0.35, 0.65), Landing.DOCK),  # inside the box
        ((0.555, -0.1, 0.9), Landing.LANDER),  # beside it, over the deck
        ((0.7, -0.35, 0.9), Landing.LANDER),  # in front of it, over the body's lower step
        ((1.8, 0.0, 0.2), Landing.TERRAIN),
        ((1.8, 0.0, GROUND_Z - 0.05), Landing.TERRAIN),  # under the surface: stays there
        ((3.5, 0.0, 0.2), Landing.BEYOND_TERRAIN),
    ],
)
def test_poured_regolith_lands_on_the_first_thing_below(targets, point, landing):
    assert targets.landing(np.array(point), field_terrain()) is landing


def test_a_missing_scoop_shape_is_named_with_those_there_are():
    with pytest.raises(GeometryError, match=r"l_scoop has no collision shape 'lid'; it has \["):
        ScoopGeometry.from_urdf(ScoopShapes(rim="lid"))


def test_what_the_scoop_keeps_agrees_with_the_polytope_cut_at_any_orientation(geometry):
    # Two ways to the same volume: the faces clipped below the level (what retained_m3 uses)
    # and the vertices of the cavity intersected with the half-space below it.
    rng = np.random.default_rng(5)
    for _ in range(200):
        q = rng.normal(size=4)
        w, x, y, z = q / np.linalg.norm(q)
        R = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        up = R.T @ np.array([0.0, 0.0, 1.0])
        level = float(np.min(geometry.mouth @ up))
        below = volume([*geometry.cavity, Halfspace.through(up * level, up)])
        assert geometry.retained_m3(R) == pytest.approx(below, abs=1e-15)
