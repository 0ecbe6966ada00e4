"""The live DEM in the running stack (docs/dem.md, "Live co-simulation"): the simulation with
``~terrain_forces: yade`` and the arm services dig; the scoop's wrench during the dig comes from
YADE (it is not the table's), and when the YADE process is killed in the middle of a second dig,
the simulation goes on (that dig ends, the rest of it with the table), logs why, and the dig
fails with the DEM's reason. A dig that
follows a grind to the same depth (the mission's) digs the grinder's cuttings live: the scoop's tip
is on the trench floor, at depth 0 below the height map, in the bed's loose layer.

A small bed of large spheres keeps a dig to a few minutes of wall time; its template is settled
before the stack starts, so no dig waits for it.
"""

from __future__ import annotations

import os
import shutil
import signal
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ow_bringup.testing import subscribe
from ow_dem_bridge.live import LiveDemModel
from ow_dem_bridge.live_config import LiveConfig
from ow_dem_bridge.models import DEFAULT_TABLE_PATH
from ow_dem_bridge.table import load_table
from ow_description.description import DEFAULT_GROUND_Z

pytestmark = [
    pytest.mark.yade,
    pytest.mark.skipif(
        shutil.which("yade") is None,
        reason="YADE is not installed: apt-get install yade (make setup installs it)",
    ),
    # Minutes of wall time, beside make test's 10: its own target.
    pytest.mark.skipif(
        not os.environ.get("OW_DEM_LIVE_TESTS"),
        reason="live DEM dig in the stack: set OW_DEM_LIVE_TESTS=1 (make test-dem-live) to run it",
    ),
]

GROUND = DEFAULT_GROUND_Z
#: ~250 spheres of 15 mm: the test's bed (the defaults are ~1500 of 10 mm).
SMALL = {
    "particle_radius": 0.015,
    "bed_length": 0.4,
    "bed_behind": 0.08,
    "bed_width": 0.16,
    "bed_height": 0.14,
    "floor_depth": 0.08,
}
DIG = {"y": 0.0, "depth": 0.04, "length": 0.1, "ground_position": GROUND}
#: s of wall time a dig may take.
DIG_TIMEOUT_S = 1800.0
#: Every /sim/dem_digs message of the module's stack (ow_msgs/DemDig), in arrival order.
DEM_DIGS: list[Any] = []


def _children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
            found.append(int(entry.name))
    return found


@pytest.fixture(scope="module")
def live_stack(ros_stack: Any, start_lander: Any, tmp_path_factory: pytest.TempPathFactory) -> Any:
    cache = tmp_path_factory.mktemp("dem_live_cache")
    params = {**SMALL, "cache_dir": str(cache)}
    prepared = LiveDemModel(LiveConfig.from_dict(params), None)
    prepared.wait_ready()
    prepared.close()
    start_lander(
        sim={"terrain_forces": "yade", "terrain_force_params": params},
        # The simulation waits for the DEM: each state comes later than the default 5 s allows
        # on a loaded machine.
        arm={"execution": {"joint_state_timeout_s": 300.0}},
        arm_services=["/arm/unstow", "/arm/dig_linear", "/arm/grind"],
        sim_topics=["/joint_states", "/sim/scoop_model_state", "/sim/scoop_model_wrench"],
    )
    from ow_msgs.msg import DemDig
    from ow_msgs.srv import Unstow
    from ow_runtime.names import SIM_DEM_DIGS

    DEM_DIGS.clear()
    subscribe(SIM_DEM_DIGS, DemDig, DEM_DIGS.append)
    unstow = ros_stack.service("/arm/unstow", Unstow)(delete_prev_traj=False)
    assert unstow.success, unstow.message
    return ros_stack


