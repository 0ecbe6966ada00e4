"""The tools' force sums on their own, fed pybullet-shaped contact rows."""

from __future__ import annotations

import numpy as np
import pytest

from ow_sim_bullet.tool_forces import ToolForces, cross

LINKS = {"scoop": 7, "grinder": 9}


def contact(link: int, point, normal, normal_force, friction=((0.0, (1.0, 0.0, 0.0)),) * 2):
    """A ``pybullet.getContactPoints`` row on the robot's ``link``."""
    (f1, d1), (f2, d2) = friction
    return (0, 1, 2, link, -1, point, (0.0, 0.0, 0.0), normal, 0.0, normal_force, f1, d1, f2, d2)


def test_cross_is_numpys():
    rng = np.random.default_rng(4)
    for _ in range(10):
        a, b = rng.normal(size=(2, 3))
        assert np.array_equal(cross(a, b), np.cross(a, b))


def test_contacts_are_summed_per_tool_and_averaged_over_the_steps():
    forces = ToolForces(LINKS)
    point = (1.5, 0.1, -0.15)
    rows = [
        contact(7, point, (0.0, 0.0, 1.0), 4.0, ((1.0, (1.0, 0.0, 0.0)), (0.5, (0.0, 1.0, 0.0)))),
        contact(7, point, (0.0, 0.0, 1.0), 2.0),
        contact(3, point, (0.0, 0.0, 1.0), 100.0),  # another link: ignored
    ]
    forces.add_contacts(rows)
    assert forces.normal_force("scoop") == 6.0
    assert forces.normal_force("grinder") == 0.0
    ((tool, last),) = forces.last_contacts
    force = np.array([1.0, 0.5, 6.0])
    assert tool == "scoop"
    assert np.allclose(last, [*force, *np.cross(point, force)])
    forces.add_contacts([])  # a step without contact: the mean is over two steps
    assert forces.normal_force("scoop") == 0.0
    assert forces.last_contacts == []
    mean = forces.take_mean("scoop")
    assert mean is not None
    assert np.allclose(mean[0], force / 2)
    assert np.allclose(mean[1], np.cross(point, force) / 2)
    assert forces.take_mean("grinder") is None


def test_a_mean_starts_the_sums_again_and_the_wrist_sees_the_last_means():
    forces = ToolForces(LINKS)
    forces.add("scoop", np.array([0.0, 0.0, 3.0]), np.array([1.0, 0.0, 0.0]))
    forces.add("grinder", np.array([1.0, 0.0, 0.0]), np.array([0.0, 2.0, 0.0]))
    forces.add_contacts([])
    assert forces.total_mean() is None  # no mean taken yet
    scoop, grinder = forces.take_mean("scoop"), forces.take_mean("grinder")
    assert scoop is not None and grinder is not None
    total = forces.total_mean()
    assert total is not None
    assert np.allclose(total[0], [1.0, 0.0, 3.0]) and np.allclose(total[1], [1.0, 2.0, 0.0])
    # Nothing since: the next means are None, and so is the wrist's total.
    assert forces.take_mean("scoop") is None and forces.take_mean("grinder") is None
    assert forces.total_mean() is None


def test_reset_forgets_the_forces():
    forces = ToolForces(LINKS)
    forces.add_contacts([contact(9, (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), 5.0)])
    forces.reset()
    assert forces.take_mean("grinder") is None
    assert forces.last_contacts == []


@pytest.mark.parametrize("samples", [1, 4])
def test_the_mean_divides_by_the_steps_since_the_last_one(samples):
    forces = ToolForces(LINKS)
    for _ in range(samples):
        forces.add_contacts([contact(9, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 8.0)])
    mean = forces.take_mean("grinder")
    assert mean is not None and mean[0][2] == pytest.approx(8.0)
