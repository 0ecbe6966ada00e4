"""Force tables: both formats load, exact at keys, interpolated between, bad ones fail clearly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ow_dem_bridge.errors import QueryError, TableError
from ow_dem_bridge.table import ForceTable, Series, load_table, write_table

OW_HEADER = "m,d,p,rho,Fx,Fy,Fz,Tx,Ty,Tz"
OUR_HEADER = "tool,material,depth_m,progress_m,Fx_N,Fy_N,Fz_N,Tx_Nm,Ty_Nm,Tz_Nm"

# Two depths x three progress keys, one material; wrench = a simple function of the keys so that
# any interpolated value is easy to predict: Fx = -(10 d + p), Fz = 100 d, Ty = p.
DEPTHS = (0.01, 0.03)
PROGRESS = (0.0, 0.1, 0.2)


def wrench_at(depth: float, progress: float) -> list[float]:
    return [-(10 * depth + progress), 0.5, 100 * depth, 0.0, progress, -0.25]


def ow_rows(passes: tuple[int, ...] = (1,)) -> list[str]:
    rows = []
    for p in passes:
        for d in DEPTHS:
            for rho in PROGRESS:
                w = wrench_at(d, rho) if p == 1 else [9.0] * 6
                rows.append(",".join(str(v) for v in [1, d, p, rho, *w]))
    return rows


def our_rows(tool: str = "scoop", material: int = 2) -> list[str]:
    return [
        ",".join(str(v) for v in [tool, material, d, p, *wrench_at(d, p)])
        for d in DEPTHS
        for p in PROGRESS
    ]


def write(tmp_path: Path, lines: list[str], name: str = "t.csv") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def ow_table(tmp_path: Path) -> ForceTable:
    return load_table(write(tmp_path, [OW_HEADER, *ow_rows(passes=(1, 2))]))


@pytest.fixture
def our_table(tmp_path: Path) -> ForceTable:
    lines = ["# made by hand for a test", OUR_HEADER, *our_rows("scoop"), *our_rows("grinder")]
    return load_table(write(tmp_path, lines))


def test_ow_format_loads_with_tool_and_pass(ow_table: ForceTable) -> None:
    assert ow_table.tools == ("scoop",)
    assert ow_table.materials("scoop") == (1,)
    assert ow_table.depths("scoop", 1) == DEPTHS


def test_ow_format_pass_selects_rows(tmp_path: Path) -> None:
    table = load_table(write(tmp_path, [OW_HEADER, *ow_rows(passes=(1, 2))]), pass_number=2)
    assert np.allclose(table.lookup("scoop", 1, 0.02, 0.05), [9.0] * 6)


def test_our_format_loads_tools_and_comments(our_table: ForceTable) -> None:
    assert our_table.tools == ("grinder", "scoop")
    assert our_table.materials("grinder") == (2,)


@pytest.mark.parametrize("depth", DEPTHS)
@pytest.mark.parametrize("progress", PROGRESS)
def test_exact_values_at_keys(ow_table: ForceTable, depth: float, progress: float) -> None:
    assert np.allclose(ow_table.lookup("scoop", 1, depth, progress), wrench_at(depth, progress))


@pytest.mark.parametrize(
    ("depth", "progress", "expected"),
    [
        (0.02, 0.05, wrench_at(0.02, 0.05)),  # both keys between: bilinear, exact for this data
        (0.015, 0.1, wrench_at(0.015, 0.1)),  # between depths at a progress key
        (0.03, 0.15, wrench_at(0.03, 0.15)),  # between progress keys at a depth key
        (0.05, 0.1, wrench_at(0.03, 0.1)),  # deeper than the deepest: hold the deepest series
        (0.02, 0.5, wrench_at(0.02, 0.2)),  # past the last progress key: hold it
        (0.02, -0.1, wrench_at(0.02, 0.0)),  # before the first progress key: hold it
        (0.005, 0.1, [0.5 * v for v in wrench_at(0.01, 0.1)]),  # shallower: scale to 0 at d = 0
        (0.0, 0.1, [0.0] * 6),  # at the surface: nothing
        (-0.01, 0.1, [0.0] * 6),  # above it: nothing
    ],
)
def test_interpolation_and_out_of_range(
    ow_table: ForceTable, depth: float, progress: float, expected: list[float]
) -> None:
    assert np.allclose(ow_table.lookup("scoop", 1, depth, progress), expected)


def test_interpolation_never_snaps_to_a_key(ow_table: ForceTable) -> None:
    values = [ow_table.lookup("scoop", 1, d, 0.1)[2] for d in np.linspace(0.01, 0.03, 9)]
    assert np.all(np.diff(values) > 0)


def test_unknown_tool_or_material_names_what_exists(our_table: ForceTable) -> None:
    with pytest.raises(
        QueryError, match=r"tool 'scoop', material 7 \(have: grinder/m2, scoop/m2\)"
    ):
        our_table.lookup("scoop", 7, 0.02, 0.1)


def test_write_then_load_round_trip(our_table: ForceTable, tmp_path: Path) -> None:
    path = tmp_path / "round.csv"
    write_table(our_table, path, ["a comment"])
    again = load_table(path)
    assert path.read_text().startswith("# a comment\n" + OUR_HEADER)
    for tool in ("scoop", "grinder"):
        assert np.allclose(again.lookup(tool, 2, 0.02, 0.13), our_table.lookup(tool, 2, 0.02, 0.13))


BAD_OW = [
    # (name, lines, message pattern)
    (
        "missing column",
        ["m,d,p,Fx,Fy,Fz,Tx,Ty,Tz", "1,0.01,1,0,0,0,0,0,0"],
        r"line 1: missing column\(s\) rho",
    ),
    (
        "NaN",
        [OW_HEADER, "1,0.01,1,0.0,1,2,3,4,5,6", "1,0.01,1,0.1,nan,2,3,4,5,6"],
        r"line 3: column 'Fx' is 'nan'; values must be finite",
    ),
    (
        "not a number",
        [OW_HEADER, "1,0.01,1,0.0,1,2,x3,4,5,6"],
        r"line 2: column 'Fz' is 'x3', not a number",
    ),
    (
        "too few fields",
        [OW_HEADER, "1,0.01,1,0.0,1,2,3,4,5"],
        r"line 2: 9 fields, the header has 10",
    ),
    (
        "duplicate key",
        [
            OW_HEADER,
            "1,0.01,1,0.0,1,2,3,4,5,6",
            "1,0.01,1,0.1,1,2,3,4,5,6",
            "1,0.01,1,0.1,1,2,3,4,5,6",
        ],
        r"line 4: duplicate key \(m=1, d=0.01, p=1, progress 0.1\): also on line 3",
    ),
    (
        "unsorted progress",
        [OW_HEADER, "1,0.01,1,0.2,1,2,3,4,5,6", "1,0.01,1,0.1,1,2,3,4,5,6"],
        r"line 3: unsorted: progress 0.1 follows 0.2 \(line 2\)",
    ),
    (
        "series split",
        [
            OW_HEADER,
            "1,0.01,1,0.0,1,2,3,4,5,6",
            "1,0.02,1,0.0,1,2,3,4,5,6",
            "1,0.01,1,0.1,1,2,3,4,5,6",
        ],
        r"line 4: unsorted: rows of series \(m=1, d=0.01, p=1\) resume here .*ended on line 2",
    ),
    (
        "non-integer material",
        [OW_HEADER, "1.5,0.01,1,0.0,1,2,3,4,5,6"],
        r"line 2: column 'm' is '1.5', not an integer",
    ),
    ("zero depth", [OW_HEADER, "1,0,1,0.0,1,2,3,4,5,6"], r"line 2: depth 0.0 m must be > 0"),
    ("no row for the pass", [OW_HEADER, "1,0.01,3,0.0,1,2,3,4,5,6"], r"no rows for pass p=1"),
    ("empty", ["# only a comment"], r"empty table"),
]


@pytest.mark.parametrize(("name", "lines", "pattern"), BAD_OW, ids=[b[0] for b in BAD_OW])
def test_bad_ow_tables_name_the_line(
    tmp_path: Path, name: str, lines: list[str], pattern: str
) -> None:
    path = write(tmp_path, lines)
    with pytest.raises(TableError, match=pattern) as info:
        load_table(path)
    assert str(path) in str(info.value)


BAD_OURS = [
    (
        "missing column",
        ["tool,material,depth_m,Fx_N,Fy_N,Fz_N,Tx_Nm,Ty_Nm,Tz_Nm"],
        r"line 1: missing column\(s\) progress_m",
    ),
    ("empty tool", [OUR_HEADER, ",1,0.01,0.0,1,2,3,4,5,6"], r"line 2: column 'tool' is empty"),
    (
        "infinite",
        [OUR_HEADER, "scoop,1,0.01,0.0,1,2,3,inf,5,6"],
        r"line 2: column 'Tx_Nm' is 'inf'",
    ),
    (
        "duplicate key",
        [OUR_HEADER, "scoop,1,0.01,0.0,1,2,3,4,5,6", "scoop,1,0.01,0.0,1,2,3,4,5,6"],
        r"line 3: duplicate key \(tool=scoop, material=1, depth=0.01",
    ),
]


@pytest.mark.parametrize(("name", "lines", "pattern"), BAD_OURS, ids=[b[0] for b in BAD_OURS])
def test_bad_tables_of_our_format(
    tmp_path: Path, name: str, lines: list[str], pattern: str
) -> None:
    with pytest.raises(TableError, match=pattern):
        load_table(write(tmp_path, lines))


def test_missing_file_is_a_table_error(tmp_path: Path) -> None:
    with pytest.raises(TableError, match="cannot read the table"):
        load_table(tmp_path / "absent.csv")


@pytest.mark.parametrize(
    ("series", "pattern"),
    [
        ([Series("scoop", 1, 0.01, np.array([0.0, 0.0]), np.zeros((2, 6)))], "increase strictly"),
        ([Series("scoop", 1, 0.01, np.array([0.0]), np.zeros((1, 5)))], r"\(k, 6\) wrench"),
        ([Series("scoop", 1, 0.01, np.array([0.0]), np.full((1, 6), np.nan))], "NaN"),
        ([Series("scoop", 1, -0.01, np.array([0.0]), np.zeros((1, 6)))], "depth must be"),
        ([Series("scoop", 1, 0.01, np.array([0.0]), np.zeros((1, 6)))] * 2, "appears twice"),
        ([], "at least one series"),
    ],
)
def test_from_series_validates(series: list[Series], pattern: str) -> None:
    with pytest.raises(TableError, match=pattern):
        ForceTable.from_series(series)