def _dig(ros_stack: Any, x: float, during: Any = None) -> tuple[Any, list[tuple[Any, Any]]]:
    """Dig at ``x``; (the response, (model state, model wrench) of each step in the ground)."""
    from geometry_msgs.msg import WrenchStamped

    from ow_msgs.msg import ToolState as ToolStateMsg
    from ow_msgs.srv import DigLinear

    lock = threading.Lock()
    states: dict[int, Any] = {}
    wrenches: dict[int, Any] = {}

    def on_state(msg: Any) -> None:
        with lock:
            states[msg.header.stamp.to_nsec()] = msg

    def on_wrench(msg: Any) -> None:
        with lock:
            wrenches[msg.header.stamp.to_nsec()] = msg

    subs = [
        subscribe("/sim/scoop_model_state", ToolStateMsg, on_state),
        subscribe("/sim/scoop_model_wrench", WrenchStamped, on_wrench),
    ]
    watcher = threading.Thread(target=during, daemon=True) if during else None
    try:
        if watcher:
            watcher.start()
        call = ros_stack.service("/arm/dig_linear", DigLinear)
        response = call(use_defaults=False, delete_prev_traj=False, x=x, **DIG)
        time.sleep(1.0)  # the last messages of the dig
    finally:
        for sub in subs:
            sub.unregister()
    with lock:
        pairs = [(states[k], wrenches[k]) for k in sorted(states) if k in wrenches]
    return response, [(s, w) for s, w in pairs if s.depth > 0.0]


def _force(msg: Any) -> np.ndarray:
    f = msg.wrench.force
    return np.array([f.x, f.y, f.z])


def test_a_dig_runs_live_and_a_killed_dem_leaves_the_stack_running(live_stack):
    table = load_table(DEFAULT_TABLE_PATH)
    sim = next(node for node in live_stack.nodes if node.name == "sim")

    response, in_ground = _dig(live_stack, 1.6)
    assert response.success, response.message
    assert len(in_ground) > 100
    # The wrench applied is the DEM's: off the table's lookup at most states in the cut.
    differs = sum(
        np.linalg.norm(_force(w) - table.lookup("scoop", s.material, s.depth, s.progress)[:3])
        > 0.05
        for s, w in in_ground
    )
    assert differs > len(in_ground) // 2, f"{differs} of {len(in_ground)} differ from the table"
    yade = [
        p
        for p in _children(sim.proc.pid)
        if b"yade_live" in Path(f"/proc/{p}/cmdline").read_bytes()
    ]
    assert len(yade) == 1
    # The dig's end is published with its sample: the spheres in the scoop, out of its bed.
    (first,) = DEM_DIGS
    assert (first.tool, first.error) == ("scoop", "")
    assert first.exchanges >= len(in_ground) and first.particles > 0
    assert 0 < first.sample_particles < first.particles and first.sample_volume > 0.0
    assert first.header.stamp.to_sec() > first.start_time

    killed: list[float] = []

    def kill_mid_dig() -> None:
        # Once the scoop is in the ground and the DEM has answered for a while.
        deadline = time.monotonic() + DIG_TIMEOUT_S
        while time.monotonic() < deadline:
            if sim.log().count("live DEM: dig at t=") >= 2:
                time.sleep(5.0)
                os.kill(yade[0], signal.SIGKILL)
                killed.append(time.monotonic())
                return
            time.sleep(0.5)

    response, in_ground = _dig(live_stack, 1.75, during=kill_mid_dig)
    assert killed, "the second dig never started live"
    # The rest of the dig ran on the table, and the dig fails with the DEM's reason.
    assert not response.success
    assert "the live DEM failed during the dig (" in response.message, response.message
    assert "killed by signal 9" in response.message
    assert sim.alive()
    log = sim.log()
    assert "live DEM: the dig that started at" in log and "killed by signal 9" in log
    # The failed dig is published too, with why and without a sample.
    failed = DEM_DIGS[1]
    assert "killed by signal 9" in failed.error and failed.sample_particles == 0


def test_a_dig_after_a_grind_to_its_depth_digs_the_cuttings_live(live_stack):
    from ow_msgs.srv import Grind

    sim = next(node for node in live_stack.nodes if node.name == "sim")
    place = {"x": 1.6, "y": 0.3, "ground_position": GROUND}
    grind = live_stack.service("/arm/grind", Grind)(
        use_defaults=False, delete_prev_traj=False, parallel=True, depth=0.04, length=0.15, **place
    )
    assert grind.success, grind.message
    digs_before = sim.log().count("live DEM: dig at t=")
    from ow_msgs.srv import DigLinear

    call = live_stack.service("/arm/dig_linear", DigLinear)
    response = call(use_defaults=False, delete_prev_traj=False, depth=0.04, length=0.1, **place)
    assert response.success, response.message
    log = sim.log()
    assert log.count("live DEM: dig at t=") > digs_before, "the dig did not reach the DEM"
    line = log[log.rindex("live DEM: dig at t=") :].splitlines()[0]
    loose = int(line.split("(")[1].split(" of them loose")[0])
    assert loose > 0, line  # the grinder's cuttings are in the bed
