"""The regolith parameters: materials, the layer column of each terrain, the scoop's and the
dock's shapes, deposits. Validated by a pure :meth:`RegolithConfig.from_dict` (the ``regolith``
section of the simulation's ``ow_sim_bullet/config/sim.yaml`` holds the defaults, each key with
its unit).

Sources of the defaults:

* Materials and densities: OceanWATERS' material database at HEAD (``ow_materials/config/
  materials.yaml``; spec 14.5): ICE 997 kg/m^3, MG_HYDRATES 2660 kg/m^3 (anhydrous MgSO4), SALT
  2160 kg/m^3 (halite). Ids follow the names in alphabetical order, as there.
* The Europa column: an irradiated top layer 0.10 m thick over pristine ice. The thickness is
  the paper's (shared/seed): the layers near the surface are of little scientific value because
  Jupiter's radiation may have destroyed any biosignature there, so the procedure grinds a 10 cm
  trench, discards its contents, and samples the ice below. Pristine ice is all ICE, as every
  single-material OceanWATERS terrain is (spec 14.5: blend {ICE: 1.0}).
* The top layer's composition (ICE 0.85, MG_HYDRATES 0.10, SALT 0.05) is a **placeholder**, not
  a measurement: neither the paper nor the spec gives one. It stands for the salts and other
  non-ice material seen on Europa's surface, and makes the top layer's part of a sample visible in
  its composition; set your own.
* ``deposit_radius`` 0.1 m: a heap about the scoop's size (our choice).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

from ow_description.description import BASE_FRAME, DOCK_FRAME
from ow_regolith.errors import ConfigError, MaterialError
from ow_regolith.materials import LayerColumn, MaterialDatabase
from ow_regolith.scoop import ScoopShapes
from ow_runtime.params import Params

#: A composition whose shares sum to within this of 1 is rescaled to sum to 1 exactly.
SHARE_SUM_TOLERANCE = 1e-6
#: The column of terrains without their own (``columns`` key).
DEFAULT_COLUMN_KEY = "default"

DEFAULT_DENSITIES: dict[str, float] = {"ICE": 997.0, "MG_HYDRATES": 2660.0, "SALT": 2160.0}
DEFAULT_COLUMN = LayerColumn.from_thicknesses(
    (
        (
            "irradiated",
            0.10,
            {"ICE": Fraction(85, 100), "MG_HYDRATES": Fraction(10, 100), "SALT": Fraction(5, 100)},
        ),
        ("pristine", None, {"ICE": Fraction(1)}),
    )
)


@dataclass(frozen=True)
class RegolithConfig:
    """The regolith model's parameters.

    Attributes:
        densities: material name -> kg/m^3.
        columns: terrain kind (``flat``, ``europa``, ``file``: the part of the simulation's
            terrain specification before ``:``) or ``default`` -> its layer column.
        scoop: which scoop shapes play which part (:class:`~ow_regolith.scoop.ScoopShapes`).
        dock_link: the link whose one box is the sample dock.
        catch_links: links whose boxes catch regolith poured over the lander.
        deposit_radius: m, regolith poured on the terrain spreads over the cells within this
            distance of where it lands.
    """

    densities: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_DENSITIES))
    columns: Mapping[str, LayerColumn] = field(
        default_factory=lambda: {DEFAULT_COLUMN_KEY: DEFAULT_COLUMN}
    )
    scoop: ScoopShapes = field(default_factory=ScoopShapes)
    dock_link: str = DOCK_FRAME
    catch_links: tuple[str, ...] = (BASE_FRAME,)
    deposit_radius: float = 0.1

    @property
    def database(self) -> MaterialDatabase:
        """The material database of :attr:`densities`."""
        return MaterialDatabase(self.densities)

    def column_for(self, terrain: str) -> LayerColumn:
        """The column of a terrain given as the simulation's specification (``europa:7``), or
        the default one."""
        kind = terrain.split(":", 1)[0]
        return self.columns.get(kind, self.columns[DEFAULT_COLUMN_KEY])

    @classmethod
    def from_dict(cls, raw: Mapping[str, Any] | None, where: str = "regolith") -> RegolithConfig:
        """Validated parameters from a mapping (a YAML file's or a node's private parameters);
        absent keys keep their defaults, ``columns`` are merged over the default ones by kind.

        Raises:
            ConfigError: naming every bad value and unknown key.
        """
        p = Params(raw, where, ConfigError)
        d = cls()
        densities = _densities(p) if p.has("materials") else dict(d.densities)
        columns = dict(d.columns)
        columns_section = p.section("columns")
        for kind in columns_section.values:
            column = _column(columns_section, str(kind))
            if column is not None:
                columns[str(kind)] = column
        for kind, column in columns.items():
            unknown = sorted(column.materials - set(densities))
            if unknown:
                p.problem(
                    f"{columns_section.name(kind)} uses materials {unknown} that "
                    f"{p.name('materials')} does not define ({', '.join(sorted(densities))})"
                )
        scoop_section = p.section("scoop")
        ds = d.scoop
        sides = scoop_section.names("side_walls", ds.side_walls)
        if len(sides) != 2:
            p.problem(f"{scoop_section.name('side_walls')} must name 2 shapes, got {list(sides)}")
            sides = ds.side_walls
        scoop = ScoopShapes(
            link=_non_empty(scoop_section, "link", ds.link),
            side_walls=(sides[0], sides[1]),
            plates=scoop_section.names("plates", ds.plates),
            rim=_non_empty(scoop_section, "rim", ds.rim),
            tip_frame=_non_empty(scoop_section, "tip_frame", ds.tip_frame),
        )
        scoop_section.check_unknown()
        config = cls(
            densities=densities,
            columns=columns,
            scoop=scoop,
            dock_link=_non_empty(p, "dock_link", d.dock_link),
            catch_links=p.names("catch_links", d.catch_links),
            deposit_radius=p.positive("deposit_radius", d.deposit_radius, "m"),
        )
        p.finish()
        return config


def _non_empty(p: Params, key: str, default: str) -> str:
    value = p.string(key, default)
    if not value:
        p.problem(f"{p.name(key)} must not be empty")
        return default
    return value


def _densities(p: Params) -> dict[str, float]:
    """``materials``: name -> {density: kg/m^3}."""
    section = p.section("materials")
    densities: dict[str, float] = {}
    for name in section.values:
        entry = section.section(str(name))
        if not entry.has("density"):
            entry.problem(f"{entry.name('density')} is missing (kg/m^3)")
            continue
        densities[str(name)] = entry.positive("density", DEFAULT_DENSITIES.get(name, 1.0), "kg/m^3")
        entry.check_unknown()
    if not densities:
        p.problem(f"{p.name('materials')} must define at least one material")
        return dict(DEFAULT_DENSITIES)
    try:
        MaterialDatabase(densities)
    except MaterialError as error:
        p.problem(f"{p.name('materials')}: {error}")
        return dict(DEFAULT_DENSITIES)
    return densities


def _composition(entry: Params, name: str) -> dict[str, Fraction] | None:
    """``composition``: material -> share in (0, 1], the shares summing to 1 (within
    :data:`SHARE_SUM_TOLERANCE`, then rescaled)."""
    raw = entry.raw("composition")
    where = entry.name("composition")
    if not isinstance(raw, Mapping) or not raw:
        entry.problem(f"{where} must map materials to their shares of the volume, got {raw!r}")
        return None
    shares: dict[str, Fraction] = {}
    for material, value in raw.items():
        share = entry.check_number(
            value, f"{where}/{material}", 0.0, low=0.0, high=1.0, low_inclusive=False
        )
        if share > 0.0:
            shares[str(material)] = Fraction(repr(share))
    if len(shares) != len(raw):
        return None
    summed = sum(shares.values(), Fraction(0))
    if abs(summed - 1) > SHARE_SUM_TOLERANCE:
        entry.problem(f"{where}: shares of layer {name!r} sum to {float(summed):g}, not 1")
        return None
    return {material: share / summed for material, share in shares.items()}


def _column(section: Params, kind: str) -> LayerColumn | None:
    """One terrain kind's layers, top down: each {name, thickness m (not the last), composition}."""
    raw = section.raw(kind)
    where = section.name(kind)
    if not isinstance(raw, list) or not raw:
        section.problem(f"{where} must be a list of layers, top down, got {raw!r}")
        return None
    layers: list[tuple[str, float | None, Mapping[str, Fraction]]] = []
    ok = True
    for index, item in enumerate(raw):
        entry = Params(item, f"{where}[{index}]", ConfigError, parent=section)
        name = _non_empty(entry, "name", f"layer{index}")
        last = index == len(raw) - 1
        thickness: float | None = None
        if last and entry.has("thickness"):
            entry.problem(
                f"{entry.name('thickness')}: the last layer reaches down without a bottom; "
                "give it no thickness"
            )
            ok = False
        elif not last and not entry.has("thickness"):
            entry.problem(
                f"{entry.name('thickness')} is missing: every layer but the last needs one (m)"
            )
            ok = False
        elif not last:
            thickness = entry.positive("thickness", math.nan, "m")
            ok = ok and math.isfinite(thickness)
        composition = _composition(entry, name)
        entry.check_unknown()
        if composition is None:
            ok = False
            continue
        layers.append((name, thickness, composition))
    if not ok:
        return None
    try:
        return LayerColumn.from_thicknesses(layers)
    except MaterialError as error:
        section.problem(f"{where}: {error}")
        return None
