"""The regolith parameters: the shipped YAML (the simulation's ``regolith`` section) is the
defaults, a terrain picks its column, and every mistake is reported with its key."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest
import yaml

from ow_regolith.config import DEFAULT_COLUMN, RegolithConfig
from ow_regolith.errors import ConfigError
from ow_runtime.errors import ConfigError as RuntimeConfigError

#: The simulation node's parameters, whose ``regolith`` section configures the regolith.
SIM_YAML = Path(__file__).resolve().parents[3] / "src" / "ow_sim_bullet" / "config" / "sim.yaml"


def test_the_shipped_file_holds_the_defaults():
    raw = yaml.safe_load(SIM_YAML.read_text())["regolith"]
    assert RegolithConfig.from_dict(raw) == RegolithConfig()


def test_the_default_column_is_an_irradiated_top_layer_over_pristine_ice():
    top, below = DEFAULT_COLUMN.layers
    assert (top.name, top.top_m, top.bottom_m) == ("irradiated", 0.0, 0.10)
    assert below.name == "pristine" and dict(below.composition) == {"ICE": 1}
    assert RegolithConfig().database.names == ("ICE", "MG_HYDRATES", "SALT")


def test_a_terrain_kind_has_its_own_column_or_the_default():
    raw = {
        "columns": {
            "flat": [
                {"name": "snow", "thickness": 0.05, "composition": {"ICE": 1.0}},
                {"name": "salt", "composition": {"SALT": 0.7, "ICE": 0.3}},
            ],
        }
    }
    config = RegolithConfig.from_dict(raw)
    assert config.column_for("flat:-0.155").top_layer == "snow"
    assert dict(config.column_for("flat:0").layers[1].composition) == {
        "ICE": Fraction(3, 10),
        "SALT": Fraction(7, 10),
    }
    assert config.column_for("europa:7") == DEFAULT_COLUMN
    assert config.column_for("file:/tmp/t.npy") == DEFAULT_COLUMN


def test_shares_close_to_one_are_rescaled_exactly():
    raw = {
        "columns": {
            "default": [{"name": "mix", "composition": {"ICE": 0.3333333, "SALT": 0.6666667}}]
        }
    }
    (layer,) = RegolithConfig.from_dict(raw).column_for("europa:1").layers
    assert sum(share for _, share in layer.composition) == 1


@pytest.mark.parametrize(
    ("raw", "match"),
    [
        (
            {"materials": {"ICE": {"density": -1.0}}},
            r"materials/ICE/density = -1 kg/m\^3 is outside",
        ),
        ({"materials": {"ICE": {}}}, "materials/ICE/density is missing"),
        ({"materials": {"ICE": {"density": 997.0}}}, r"uses materials \['MG_HYDRATES', 'SALT'\]"),
        (
            {"columns": {"default": [{"name": "a", "composition": {"ICE": 0.5}}]}},
            "shares of layer 'a' sum to 0.5, not 1",
        ),
        (
            {
                "columns": {
                    "default": [
                        {"name": "a", "composition": {"ICE": 1.0}},
                        {"name": "b", "composition": {"ICE": 1.0}},
                    ]
                }
            },
            r"columns/default\[0\]/thickness is missing",
        ),
        (
            {
                "columns": {
                    "default": [{"name": "a", "thickness": 0.1, "composition": {"ICE": 1.0}}]
                }
            },
            "the last layer reaches down without a bottom",
        ),
        ({"columns": {"default": "ice"}}, "columns/default must be a list of layers"),
        (
            {"columns": {"default": [{"name": "a", "composition": {"ICE": 1.0}, "thicknes": 1}]}},
            r"unknown key 'regolith/columns/default\[0\]/thicknes'",
        ),
        ({"scoop": {"side_walls": ["left"]}}, "scoop/side_walls must name 2 shapes"),
        ({"deposit_radius": 0.0}, "deposit_radius = 0 m is outside"),
        ({"deposit_raduis": 0.1}, "did you mean 'deposit_radius'"),
    ],
)
def test_mistakes_are_reported_with_their_key(raw, match):
    with pytest.raises(ConfigError, match=match):
        RegolithConfig.from_dict(raw)


def test_the_error_is_the_runtimes_configuration_error():
    assert issubclass(ConfigError, RuntimeConfigError)
