"""Balovnev's analytic bucket-cutting model, as later OceanWATERS used it for the scoop.

Horizontal resistance H(d) of a bucket cutting at depth d is the sum of three terms (cutting edge,
blunt edge, side plates); the vertical force is V = H cot(beta + delta). Both are capped. The
wrench on the scoop is (-H, 0, +V) in the ``l_scoop`` frame, applied at the link's centre of mass
(no torque), as the original plugin did: link -x resists the cut, link +z is the direction the
scoop bottom faces (down while digging). Cohesion enters through c cot(phi); the "buried bucket"
case of the model is not implemented (the original ran with it off).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from ow_dem_bridge.api import ToolState, Wrench
from ow_dem_bridge.errors import ConfigError
from ow_description.description import EUROPA_GRAVITY


@dataclass(frozen=True)
class BalovnevParams:
    """Constants of the model (defaults: later OceanWATERS, Europa).

    Attributes:
        gravity: m/s2 (Europa's, ``ow_description.description.EUROPA_GRAVITY``).
        width: m, bucket width.
        side_plate_length: m.
        blunt_edge_thickness: m.
        blunt_edge_angle: rad.
        side_plate_thickness: m.
        soil_density: kg/m3.
        cohesion: Pa.
        internal_friction: rad, soil internal friction angle phi.
        external_friction: rad, soil-metal friction angle delta.
        surcharge_mass: kg/m2 on the surface.
        rake_angle: rad, beta.
        fudge: dimensionless factor on H.
        max_horizontal: N, cap of H.
        max_vertical: N, cap of V.
    """

    gravity: float = EUROPA_GRAVITY
    width: float = 0.085
    side_plate_length: float = 0.1225
    blunt_edge_thickness: float = 0.0004
    blunt_edge_angle: float = math.radians(30.0)
    side_plate_thickness: float = 0.0016
    soil_density: float = 1700.0
    cohesion: float = 0.0
    internal_friction: float = math.radians(44.0)
    external_friction: float = math.radians(28.0)
    surcharge_mass: float = 1.0
    rake_angle: float = math.radians(10.0)
    fudge: float = 1.0
    max_horizontal: float = 40.0
    max_vertical: float = 30.0

    @classmethod
    def from_dict(cls, params: Mapping[str, Any]) -> BalovnevParams:
        """Parameters from a mapping of field names to numbers (missing keys keep defaults).

        Raises:
            ConfigError: unknown key, non-number, or a value out of its physical range.
        """
        names = {f.name for f in fields(cls)}
        values: dict[str, float] = {}
        for key, value in params.items():
            if key not in names:
                msg = f"unknown Balovnev parameter {key!r} (known: {', '.join(sorted(names))})"
                raise ConfigError(msg)
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not math.isfinite(value)
            ):
                msg = f"Balovnev parameter {key!r} must be a finite number, got {value!r}"
                raise ConfigError(msg)
            values[key] = float(value)
        result = cls(**values)
        phi, delta = result.internal_friction, result.external_friction
        if not 0 < delta < phi < math.pi / 2:
            msg = f"need 0 < external_friction ({delta}) < internal_friction ({phi}) < pi/2 rad"
            raise ConfigError(msg)
        return result


def coefficient_a(x: float, phi: float, delta: float) -> float:
    """Balovnev's passive-pressure coefficient A(x, phi, delta) for a face at angle x (rad)."""
    s = math.asin(math.sin(delta) / math.sin(phi))
    if x <= 0.5 * s - delta:
        return (1.0 - math.sin(phi) * math.cos(2.0 * x)) / (1.0 - math.sin(phi))
    root = math.sqrt(math.sin(phi) ** 2 - math.sin(delta) ** 2)
    return (
        math.cos(delta)
        * (math.cos(delta) + root)
        / (1.0 - math.sin(phi))
        * math.exp((2.0 * x - math.pi + delta + s) * math.tan(phi))
    )


def balovnev_forces(depth: float, p: BalovnevParams | None = None) -> tuple[float, float]:
    """Horizontal and vertical cutting forces.

    Args:
        depth: m, cut depth (<= 0 gives no force).
        p: model constants.

    Returns:
        (H, V) in N, each capped (H by ``max_horizontal``, V by ``max_vertical``).
    """
    p = p or BalovnevParams()
    if depth <= 0.0:
        return 0.0, 0.0
    phi, delta, beta = p.internal_friction, p.external_friction, p.rake_angle
    g, rho = p.gravity, p.soil_density
    a1 = coefficient_a(beta, phi, delta)
    a2 = coefficient_a(p.blunt_edge_angle, phi, delta)
    a3 = coefficient_a(math.pi / 2, phi, delta)
    c_term = p.cohesion / math.tan(phi)
    q_term = g * p.surcharge_mass
    pressure = depth * g * rho / 2.0 + c_term + q_term
    cutting = p.width * depth * a1 * (1.0 + math.tan(delta) / math.tan(beta)) * pressure
    t = p.blunt_edge_thickness
    blunt = (
        p.width
        * t
        * a2
        * (1.0 + math.tan(delta) / math.tan(p.blunt_edge_angle))
        * (
            t * g * rho / 2.0
            + c_term
            + q_term
            + depth * g * rho * (1.0 - math.sin(phi)) / (1.0 + math.sin(phi))
        )
    )
    sides = (
        depth
        * a3
        * (2.0 * p.side_plate_thickness + 4.0 * p.side_plate_length * math.tan(delta))
        * pressure
    )
    horizontal = p.fudge * (cutting + blunt + sides)
    vertical = horizontal * math.cos(beta + delta) / math.sin(beta + delta)
    return min(horizontal, p.max_horizontal), min(vertical, p.max_vertical)


class BalovnevModel:
    """Terrain-force model of the scoop after Balovnev; the grinder is delegated (or zero).

    Args:
        params: model constants.
        grinder: model for grinder states (None: zero wrench on the grinder).
    """

    def __init__(self, params: BalovnevParams | None = None, grinder: Any | None = None) -> None:
        self.params = params or BalovnevParams()
        self.grinder = grinder

    def wrench(self, state: ToolState) -> Wrench:
        """(-H, 0, +V) N on the scoop in its link frame, no torque; see the module docstring."""
        if state.tool == "grinder" and self.grinder is not None:
            return self.grinder.wrench(state)
        if state.tool != "scoop" or state.depth <= 0.0:
            return Wrench(np.zeros(3), np.zeros(3))
        horizontal, vertical = balovnev_forces(state.depth, self.params)
        return Wrench(np.array([-horizontal, 0.0, vertical]), np.zeros(3))
