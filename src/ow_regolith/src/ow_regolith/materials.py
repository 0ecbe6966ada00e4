"""Materials, the layered column under a terrain, and bulks of regolith with exact volumes.

Volumes are integers of :data:`UNIT_M3` (1 um^3 = 1e-18 m^3): adding, subtracting and splitting
bulks is exact, so the budget of :mod:`ow_regolith.budget` balances to the unit at every moment.
A float volume becomes units only where a height map's cut enters the ledger
(:meth:`LayerColumn.bulk_between`), rounded to the nearest unit there.

A :class:`Bulk` keeps its volume per *component*, a (layer, material) pair: its composition by
material is what OceanWATERS' ``ow_materials/BulkExcavation`` carries, and its share by layer
says how much of a sample came from, say, the irradiated top layer.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction

from ow_regolith.errors import MaterialError

#: Units in one m^3: volumes are integers of 1e-18 m^3 (1 um^3).
UNITS_PER_M3 = 10**18
#: m^3, the volume of one unit.
UNIT_M3 = 1.0 / UNITS_PER_M3
#: OceanWATERS' ``MaterialConcentration.id`` is a uint8.
MAX_MATERIALS = 256

#: (layer name, material name): the key of a bulk's volumes.
Component = tuple[str, str]


def units_from_m3(volume_m3: float) -> int:
    """The volume ``volume_m3`` (m^3, finite, >= 0) in units, rounded to the nearest unit.

    Raises:
        MaterialError: a negative or non-finite volume.
    """
    if not (math.isfinite(volume_m3) and volume_m3 >= 0.0):
        msg = f"a volume must be a finite number >= 0 m^3, got {volume_m3!r}"
        raise MaterialError(msg)
    return round(volume_m3 * UNITS_PER_M3)


def apportion(amount: int, weights: Sequence[int | Fraction]) -> list[int]:
    """Integers summing exactly to ``amount``, in proportion to ``weights`` (>= 0, not all 0).

    Cumulative floors: part k is floor(amount * W_k / W) - floor(amount * W_(k-1) / W), with W_k
    the sum of the first k + 1 weights. Each part is within one unit of its exact share, and
    never exceeds its weight when ``amount`` <= W and the weights are integers (so taking
    ``amount`` units from parts of those sizes never overdraws one).
    """
    if all(type(w) is int for w in weights):
        # Whole weights (a bulk's units, equal parts): the same floors in integers, without the
        # cost of Fractions (a deposit splits a bulk over ~20 cells at every pour).
        whole = sum(weights)
        if whole <= 0 or any(w < 0 for w in weights):
            msg = f"weights must be >= 0 and not all 0, got {list(weights)}"
            raise MaterialError(msg)
        bounds = [amount * c // whole for c in itertools.accumulate(weights)]
        return [b - a for a, b in zip([0, *bounds[:-1]], bounds, strict=True)]
    total = sum(weights, Fraction(0))
    if total <= 0 or any(w < 0 for w in weights):
        msg = f"weights must be >= 0 and not all 0, got {list(weights)}"
        raise MaterialError(msg)
    parts = []
    previous = 0
    cumulative = Fraction(0)
    for weight in weights:
        cumulative += weight
        share = amount * cumulative / total
        upto = share.numerator // share.denominator
        parts.append(upto - previous)
        previous = upto
    return parts


@dataclass(frozen=True)
class Material:
    """One material of the database.

    Attributes:
        name: e.g. ``"ICE"``.
        id: its index in the database's names sorted alphabetically (OceanWATERS' rule).
        density_kg_m3: kg/m^3, bulk density of the material as it lies in the terrain.
    """

    name: str
    id: int
    density_kg_m3: float


class MaterialDatabase:
    """The materials a terrain may be made of, with ids in alphabetical name order.

    Args:
        densities: material name -> kg/m^3 (> 0).

    Raises:
        MaterialError: no material, more than :data:`MAX_MATERIALS`, an empty name or a density
            that is not a positive number.
    """

    def __init__(self, densities: Mapping[str, float]) -> None:
        if not densities or len(densities) > MAX_MATERIALS:
            msg = f"a material database needs 1 to {MAX_MATERIALS} materials, got {len(densities)}"
            raise MaterialError(msg)
        materials = []
        for index, name in enumerate(sorted(densities)):
            density = densities[name]
            if not name or not (math.isfinite(density) and density > 0.0):
                msg = f"material {name!r}: density {density!r} kg/m^3 must be a positive number"
                raise MaterialError(msg)
            materials.append(Material(name, index, float(density)))
        self.materials: tuple[Material, ...] = tuple(materials)
        self._by_name = {m.name: m for m in materials}

    @property
    def names(self) -> tuple[str, ...]:
        """The material names, in id order."""
        return tuple(m.name for m in self.materials)

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def __getitem__(self, name: str) -> Material:
        """The material called ``name``.

        Raises:
            MaterialError: no such material.
        """
        try:
            return self._by_name[name]
        except KeyError:
            msg = f"unknown material {name!r}; the database has {', '.join(self.names)}"
            raise MaterialError(msg) from None

    def __eq__(self, other: object) -> bool:
        return isinstance(other, MaterialDatabase) and self.materials == other.materials

    def __hash__(self) -> int:
        return hash(self.materials)

    def __repr__(self) -> str:
        return f"MaterialDatabase({ {m.name: m.density_kg_m3 for m in self.materials} })"


class Bulk:
    """A volume of regolith: integer units per (layer, material) component; immutable.

    Args:
        parts: component -> units (>= 0; zero entries are dropped).

    Raises:
        MaterialError: a negative or non-integer volume.
    """

    __slots__ = ("_parts",)

    def __init__(self, parts: Mapping[Component, int] | None = None) -> None:
        items = []
        for key, units in (parts or {}).items():
            if not isinstance(units, int) or isinstance(units, bool) or units < 0:
                msg = (
                    f"a bulk's volume of {key} must be a whole number >= 0 of units, got {units!r}"
                )
                raise MaterialError(msg)
            if units:
                items.append((key, units))
        self._parts: tuple[tuple[Component, int], ...] = tuple(sorted(items))

    @classmethod
    def of(cls, layer: str, material: str, units: int) -> Bulk:
        """``units`` of one material from one layer."""
        return cls({(layer, material): units})

    # ------------------------------------------------------------------ reading
    @property
    def parts(self) -> dict[Component, int]:
        """(layer, material) -> units, components with volume only, sorted."""
        return dict(self._parts)

    @property
    def units(self) -> int:
        """The whole volume, units."""
        return sum(units for _, units in self._parts)

    @property
    def volume_m3(self) -> float:
        """m^3, the whole volume."""
        return self.units * UNIT_M3

    @property
    def is_empty(self) -> bool:
        """Whether the bulk has no volume."""
        return not self._parts

    def by_material(self) -> dict[str, int]:
        """material -> units, summed over layers."""
        return self._summed(1)

    def by_layer(self) -> dict[str, int]:
        """layer -> units, summed over materials."""
        return self._summed(0)

    def _summed(self, index: int) -> dict[str, int]:
        sums: dict[str, int] = {}
        for key, units in self._parts:
            sums[key[index]] = sums.get(key[index], 0) + units
        return sums

    def composition(self) -> dict[str, Fraction]:
        """material -> its exact share of the volume (empty for an empty bulk)."""
        total = self.units
        return {name: Fraction(units, total) for name, units in self.by_material().items()}

    def layer_share(self, layer: str) -> Fraction:
        """The exact share of the volume that came from ``layer`` (0 for an empty bulk)."""
        total = self.units
        return Fraction(self.by_layer().get(layer, 0), total) if total else Fraction(0)

    def mass_kg(self, database: MaterialDatabase) -> float:
        """kg, the sum over materials of density x volume.

        Raises:
            MaterialError: a material the database does not have.
        """
        return sum(
            database[name].density_kg_m3 * units * UNIT_M3
            for name, units in self.by_material().items()
        )

    # ------------------------------------------------------------------ arithmetic
    def __add__(self, other: Bulk) -> Bulk:
        parts = dict(self._parts)
        for key, units in other._parts:
            parts[key] = parts.get(key, 0) + units
        return Bulk(parts)

    def __sub__(self, other: Bulk) -> Bulk:
        """The bulk less ``other``, component by component.

        Raises:
            MaterialError: ``other`` holds more of a component than this bulk.
        """
        parts = dict(self._parts)
        for key, units in other._parts:
            left = parts.get(key, 0) - units
            if left < 0:
                msg = (
                    f"cannot take {units} units of {key[1]} from layer {key[0]!r}: "
                    f"the bulk holds {parts.get(key, 0)}"
                )
                raise MaterialError(msg)
            parts[key] = left
        return Bulk(parts)

    def take(self, units: int) -> tuple[Bulk, Bulk]:
        """(taken, rest): ``units`` taken in proportion to the components (a well-mixed bulk),
        exactly (:func:`apportion`), and what is left.

        Raises:
            MaterialError: ``units`` negative or more than the bulk holds.
        """
        total = self.units
        if not 0 <= units <= total:
            msg = f"cannot take {units} units from a bulk of {total} units"
            raise MaterialError(msg)
        if units == total:
            return self, Bulk()
        if units == 0:
            return Bulk(), self
        keys = [key for key, _ in self._parts]
        shares = apportion(units, [u for _, u in self._parts])
        taken = Bulk(dict(zip(keys, shares, strict=True)))
        return taken, self - taken

    def split(self, count: int) -> list[Bulk]:
        """The bulk in ``count`` (>= 1) parts of nearly equal volume (within a unit), each a
        well-mixed share; the parts sum exactly to the bulk."""
        if count < 1:
            msg = f"a bulk is split into at least 1 part, got {count}"
            raise MaterialError(msg)
        parts = []
        rest = self
        for size in apportion(self.units, [1] * count):
            taken, rest = rest.take(size)
            parts.append(taken)
        return parts

    # ------------------------------------------------------------------ identity
    def __eq__(self, other: object) -> bool:
        return isinstance(other, Bulk) and self._parts == other._parts

    def __hash__(self) -> int:
        return hash(self._parts)

    def __repr__(self) -> str:
        inner = ", ".join(
            f"{layer}/{material}: {units}" for (layer, material), units in self._parts
        )
        return f"Bulk({inner})"


def total(bulks: Iterable[Bulk]) -> Bulk:
    """The sum of ``bulks`` (an empty bulk for none)."""
    result = Bulk()
    for bulk in bulks:
        result = result + bulk
    return result


@dataclass(frozen=True)
class Layer:
    """One layer of a terrain's column.

    Attributes:
        name: e.g. ``"irradiated"``.
        top_m: m below the original surface, where the layer begins.
        bottom_m: m below the original surface, where it ends (``math.inf`` for the last).
        composition: (material, share of the volume) pairs, shares in (0, 1] summing to 1.
    """

    name: str
    top_m: float
    bottom_m: float
    composition: tuple[tuple[str, Fraction], ...]


@dataclass(frozen=True)
class LayerColumn:
    """The layers under every cell of a terrain, by depth below the cell's original surface
    (the height the cell had when the terrain was made), top down.

    Attributes:
        layers: contiguous from depth 0, the last one without a bottom.

    Raises:
        MaterialError: no layer, a gap or overlap, a bounded last layer, a layer name used twice,
            or a composition that is empty, has a share outside (0, 1] or does not sum to 1.
    """

    layers: tuple[Layer, ...]

    def __post_init__(self) -> None:
        if not self.layers:
            msg = "a layer column needs at least one layer"
            raise MaterialError(msg)
        depth = 0.0
        for layer in self.layers:
            if layer.top_m != depth or not layer.bottom_m > layer.top_m:
                msg = (
                    f"layer {layer.name!r} spans {layer.top_m:g}..{layer.bottom_m:g} m: layers "
                    f"must follow each other from 0 m down, the next one beginning at {depth:g} m"
                )
                raise MaterialError(msg)
            shares = [share for _, share in layer.composition]
            if not shares or any(not 0 < s <= 1 for s in shares) or sum(shares) != 1:
                msg = (
                    f"layer {layer.name!r}: composition {dict(layer.composition)} must give "
                    "each material a share in (0, 1], the shares summing to 1"
                )
                raise MaterialError(msg)
            depth = layer.bottom_m
        if not math.isinf(self.layers[-1].bottom_m):
            msg = f"the last layer, {self.layers[-1].name!r}, must reach down without a bottom"
            raise MaterialError(msg)
        names = [layer.name for layer in self.layers]
        if len(set(names)) != len(names):
            msg = f"layer names must differ, got {names}"
            raise MaterialError(msg)

    @classmethod
    def from_thicknesses(
        cls, layers: Sequence[tuple[str, float | None, Mapping[str, Fraction]]]
    ) -> LayerColumn:
        """A column from (name, thickness m or None for the last, {material: share}) top down."""
        built = []
        top = 0.0
        for name, thickness, composition in layers:
            bottom = math.inf if thickness is None else top + thickness
            built.append(Layer(name, top, bottom, tuple(sorted(composition.items()))))
            top = bottom
        return cls(tuple(built))

    @property
    def top_layer(self) -> str:
        """The name of the layer at the surface."""
        return self.layers[0].name

    @property
    def materials(self) -> frozenset[str]:
        """Every material some layer holds."""
        return frozenset(m for layer in self.layers for m, _ in layer.composition)

    @staticmethod
    def units_above(depth_m: float, area_m2: float) -> int:
        """Units of the column between the surface and ``depth_m`` (m) under ``area_m2`` (m^2):
        the one rounding of a cut, so that successive cuts of a cell telescope exactly."""
        return round(depth_m * area_m2 * UNITS_PER_M3)

    def bulk_between(self, top_m: float, bottom_m: float, area_m2: float) -> Bulk:
        """The regolith between depths ``top_m`` and ``bottom_m`` (m below the original
        surface, 0 <= top_m <= bottom_m) under ``area_m2`` (m^2).

        Its volume is ``units_above(bottom_m) - units_above(top_m)``, so the bulks of cuts
        following each other down a cell add up to the column above the deepest, exactly; each
        layer's part is split among its materials by :func:`apportion`.

        Raises:
            MaterialError: depths out of order or negative.
        """
        if not 0.0 <= top_m <= bottom_m:
            msg = f"a cut must go down from depth >= 0 m: got {top_m:g} to {bottom_m:g} m"
            raise MaterialError(msg)
        parts: dict[Component, int] = {}
        for layer in self.layers:
            high, low = max(top_m, layer.top_m), min(bottom_m, layer.bottom_m)
            if low <= high:
                continue
            units = self.units_above(low, area_m2) - self.units_above(high, area_m2)
            if not units:
                continue
            materials = [m for m, _ in layer.composition]
            shares = apportion(units, [share for _, share in layer.composition])
            for material, share in zip(materials, shares, strict=True):
                parts[(layer.name, material)] = share
        return Bulk(parts)


@dataclass(frozen=True)
class BulkSummary:
    """A bulk as a report gives it.

    Attributes:
        volume_m3: m^3.
        mass_kg: kg.
        composition: material -> share of the volume (1), every material of the database.
        layers: layer -> share of the volume (1), every layer of the column.
        top_layer: the name of the column's top layer.
        top_layer_share: share of the volume (1) that came from the top layer.
    """

    volume_m3: float
    mass_kg: float
    composition: dict[str, float]
    layers: dict[str, float]
    top_layer: str
    top_layer_share: float


def summarize(bulk: Bulk, database: MaterialDatabase, column: LayerColumn) -> BulkSummary:
    """``bulk`` by material and by layer of ``column`` (shares 0 for an empty bulk).

    Raises:
        MaterialError: a material the database does not have.
    """
    materials = bulk.composition()
    layers = bulk.by_layer()
    return BulkSummary(
        volume_m3=bulk.volume_m3,
        mass_kg=bulk.mass_kg(database),
        composition={name: float(materials.get(name, 0)) for name in database.names},
        layers={
            layer.name: float(bulk.layer_share(layer.name)) if layers else 0.0
            for layer in column.layers
        },
        top_layer=column.top_layer,
        top_layer_share=float(bulk.layer_share(column.top_layer)),
    )
