"""The live DEM's part of a mission report on synthetic bag messages: the NRMSD (the paper's
Table 6 metric), the digs' in-ground states paired with their wrenches by stamp, the section only
for ``terrain_forces: yade`` missions, and its figure (the paper's Figure 19 for our scoop)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from ow_dem_bridge.api import ToolState, Wrench
from ow_dem_bridge.comparison import compare_forces, nrmsd
from ow_mission.live_dem_plot import plot_live_dem
from ow_mission.live_dem_report import (
    FIGURE,
    dig_series,
    dig_summary,
    live_dem_section,
    markdown_lines,
)
from ow_mission.report import live_dem_part, step_windows
from ow_mission.report_files import Figures
from ow_runtime.names import SIM_DEM_DIGS, SIM_SCOOP_MODEL_STATE, SIM_SCOOP_MODEL_WRENCH

TIP = np.array([0.1, 0.0, 0.08])


def test_nrmsd_is_the_rms_deviation_over_the_references_range():
    reference = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    assert nrmsd(reference, reference) == 0.0
    # A constant offset of 0.5 N over a range of 4 N.
    assert nrmsd(reference + 0.5, reference) == pytest.approx(0.125)
    # RMS of (1, -1, 1, -1, 1) = 1, range 4.
    assert nrmsd(reference + np.array([1, -1, 1, -1, 1]), reference) == pytest.approx(0.25)
    assert math.isnan(nrmsd(np.ones(3), np.zeros(3)))  # the reference does not vary
    with pytest.raises(ValueError, match=r"a model series of \(2,\) values against .*\(3,\)"):
        nrmsd(np.zeros(2), np.zeros(3))


def test_each_force_component_is_compared_on_its_own():
    live = np.array([[0.0, 0.0, 1.0, 9, 9, 9], [2.0, 4.0, 1.0, 9, 9, 9]])
    other = np.array([[1.0, 0.0, 1.0, 0, 0, 0], [1.0, 4.0, 1.0, 0, 0, 0]])
    result = compare_forces(live, {"table": other})
    assert result["table"]["Fx"] == pytest.approx(0.5)
    assert result["table"]["Fy"] == 0.0
    assert math.isnan(result["table"]["Fz"])


def _stamp(t: float) -> SimpleNamespace:
    sec = int(t)
    return SimpleNamespace(sec=sec, nanosec=round((t - sec) * 1e9))


def _state(t: float, depth: float) -> SimpleNamespace:
    return SimpleNamespace(
        header=SimpleNamespace(stamp=_stamp(t), frame_id="base_link"),
        tool="scoop",
        link="l_scoop",
        pose=SimpleNamespace(
            position=SimpleNamespace(x=1.7, y=0.0, z=-0.2),
            orientation=SimpleNamespace(w=1.0, x=0.0, y=0.0, z=0.0),
        ),
        twist=SimpleNamespace(
            linear=SimpleNamespace(x=0.1, y=0.0, z=0.0),
            angular=SimpleNamespace(x=0.0, y=0.0, z=0.0),
        ),
        depth=depth,
        progress=t,
        material=1,
    )


def _wrench(t: float, fx: float) -> SimpleNamespace:
    return SimpleNamespace(
        header=SimpleNamespace(stamp=_stamp(t), frame_id="l_scoop"),
        wrench=SimpleNamespace(
            force=SimpleNamespace(x=fx, y=0.0, z=2 * fx),
            torque=SimpleNamespace(x=0.0, y=0.1, z=0.0),
        ),
    )


def _messages(times: list[float], depths: list[float]) -> dict[str, list]:
    return {
        SIM_SCOOP_MODEL_STATE: [(0, _state(t, d)) for t, d in zip(times, depths, strict=True)],
        SIM_SCOOP_MODEL_WRENCH: [(0, _wrench(t, -t)) for t in times],
    }


WINDOWS = [("grind", 0.0, 10.0), ("dig_spoil", 10.0, 20.0), ("dig_sample", 30.0, 40.0)]


def test_the_in_ground_states_of_each_dig_step_are_paired_with_their_wrenches():
    times = [5.0, 11.0, 11.01, 11.02, 19.5, 25.0, 31.0]
    depths = [0.05, 0.0, 0.02, 0.03, 0.01, 0.04, 0.02]
    series = dig_series(_messages(times, depths), WINDOWS, TIP)
    assert [s.step for s in series] == ["dig_spoil", "dig_sample"]
    spoil = series[0]
    # 11.0 s: out of the ground (depth 0); 5 s (grind) and 25 s (between steps) are no dig's.
    assert spoil.times.tolist() == [11.01, 11.02, 19.5]
    assert np.allclose(spoil.wrenches[:, 0], [-11.01, -11.02, -19.5])
    assert np.allclose(spoil.wrenches[:, 2], 2 * spoil.wrenches[:, 0])
    # The tip velocity from the link twist (identity pose, no rotation): the link's.
    assert np.allclose(spoil.states[0].velocity, [0.1, 0.0, 0.0])
    assert spoil.states[1].depth == 0.03


class Offset:
    """A model answering the live wrench's Fx shifted by 1 N (knows it from the progress)."""

    def wrench(self, state: ToolState) -> Wrench:
        return Wrench(np.array([-state.progress + 1.0, 0.0, -2 * state.progress]), np.zeros(3))


