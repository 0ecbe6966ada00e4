"""Force lookup tables: loading (two CSV formats), validation and interpolation.

A table holds, for each tool and material, one *series* per depth: the wrench on the tool link
(force N and torque N m, in the tool link frame, torque about the link centre of mass) as a
function of dig progress (m of tool-tip path below the surface).

Formats (detected from the header; ``#`` lines before the header are comments):

* ``ow_dem_bridge``: ``tool,material,depth_m,progress_m,Fx_N,Fy_N,Fz_N,Tx_Nm,Ty_Nm,Tz_Nm``.
* OceanWATERS (LinkForcePlugin): ``m,d,p,rho,Fx,Fy,Fz,Tx,Ty,Tz`` with m the material, d the depth
  (m), p the pass number and rho read as progress (m); one pass is selected when loading and the
  tool is given by the caller (the original tables are scoop tables).

Rules (a :class:`TableError` names the line): every column present; every value a finite number;
integer material (and pass); each series' rows together and in strictly increasing progress; no key
twice.

Lookup (:meth:`ForceTable.lookup`) interpolates linearly in progress within the two series whose
depths bracket the query and then linearly in depth; it never snaps to a key. Out of range:
progress before the first or after the last key holds that key's wrench; depth beyond the deepest
series holds the deepest series; depth between 0 and the shallowest series scales that series
linearly down to zero at depth 0; depth <= 0 gives a zero wrench.
"""

from __future__ import annotations

import bisect
import csv
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ow_dem_bridge.api import FloatArray
from ow_dem_bridge.errors import QueryError, TableError

#: Wrench components in table order.
FORCE_COLUMNS: tuple[str, ...] = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
#: Header of the OceanWATERS LinkForcePlugin format.
OW_COLUMNS: tuple[str, ...] = ("m", "d", "p", "rho", *FORCE_COLUMNS)
#: Header of our own format (units in the names).
OUR_COLUMNS: tuple[str, ...] = (
    "tool",
    "material",
    "depth_m",
    "progress_m",
    "Fx_N",
    "Fy_N",
    "Fz_N",
    "Tx_Nm",
    "Ty_Nm",
    "Tz_Nm",
)
_ZERO6 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Series:
    """The wrench along one dig: one tool, one material, one depth.

    Attributes:
        tool: "scoop" or "grinder".
        material: material id.
        depth: m, depth key.
        progress: (k,) m, strictly increasing progress keys.
        wrench: (k, 6) N and N m, (Fx, Fy, Fz, Tx, Ty, Tz) at each progress key.
    """

    tool: str
    material: int
    depth: float
    progress: FloatArray
    wrench: FloatArray


class _Group:
    """Series of one tool and material, sorted by depth, as plain lists for fast lookups."""

    def __init__(self, series: Sequence[Series]) -> None:
        self.depths = [s.depth for s in series]
        self.keys = [[float(p) for p in s.progress] for s in series]
        self.rows = [[tuple(float(v) for v in row) for row in s.wrench] for s in series]

    def along(self, i: int, progress: float) -> tuple[float, ...]:
        keys, rows = self.keys[i], self.rows[i]
        if progress <= keys[0]:
            return rows[0]
        if progress >= keys[-1]:
            return rows[-1]
        j = bisect.bisect_right(keys, progress)
        t = (progress - keys[j - 1]) / (keys[j] - keys[j - 1])
        a, b = rows[j - 1], rows[j]
        return tuple(x + t * (y - x) for x, y in zip(a, b, strict=True))

    def lookup(self, depth: float, progress: float) -> tuple[float, ...]:
        depths = self.depths
        if depth <= 0.0:
            return _ZERO6
        if depth < depths[0]:
            scale = depth / depths[0]
            return tuple(scale * v for v in self.along(0, progress))
        if depth >= depths[-1]:
            return self.along(len(depths) - 1, progress)
        i = bisect.bisect_right(depths, depth) - 1
        t = (depth - depths[i]) / (depths[i + 1] - depths[i])
        a, b = self.along(i, progress), self.along(i + 1, progress)
        return tuple(x + t * (y - x) for x, y in zip(a, b, strict=True))


