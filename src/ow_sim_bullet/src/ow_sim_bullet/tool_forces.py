"""The forces on the tools, summed between snapshots: the simulator's contact forces and the
terrain-force model's wrenches, in base_link (the world), moments about its origin.

No pybullet and no kinematics here: contacts arrive as pybullet's ``getContactPoints`` rows,
model wrenches already in base_link.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """a x b of two (3,) vectors: ``np.cross``'s arithmetic (bit-identical), ten times cheaper."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))


@dataclass
class _Sums:
    """One tool's forces (mutable, sim thread only)."""

    last_normal_force: float = 0.0
    force_sum: FloatArray = field(default_factory=lambda: np.zeros(3))
    moment_sum: FloatArray = field(default_factory=lambda: np.zeros(3))
    #: steps since the last mean.
    samples: int = 0
    #: a force was added to the sums since they were last cleared.
    loaded: bool = False
    #: (3,) N and N m: the last mean force and its moment, None when the tool had no force then.
    mean_force: FloatArray | None = None
    mean_moment: FloatArray | None = None


class ToolForces:
    """Per tool, the forces of each step and their means between snapshots.

    Args:
        link_index: tool -> the simulator's index of its link (contact rows name links by it).
    """

    def __init__(self, link_index: Mapping[str, int]) -> None:
        self._sums = {tool: _Sums() for tool in link_index}
        self._by_link = {index: (tool, self._sums[tool]) for tool, index in link_index.items()}
        #: (tool, its last step's contact force N and moment about the origin N m) of each tool
        #: in contact in the last step.
        self.last_contacts: list[tuple[str, list[float]]] = []

    def reset(self) -> None:
        """Forget every force."""
        for sums in self._sums.values():
            sums.force_sum[:] = 0.0
            sums.moment_sum[:] = 0.0
            sums.samples = 0
            sums.loaded = False
            sums.mean_force = sums.mean_moment = None
        self.last_contacts = []

    def add_contacts(self, contacts: Iterable[Sequence[Any]]) -> None:
        """Add one step's contact forces on each tool to its sums and record its total normal
        force (one call per physics step: it counts the steps of the mean).

        Args:
            contacts: pybullet ``getContactPoints`` rows of the robot (index 3: its link, 5: the
                point on it, 7: the normal towards it, 9: normal force, 10-13: the two friction
                forces and directions); rows of other links are ignored.

        Summed in plain Python: a step has a handful of contacts, too few for numpy to pay off.
        """
        by_link = self._by_link
        totals: dict[int, list[float]] = {}
        for c in contacts:
            link = c[3]
            if link not in by_link:
                continue
            (px, py, pz), (nx, ny, nz), fn = c[5], c[7], c[9]
            f1, (ax, ay, az), f2, (bx, by, bz) = c[10], c[11], c[12], c[13]
            fx = nx * fn + ax * f1 + bx * f2
            fy = ny * fn + ay * f1 + by * f2
            fz = nz * fn + az * f1 + bz * f2
            found = totals.get(link)
            if found is None:
                found = totals[link] = [0.0] * 7
            found[0] += fx
            found[1] += fy
            found[2] += fz
            found[3] += py * fz - pz * fy
            found[4] += pz * fx - px * fz
            found[5] += px * fy - py * fx
            found[6] += fn
        last_contacts = []
        for link, (tool, sums) in by_link.items():
            sums.samples += 1
            found = totals.get(link)
            if found is None:
                sums.last_normal_force = 0.0
                continue
            sums.last_normal_force = found[6]
            last_contacts.append((tool, found[0:6]))
            sums.force_sum += found[0:3]
            sums.moment_sum += found[3:6]
            sums.loaded = True
        self.last_contacts = last_contacts

    def add(self, tool: str, force: FloatArray, moment: FloatArray) -> None:
        """Add a force (3,) N and its moment about the origin (3,) N m to a tool's sums."""
        sums = self._sums[tool]
        sums.force_sum += force
        sums.moment_sum += moment
        sums.loaded = True

    def normal_force(self, tool: str) -> float:
        """N, the total normal contact force on a tool in the last step."""
        return self._sums[tool].last_normal_force

    def take_mean(self, tool: str) -> tuple[FloatArray, FloatArray] | None:
        """A tool's mean force (N) and moment about the origin (N m) per step since its last
        mean, None when nothing pushed it; the sums start again."""
        sums = self._sums[tool]
        if sums.loaded:
            count = max(sums.samples, 1)
            sums.mean_force, sums.mean_moment = sums.force_sum / count, sums.moment_sum / count
            sums.force_sum[:] = 0.0
            sums.moment_sum[:] = 0.0
            sums.loaded = False
        else:
            sums.mean_force = sums.mean_moment = None
        sums.samples = 0
        if sums.mean_force is None or sums.mean_moment is None:
            return None
        return sums.mean_force, sums.mean_moment

    def total_mean(self) -> tuple[FloatArray, FloatArray] | None:
        """The tools' last means added up (force N, moment about the origin N m), None when no
        tool had a force then."""
        force = moment = None
        for sums in self._sums.values():
            if sums.mean_force is not None and sums.mean_moment is not None:
                force = sums.mean_force if force is None else force + sums.mean_force
                moment = sums.mean_moment if moment is None else moment + sums.mean_moment
        if force is None or moment is None:
            return None
        return force, moment