def test_a_digs_summary_compares_the_models_on_the_recorded_states():
    times = [11.0 + 0.01 * k for k in range(11)]
    (series,) = dig_series(_messages(times, [0.03] * 11), WINDOWS[:2], TIP)
    summary = dig_summary(series, {"table": Offset()})
    assert summary["samples"] == 11 and summary["step"] == "dig_spoil"
    assert summary["nrmsd"]["table"]["Fx"] == pytest.approx(1.0 / 0.1)  # 1 N over 0.1 N range
    assert summary["nrmsd"]["table"]["Fz"] == pytest.approx(0.0, abs=1e-9)
    assert summary["mean_live_n"]["Fx"] == pytest.approx(-11.05)
    assert summary["peak_force_n"] == pytest.approx(11.1 * math.sqrt(5))


def test_the_section_is_made_for_live_dem_missions_only():
    document = {"config": {"terrain_forces": "table"}, "steps": []}
    assert (
        live_dem_section(document, {}, step_windows(document)) is None
        and "live_dem" not in document
    )
    assert markdown_lines(document) == []
    steps = [{"step": "dig_spoil", "sim_start_s": 10.0, "sim_end_s": 20.0}]
    document = {"config": {"terrain_forces": "yade"}, "steps": steps}
    note = live_dem_section(document, {}, step_windows(document))
    assert note is not None and "no live DEM forces" in note
    assert document["live_dem"] == {"digs": []}
    times = [11.0 + 0.01 * k for k in range(5)]
    assert live_dem_section(document, _messages(times, [0.03] * 5), step_windows(document)) is None
    (dig,) = document["live_dem"]["digs"]
    assert set(dig["nrmsd"]) == {"table", "balovnev"} and dig["samples"] == 5
    lines = markdown_lines(document)
    assert lines[0].startswith("## Live DEM forces")
    assert any("| dig_spoil | 5 |" in line for line in lines)


