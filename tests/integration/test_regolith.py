"""The regolith in the running stack (docs/regolith.md): a dig, a discard, a second dig and a
delivery through OceanWATERS' actions (actionlib's stock ``SimpleActionClient``), then
DockIngestSample. The budget on ``/regolith/budget`` holds exactly at every message, the dock's
content goes to ``ingested`` and ``/ground_truth/material_ingested`` carries it (one message,
with its composition). That the same run gives the same budgets, every message to the unit, is
test_mission's determinism pair's (``run_compare`` compares both topics).

The stack runs in the lockstep, held where each operation has settled (as a mission does), so a
run is a function of its goals whatever the machine's load.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import actionlib
import pytest
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point
from std_srvs.srv import Trigger

import owl_msgs.msg as owl
from ow_bringup.stack import wait_until
from ow_bringup.testing import subscribe, wait_connected, wait_for_server
from ow_description.description import DEFAULT_GROUND_Z
from ow_lander.msg import DockIngestSampleAction, DockIngestSampleGoal
from ow_materials.msg import BulkExcavation
from ow_msgs.msg import RegolithBudget
from ow_msgs.srv import IngestSample
from ow_runtime.connections import wait_sending
from ow_runtime.names import MATERIAL_INGESTED, REGOLITH_BUDGET, SIM_INGEST_SAMPLE

GROUND = DEFAULT_GROUND_Z
#: s of wall time a goal may take, and a server or a message may take to appear.
GOAL_TIMEOUT_S = 300.0
WAIT_S = 60.0
ACCOUNTS = ("excavated", "in_scoop", "in_dock", "ingested", "spilled", "deposited")
HOLDING = ACCOUNTS[1:]

#: The operations before the ingestion: (action, goal).
SEQUENCE: list[tuple[str, Any]] = [
    ("ArmUnstow", owl.ArmUnstowGoal()),
    ("TaskScoopLinear", owl.TaskScoopLinearGoal(0, False, Point(1.7, 0.0, GROUND), 0.05, 0.2)),
    ("TaskDiscardSample", owl.TaskDiscardSampleGoal(0, False, Point(1.5, 0.5, GROUND), 0.3)),
    ("TaskScoopLinear", owl.TaskScoopLinearGoal(0, False, Point(1.7, -0.25, GROUND), 0.05, 0.2)),
    ("TaskDeliverSample", owl.TaskDeliverSampleGoal()),
]


class Latest:
    """Every message of a topic from now on (a latched one first)."""

    def __init__(self, topic: str, data_class: type) -> None:
        self.messages: list[Any] = []
        self._lock = threading.Lock()
        self.sub = subscribe(topic, data_class, self._on)

    def _on(self, msg: Any) -> None:
        with self._lock:
            self.messages.append(msg)

    def all(self) -> list[Any]:
        with self._lock:
            return list(self.messages)

    def wait_for(self, condition, what: str) -> Any:
        """The newest message, once one satisfies ``condition`` (wall-time wait)."""
        deadline = time.monotonic() + WAIT_S
        while True:
            messages = self.all()
            if messages and condition(messages[-1]):
                return messages[-1]
            assert time.monotonic() < deadline, f"{self.sub.name}: no message with {what}"
            time.sleep(0.02)


#: The stock clients, one per action, for the run.
CLIENTS: dict[str, actionlib.SimpleActionClient] = {}


def stock_client(name: str, action: type) -> actionlib.SimpleActionClient:
    """actionlib's own client of ``name``, connected to the running server (results and
    feedback written to it on the server's side)."""
    if name not in CLIENTS:
        CLIENTS[name] = actionlib.SimpleActionClient(name, action)
    client = CLIENTS[name]
    wait_for_server(client, WAIT_S)
    for sub in (client.action_client.result_sub, client.action_client.feedback_sub):
        assert wait_sending(sub, WAIT_S), f"{name}: {sub.name} not connected"
    return client