class ForceTable:
    """A validated set of series with multilinear lookup (see the module docstring).

    Build it with :func:`load_table` or :meth:`from_series`.
    """

    def __init__(self, series: Sequence[Series]) -> None:
        """Use :meth:`from_series`, which validates."""
        self.series: tuple[Series, ...] = tuple(
            sorted(series, key=lambda s: (s.tool, s.material, s.depth))
        )
        groups: dict[tuple[str, int], list[Series]] = {}
        for s in self.series:
            groups.setdefault((s.tool, s.material), []).append(s)
        self._groups = {key: _Group(value) for key, value in groups.items()}

    @classmethod
    def from_series(cls, series: Iterable[Series]) -> ForceTable:
        """A table from series, checked for shape, finite values, increasing progress, unique keys.

        Raises:
            TableError: a series is empty, malformed or repeats another's key.
        """
        checked: list[Series] = []
        seen: set[tuple[str, int, float]] = set()
        for s in series:
            name = f"series (tool={s.tool}, material={s.material}, depth={s.depth})"
            progress = np.asarray(s.progress, dtype=np.float64)
            wrench = np.asarray(s.wrench, dtype=np.float64)
            if progress.ndim != 1 or progress.size == 0 or wrench.shape != (progress.size, 6):
                msg = (
                    f"{name}: need k >= 1 progress keys and a (k, 6) wrench, "
                    f"got {progress.shape} and {wrench.shape}"
                )
                raise TableError(msg)
            if not (np.all(np.isfinite(progress)) and np.all(np.isfinite(wrench))):
                msg = f"{name}: NaN or infinite values"
                raise TableError(msg)
            if not math.isfinite(s.depth) or s.depth <= 0:
                msg = f"{name}: depth must be a finite number > 0 m"
                raise TableError(msg)
            if np.any(np.diff(progress) <= 0):
                msg = f"{name}: progress keys must increase strictly"
                raise TableError(msg)
            key = (s.tool, s.material, s.depth)
            if key in seen:
                msg = f"{name} appears twice"
                raise TableError(msg)
            seen.add(key)
            checked.append(Series(s.tool, int(s.material), float(s.depth), progress, wrench))
        if not checked:
            msg = "a force table needs at least one series"
            raise TableError(msg)
        return cls(checked)

    @property
    def tools(self) -> tuple[str, ...]:
        """Tools with at least one series."""
        return tuple(sorted({tool for tool, _ in self._groups}))

    def materials(self, tool: str) -> tuple[int, ...]:
        """Material ids with at least one series for ``tool``."""
        return tuple(sorted(m for t, m in self._groups if t == tool))

    def depths(self, tool: str, material: int) -> tuple[float, ...]:
        """m, depth keys of a tool and material (increasing)."""
        return tuple(self._group(tool, material).depths)

    def _group(self, tool: str, material: int) -> _Group:
        try:
            return self._groups[(tool, material)]
        except KeyError:
            have = ", ".join(f"{t}/m{m}" for t, m in sorted(self._groups))
            msg = f"no table data for tool {tool!r}, material {material} (have: {have})"
            raise QueryError(msg) from None

    def lookup(self, tool: str, material: int, depth: float, progress: float) -> FloatArray:
        """Interpolated wrench.

        Args:
            tool: "scoop" or "grinder".
            material: material id.
            depth: m, tool-tip depth below the surface.
            progress: m, tip path length below the surface in this dig.

        Returns:
            (6,) force N and torque N m in the tool link frame, torque about the link COM.

        Raises:
            QueryError: the table has no series for this tool and material.
        """
        return np.array(self._group(tool, material).lookup(depth, progress))


def _fail(path: Path, line: int, text: str) -> TableError:
    return TableError(f"{path}, line {line}: {text}")