def test_the_report_draws_the_figure_with_the_models_on_the_recorded_states(tmp_path):
    import cv2

    steps = [
        {"step": "dig_spoil", "sim_start_s": 10.0, "sim_end_s": 20.0},
        {"step": "dig_sample", "sim_start_s": 30.0, "sim_end_s": 40.0},
    ]
    document = {"config": {"terrain_forces": "yade"}, "steps": steps}
    times = [11.0 + 0.01 * k for k in range(20)] + [31.0 + 0.01 * k for k in range(20)]
    figures = Figures()
    messages = _messages(times, [0.03] * 40)
    assert live_dem_part(tmp_path, document, messages, figures) is None
    assert figures.files == {"live_dem": FIGURE}
    assert "Figure 19" in figures.captions["live_dem"]
    assert [d["step"] for d in document["live_dem"]["digs"]] == ["dig_spoil", "dig_sample"]
    image = cv2.imread(str(tmp_path / FIGURE))
    assert image is not None
    assert image.shape[:2] == (680, 1300)  # two digs: 13 x (2 x 3.0 + 0.8) in at 100 dpi
    # Not drawn when the report only works out the numbers, nor without live forces.
    (tmp_path / FIGURE).unlink()
    undrawn = Figures(draw=False)
    assert live_dem_part(tmp_path, document, messages, undrawn) is None
    assert not (tmp_path / FIGURE).exists() and not undrawn.files
    note = live_dem_part(tmp_path, document, {}, figures := Figures())
    assert note is not None and "no live DEM forces" in note
    assert not (tmp_path / FIGURE).exists() and not figures.files


def test_the_figure_refuses_no_dig_and_a_score_list_of_another_length(tmp_path):
    with pytest.raises(ValueError, match="no dig to draw"):
        plot_live_dem([], [], tmp_path / "x.png")
    dig = ("dig_spoil", np.arange(3.0), np.zeros((3, 6)), {"table": np.ones((3, 6))})
    with pytest.raises(ValueError, match="0 NRMSD entries for 1 digs"):
        plot_live_dem([dig], [], tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


def _dem_dig(start: float, particles: int, volume: float, error: str = "") -> SimpleNamespace:
    return SimpleNamespace(
        start_time=start,
        particles=700,
        loose_particles=250,
        sample_particles=particles,
        sample_volume=volume,
        sample_mass=volume * 1500.0,
        error=error,
    )


def test_each_dig_step_shows_the_sample_of_its_last_dem_dig_and_every_failure():
    steps = [
        {"step": "dig_spoil", "sim_start_s": 10.0, "sim_end_s": 20.0},
        {"step": "dig_sample", "sim_start_s": 30.0, "sim_end_s": 40.0},
    ]
    document = {"config": {"terrain_forces": "yade"}, "steps": steps}
    times = [11.0 + 0.01 * k for k in range(5)] + [31.0 + 0.01 * k for k in range(5)]
    messages = _messages(times, [0.03] * 10)
    messages[SIM_DEM_DIGS] = [
        (0, _dem_dig(11.0, 10, 2e-5)),
        (0, _dem_dig(15.0, 21, 3.2e-4)),  # the step's last dig: what the scoop carries out
        (0, _dem_dig(31.0, 0, 0.0, "the YADE process (pid 7) was killed by signal 9")),
    ]
    assert live_dem_section(document, messages, step_windows(document)) is None
    spoil, sample = document["live_dem"]["digs"]
    assert spoil["dem"] == {
        "digs": 2,
        "particles": 700,
        "loose_particles": 250,
        "sample_particles": 21,
        "sample_volume_m3": 3.2e-4,
        "sample_mass_kg": pytest.approx(0.48),
        "errors": [],
    }
    assert sample["dem"]["errors"] == ["the YADE process (pid 7) was killed by signal 9"]
    lines = markdown_lines(document)
    assert any(line.endswith("| 21 of 700, 320.0, 480.0 |") for line in lines)
    assert "- **dig_sample: the DEM failed**: the YADE process (pid 7) was killed by signal 9" in (
        lines
    )
    # A bag without /sim/dem_digs (a run from before it) shows no sample.
    del messages[SIM_DEM_DIGS]
    live_dem_section(document, messages, step_windows(document))
    assert document["live_dem"]["digs"][0]["dem"] == {"digs": 0}
    assert any(line.endswith("| - |") for line in markdown_lines(document))