def finish(name: str, action: type, goal: Any) -> tuple[int, Any, str]:
    """Send ``goal`` and wait (wall time) for its end: (state, result, status text)."""
    client = stock_client(name, action)
    client.send_goal(goal)
    deadline = time.monotonic() + GOAL_TIMEOUT_S
    while client.simple_state != actionlib.SimpleGoalState.DONE:
        assert time.monotonic() < deadline, f"{name}: the goal did not end"
        time.sleep(0.05)
    return client.get_state(), client.get_result(), client.get_goal_status_text()


def units(msg: RegolithBudget) -> dict[str, int]:
    """account -> um^3."""
    return {name: getattr(msg, name).volume_um3 for name in ACCOUNTS}


def holds(msg: RegolithBudget) -> bool:
    """The budget's equation, exactly."""
    return msg.excavated.volume_um3 == sum(getattr(msg, name).volume_um3 for name in HOLDING)


def run_once(ros_stack) -> dict[str, Any]:
    """Start the stack, run the sequence and ingest twice; what the run left, as plain values."""
    ros_stack.start_node(
        "ow_lander",
        "arm_services",
        params={
            "plan_and_execute": True,
            "execution": {"lockstep": True, "lockstep_hold": True},
        },
        wait_for_topics=["/TaskDeliverSample/status"],
    )
    ros_stack.start_node("ow_lander", "pan_tilt", wait_for_topics=["/DockIngestSample/status"])
    # Paused until every subscription is connected, and held at t = 0 until the arm services
    # joined the lockstep: they get the state the run starts from (as a mission starts).
    ros_stack.start_node(
        "ow_sim_bullet",
        "sim",
        params={
            "terrain": f"flat:{GROUND}",
            "real_time_factor": 0.0,
            "start_paused": True,
            "lockstep_clients": ["/arm_services"],
        },
        wait_for_services=["/sim/resume", SIM_INGEST_SAMPLE],
        wait_for_topics=[REGOLITH_BUDGET],
    )
    budgets = Latest(REGOLITH_BUDGET, RegolithBudget)
    ingested = Latest(MATERIAL_INGESTED, BulkExcavation)
    try:
        wait_connected(budgets.sub)
        # The arm services get the state the run starts from (as a mission waits). A /clock
        # that never connected (seen in CI) was a killed node of an earlier module still
        # listed as its subscriber: module stacks forget such nodes now.
        arm_topics = ros_stack.master.subscribed_by("/arm_services")
        if not wait_until(lambda: not ros_stack.master.unconnected(arm_topics), WAIT_S):
            raise AssertionError(f"unconnected: {ros_stack.master.unconnected(arm_topics)}")
        assert ros_stack.service("/sim/resume", Trigger)().success
        empty = budgets.wait_for(lambda m: True, "the latched budget")
        assert units(empty) == dict.fromkeys(ACCOUNTS, 0)
        for name, goal in SEQUENCE:
            state, _, text = finish(name, getattr(owl, f"{name}Action"), goal)
            assert state == GoalStatus.SUCCEEDED, f"{name}: {text}"
        first = finish("DockIngestSample", DockIngestSampleAction, DockIngestSampleGoal())
        after = budgets.wait_for(lambda m: m.ingested.volume_um3 > 0, "regolith ingested")
        # The budget the ingestion changed: the last before it (the simulation stood there).
        before = [m for m in budgets.all() if m.ingested.volume_um3 == 0][-1]
        truth = ingested.wait_for(lambda m: True, "the ingestion's ground truth")
        again = finish("DockIngestSample", DockIngestSampleAction, DockIngestSampleGoal())
        service = ros_stack.service(SIM_INGEST_SAMPLE, IngestSample)()
        time.sleep(0.5)  # wall: a second ground truth would have come by now
        return {
            "budgets": budgets.all(),
            "before": before,
            "after": after,
            "first": first,
            "again": again,
            "service": service,
            "truths": ingested.all(),
            "truth": truth,
        }
    finally:
        budgets.sub.unregister()
        ingested.sub.unregister()
        ros_stack.shutdown()