def _number(path: Path, line: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _fail(path, line, f"column {column!r} is {text!r}, not a number") from None
    if not math.isfinite(value):
        raise _fail(path, line, f"column {column!r} is {text!r}; values must be finite")
    return value


def _integer(path: Path, line: int, column: str, text: str) -> int:
    value = _number(path, line, column, text)
    if value != int(value):
        raise _fail(path, line, f"column {column!r} is {text!r}, not an integer")
    return int(value)


def load_table(path: Path | str, tool: str = "scoop", pass_number: int = 1) -> ForceTable:
    """Read a force table in either format (see the module docstring).

    Args:
        path: CSV file.
        tool: tool of an OceanWATERS-format table (that format has no tool column).
        pass_number: the pass (key p) to use from an OceanWATERS-format table.

    Returns:
        The validated table.

    Raises:
        TableError: unreadable file, unknown header, missing column, bad or non-finite number,
            duplicate key, rows of a series not together or not in increasing progress, or no row
            for the selected pass. The message names the file and line.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        msg = f"{path}: cannot read the table: {exc.strerror}"
        raise TableError(msg) from None
    lines = [(n, raw) for n, raw in enumerate(text.splitlines(), start=1)]
    body = [(n, raw) for n, raw in lines if raw.strip() and not raw.lstrip().startswith("#")]
    if not body:
        msg = f"{path}: empty table (no header line)"
        raise TableError(msg)
    header_line, header_text = body[0]
    header = [h.strip() for h in next(csv.reader([header_text]))]
    ow = "rho" in header or "m" in header
    required = OW_COLUMNS if ow else OUR_COLUMNS
    missing = [c for c in required if c not in header]
    if missing:
        fmt = "OceanWATERS (m,d,p,rho,...)" if ow else "ow_dem_bridge (tool,material,...)"
        raise _fail(
            path, header_line, f"missing column(s) {', '.join(missing)} for the {fmt} format"
        )
    col = {name: header.index(name) for name in required}
    forces = [col[c] for c in (FORCE_COLUMNS if ow else OUR_COLUMNS[4:])]
    rows: list[tuple[int, tuple[str, int, float, int], float, tuple[float, ...]]] = []
    for n, raw in body[1:]:
        fields = [f.strip() for f in next(csv.reader([raw]))]
        if len(fields) != len(header):
            raise _fail(path, n, f"{len(fields)} fields, the header has {len(header)}")
        if ow:
            material = _integer(path, n, "m", fields[col["m"]])
            depth = _number(path, n, "d", fields[col["d"]])
            pass_key = _integer(path, n, "p", fields[col["p"]])
            progress = _number(path, n, "rho", fields[col["rho"]])
            row_tool = tool
        else:
            row_tool = fields[col["tool"]]
            if not row_tool:
                raise _fail(path, n, "column 'tool' is empty")
            material = _integer(path, n, "material", fields[col["material"]])
            depth = _number(path, n, "depth_m", fields[col["depth_m"]])
            pass_key = pass_number
            progress = _number(path, n, "progress_m", fields[col["progress_m"]])
        if depth <= 0:
            raise _fail(path, n, f"depth {depth} m must be > 0")
        values = tuple(_number(path, n, header[i], fields[i]) for i in forces)
        rows.append((n, (row_tool, material, depth, pass_key), progress, values))
    return ForceTable.from_series(_group_rows(path, rows, pass_number, ow))


def _group_rows(
    path: Path,
    rows: list[tuple[int, tuple[str, int, float, int], float, tuple[float, ...]]],
    pass_number: int,
    ow: bool,
) -> list[Series]:
    """Check the key rules on all rows (every pass), then build the series of the chosen pass."""
    seen: dict[tuple[tuple[str, int, float, int], float], int] = {}
    ended: dict[tuple[str, int, float, int], int] = {}
    current: tuple[str, int, float, int] | None = None
    last: tuple[int, float] = (0, 0.0)
    blocks: dict[tuple[str, int, float, int], tuple[list[float], list[tuple[float, ...]]]] = {}
    for n, key, progress, values in rows:
        name = _key_name(key, ow)
        if (key, progress) in seen:
            first = seen[(key, progress)]
            raise _fail(
                path, n, f"duplicate key ({name}, progress {progress}): also on line {first}"
            )
        seen[(key, progress)] = n
        if key != current:
            if key in ended:
                raise _fail(
                    path,
                    n,
                    f"unsorted: rows of series ({name}) resume here after other rows "
                    f"(it ended on line {ended[key]}); keep each series' rows together",
                )
            if current is not None:
                ended[current] = last[0]
            current = key
        elif progress <= last[1]:
            raise _fail(
                path,
                n,
                f"unsorted: progress {progress} follows {last[1]} (line {last[0]}) in series "
                f"({name}); progress must increase within a series",
            )
        last = (n, progress)
        keys, vals = blocks.setdefault(key, ([], []))
        keys.append(progress)
        vals.append(values)
    series = [
        Series(key[0], key[1], key[2], np.asarray(keys), np.asarray(vals))
        for key, (keys, vals) in blocks.items()
        if key[3] == pass_number
    ]
    if not series:
        what = f"pass p={pass_number}" if ow else "data"
        msg = f"{path}: no rows for {what}"
        raise TableError(msg)
    return series


def _key_name(key: tuple[str, int, float, int], ow: bool) -> str:
    if ow:
        return f"m={key[1]}, d={key[2]}, p={key[3]}"
    return f"tool={key[0]}, material={key[1]}, depth={key[2]}"


def write_table(table: ForceTable, path: Path | str, comments: Sequence[str] = ()) -> None:
    """Write a table in the ``ow_dem_bridge`` format.

    Args:
        table: the table.
        path: CSV file to write.
        comments: lines written first, each prefixed with ``# ``.
    """
    with Path(path).open("w", newline="") as fh:
        for line in comments:
            fh.write(f"# {line}\n")
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(OUR_COLUMNS)
        for s in table.series:
            for progress, row in zip(s.progress, s.wrench, strict=True):
                writer.writerow(
                    [s.tool, s.material, f"{s.depth:.6g}", f"{progress:.6g}"]
                    + [f"{v:.6g}" for v in row]
                )
