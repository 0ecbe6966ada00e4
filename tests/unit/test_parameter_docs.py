"""The parameter tables of the docs say what the shipped YAML files say: every parameter of the
node documented, none documented that the node does not have, and each default written the same.

The YAML files are checked against the configuration dataclasses' defaults by
``tests/unit/ow_bringup/test_node_config.py``; with this test a default has one home (the
dataclass) and two checked copies.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]

#: doc page -> the YAML files (and their section, "" for the whole file) its table documents.
TABLES = {
    "docs/simulation.md": (
        ("src/ow_sim_bullet/config/sim.yaml", ""),
        ("src/ow_sim_bullet/config/pid.yaml", ""),
    ),
    "docs/viz.md": (("src/ow_viz/config/viz.yaml", ""),),
}
#: Defaults the table gives in words, not as a value (each is described in its row, or on the
#: page named: the regolith's nested parameters).
IN_WORDS = {"stowed pose", "spec §4.2", "docs/regolith.md"}

_ROW = re.compile(r"^\| (`[a-z_]+`(?:, `[a-z_]+`)*) \| ([^|]*) \|")


def documented(page: str) -> dict[str, Any]:
    """parameter -> default of the page's ``| parameter | default | ... |`` table."""
    text = (ROOT / page).read_text()
    table = text[text.index("| parameter | default |") :]
    rows: dict[str, Any] = {}
    for line in table.splitlines()[2:]:
        if not line.startswith("|"):
            break
        match = _ROW.match(line)
        assert match, f"{page}: unreadable row {line!r}"
        names = re.findall(r"`([a-z_]+)`", match.group(1))
        defaults = [d.strip().strip("`") for d in match.group(2).split(",")]
        if len(names) > 1 and len(defaults) != len(names):
            pytest.fail(f"{page}: {len(names)} names but {len(defaults)} defaults in {line!r}")
        if len(names) == 1:
            defaults = [match.group(2).strip().strip("`")]
        rows.update(zip(names, defaults, strict=True))
    return rows


def shipped(files: tuple[tuple[str, str], ...]) -> dict[str, Any]:
    values: dict[str, Any] = {}
    for path, section in files:
        data = yaml.safe_load((ROOT / path).read_text()) or {}
        values.update(data[section] if section else data)
    return values


@pytest.mark.parametrize("page", sorted(TABLES))
def test_the_table_lists_exactly_the_shipped_parameters(page):
    docs, files = documented(page), shipped(TABLES[page])
    assert set(docs) == set(files), (
        f"{page}: undocumented {sorted(set(files) - set(docs))}, "
        f"not a parameter {sorted(set(docs) - set(files))}"
    )


@pytest.mark.parametrize("page", sorted(TABLES))
def test_the_tables_defaults_are_the_shipped_ones(page):
    docs, files = documented(page), shipped(TABLES[page])
    wrong = []
    for name, written in docs.items():
        if written in IN_WORDS:
            continue
        value = yaml.safe_load(written)
        expected = files[name]
        same = (
            value == pytest.approx(expected)
            if isinstance(expected, (int, float)) and not isinstance(expected, bool)
            else value == expected
        )
        if not same:
            wrong.append(f"{name}: docs {written!r}, YAML {expected!r}")
    assert not wrong, f"{page}: {wrong}"


def test_the_checker_reads_a_table_with_grouped_rows(tmp_path, monkeypatch):
    page = tmp_path / "docs" / "x.md"
    page.parent.mkdir()
    page.write_text(
        "| parameter | default | notes |\n|---|---|---|\n"
        "| `a_hz`, `b_hz` | 100, 30 | Hz |\n| `name` | `world` | frame |\n\nafter\n"
    )
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    assert documented("docs/x.md") == {"a_hz": "100", "b_hz": "30", "name": "world"}
