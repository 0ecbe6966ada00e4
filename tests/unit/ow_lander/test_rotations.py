"""The rotations the operations turn tools with (ow_lander.operations.motions): interpolating
between two orientations and the angle between them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ow_lander.operations.motions import align, angle_between, ry, rz, turned

#: (from, to): a pitch, a yaw, both, a half turn (the axis is then not in the skew part).
PAIRS = [
    (np.eye(3), ry(0.6)),
    (rz(0.3) @ ry(-0.5), rz(0.3)),
    (rz(-1.2), rz(0.9) @ ry(1.1)),
    (np.eye(3), rz(math.pi)),
    (ry(0.4), ry(0.4)),
]


@pytest.mark.parametrize(("R_from", "R_to"), PAIRS)
def test_turned_goes_evenly_from_one_orientation_to_the_other(R_from, R_to):
    total = angle_between(R_from, R_to)
    assert np.allclose(turned(R_from, R_to, 0.0), R_from)
    assert np.allclose(turned(R_from, R_to, 1.0), R_to, atol=1e-9)
    for fraction in (0.25, 0.5, 0.75):
        between = turned(R_from, R_to, fraction)
        assert np.allclose(between @ between.T, np.eye(3), atol=1e-12)  # a rotation
        assert angle_between(R_from, between) == pytest.approx(fraction * total, abs=1e-9)
        assert angle_between(between, R_to) == pytest.approx((1 - fraction) * total, abs=1e-9)


@pytest.mark.parametrize(
    ("R_a", "R_b", "angle"),
    [(np.eye(3), ry(0.7), 0.7), (rz(0.2), rz(-0.3), 0.5), (np.eye(3), rz(math.pi), math.pi)],
)
def test_angle_between_is_the_rotation_angle(R_a, R_b, angle):
    assert angle_between(R_a, R_b) == pytest.approx(angle, abs=1e-9)


def test_a_pitched_scoop_levelled_keeps_its_heading():
    """What the dig's curl turns to: the smallest rotation putting the tip frame's z straight
    down keeps the cutting edge's heading (x in the horizontal plane, same direction)."""
    down = np.array([0.0, 0.0, -1.0])
    cutting = rz(0.4) @ np.diag([1.0, -1.0, -1.0]) @ ry(math.radians(-30))
    level = align(cutting, 2, down)
    assert np.allclose(level[:, 2], down)
    heading = math.atan2(level[1, 0], level[0, 0])
    assert heading == pytest.approx(0.4, abs=1e-9)
    assert angle_between(cutting, level) == pytest.approx(math.radians(30), abs=1e-9)