@pytest.fixture(scope="module")
def run(ros_stack):
    CLIENTS.clear()
    try:
        yield run_once(ros_stack)
    finally:
        CLIENTS.clear()


def test_the_budget_holds_exactly_at_every_message(run):
    assert len(run["budgets"]) > 10
    off = [units(m) for m in run["budgets"] if not holds(m)]
    assert not off, f"excavated != in scoop + in dock + ingested + spilled + deposited: {off[0]}"
    stamps = [m.header.stamp.to_sec() for m in run["budgets"]]
    assert stamps == sorted(stamps)


def test_dig_discard_dig_and_delivery_move_the_regolith_where_it_went(run):
    before = units(run["before"])
    assert before["in_dock"] > 0  # the delivery poured some into the dock
    capacity = 6.68e-4  # m^3: each 20 cm cut 5 cm deep fills the scoop
    assert run["before"].excavated.volume == pytest.approx(2 * capacity, rel=0.01)
    assert before["in_scoop"] == before["ingested"] == 0  # discarded, then delivered
    assert before["deposited"] > 0  # the discard (and spills) on the terrain
    # Both cuts were in the irradiated top layer only (5 cm of its 10 cm).
    assert run["before"].layers[0] == run["before"].top_layer == "irradiated"
    assert list(run["before"].excavated.layer_volumes[1:]) == [0.0]


def test_dock_ingest_sample_ingests_the_dock_and_reports_it_as_oceanwaters(run):
    before, after = run["before"], run["after"]
    state, result, text = run["first"]
    assert (state, text, result.sample_ingested) == (GoalStatus.SUCCEEDED, "Sample ingested", True)
    assert after.ingested.volume_um3 == before.in_dock.volume_um3 > 0
    assert after.in_dock.volume_um3 == 0
    for name in ("excavated", "in_scoop", "spilled", "deposited"):
        assert getattr(after, name).volume_um3 == getattr(before, name).volume_um3, name
    # The top layer's share of the sample, from the budget's layers.
    top_share = after.ingested.layer_volumes[after.layers.index(after.top_layer)]
    assert top_share / after.ingested.volume == pytest.approx(1.0)
    # One ground-truth message for the one ingestion, with the sample's volume and composition.
    assert len(run["truths"]) == 1
    truth = run["truth"]
    assert truth.volume == pytest.approx(after.ingested.volume, rel=1e-12)
    assert [(c.id, c.name) for c in truth.composition] == [
        (0, "ICE"),
        (1, "MG_HYDRATES"),
        (2, "SALT"),
    ]
    assert [c.proportion for c in truth.composition] == pytest.approx([0.85, 0.10, 0.05], abs=1e-6)
    assert truth.header.stamp.to_sec() == pytest.approx(after.header.stamp.to_sec())
    # Nothing left: OceanWATERS' answer, and the simulation's.
    state, result, text = run["again"]
    assert (state, text, result.sample_ingested) == (
        GoalStatus.SUCCEEDED,
        "No sample was present in dock",
        False,
    )
    service = run["service"]
    assert (service.success, service.sample_ingested, service.volume) == (True, False, 0.0)
    assert service.message == "No sample was present in dock"


def test_without_the_simulation_dock_ingest_sample_aborts_saying_why(ros_stack):
    ros_stack.start_node("ow_lander", "pan_tilt", wait_for_topics=["/DockIngestSample/status"])
    try:
        state, result, text = finish(
            "DockIngestSample", DockIngestSampleAction, DockIngestSampleGoal()
        )
    finally:
        ros_stack.shutdown()
    assert state == GoalStatus.ABORTED
    assert result.sample_ingested is False
    assert text.startswith(f"Removal service failed: {SIM_INGEST_SAMPLE} did not answer"), text
