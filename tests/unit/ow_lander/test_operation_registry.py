"""The operation registry: each entry is planned by a method that exists, served by a service
that exists, and its defaults name fields of that service's request."""

from pathlib import Path

import pytest

from ow_lander.execution.fault_reaction import group_of
from ow_lander.operations.ground import effective_parameters
from ow_lander.operations.planner import Operations
from ow_lander.operations.registry import OPERATIONS, SERVICE_OPERATIONS

SRV_DIR = Path(__file__).resolve().parents[3] / "src" / "ow_msgs" / "srv"


def _request_fields(service: str) -> set[str]:
    request = (SRV_DIR / f"{service}.srv").read_text().split("---")[0]
    return {
        line.split()[1]
        for line in request.splitlines()
        if line.strip() and not line.lstrip().startswith("#")
    }


@pytest.mark.parametrize("spec", OPERATIONS.values(), ids=lambda s: s.name)
def test_every_operation_is_planned_by_a_method_of_the_planner(spec):
    assert callable(getattr(Operations, spec.planner_method, None)), spec.planner_method


@pytest.mark.parametrize("spec", SERVICE_OPERATIONS, ids=lambda s: s.name)
def test_every_service_exists_and_its_defaults_are_request_fields(spec):
    fields = _request_fields(spec.service)
    assert set(spec.defaults) <= fields, set(spec.defaults) - fields
    if spec.defaults:
        assert "use_defaults" in fields


def test_the_paper_services_are_the_seven_of_the_paper_in_order():
    assert [s.name for s in SERVICE_OPERATIONS] == [
        "unstow",
        "stow",
        "guarded_move",
        "grind",
        "dig_circular",
        "dig_linear",
        "deliver_sample",
    ]


def test_use_defaults_replaces_the_request_with_the_registrys_values():
    request = {"use_defaults": True, "x": 9.0, "depth": 0.3, "delete_prev_traj": False}
    values = effective_parameters("dig_linear", request)
    assert values["x"] == pytest.approx(1.46)
    assert values["depth"] == pytest.approx(0.01)
    assert "use_defaults" not in values and "delete_prev_traj" not in values
    assert effective_parameters("dig_linear", {**request, "use_defaults": False})["x"] == 9.0


def test_the_fault_groups_follow_the_registry():
    assert {s.name for s in SERVICE_OPERATIONS if group_of(s.name) == "arm"} == {
        "unstow",
        "stow",
        "guarded_move",
    }
    assert group_of("publish_trajectory") == "arm"
