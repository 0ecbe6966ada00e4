"""The mission report made from a run's bags (ow_mission.report, plots, replay, render), on
synthetic runs written as real split bags in tmp_path; no ROS master."""

from __future__ import annotations

import json
import subprocess
from datetime import datetime
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest

import ow_mission.report as report_module
from ow_description.description import URDF_PATH
from ow_description.terrain import HeightMap
from ow_mission.errors import FiguresError, ReplayError
from ow_mission.figures import (
    figures_status,
    make_figures,
    start_figures,
    tell_figures,
    wait_for_figures,
)
from ow_mission.figures import main as figures_main
from ow_mission.plots import DEPTH_TOLERANCE_M, TrenchGeometry, detector_trace, trench_profile
from ow_mission.recording import read_recording
from ow_mission.render import Camera, camera_axes, fit_camera
from ow_mission.replay import frame_times, make_replay, step_at
from ow_mission.report import write_run_report
from ow_mission.report_files import image_links
from ow_power.bagwriter import SplitBagWriter
from ow_power.synthetic import BagMessages, Segment, write_run

JOINTS = (
    "j_shou_yaw",
    "j_shou_pitch",
    "j_prox_pitch",
    "j_dist_pitch",
    "j_hand_yaw",
    "j_scoop_yaw",
    "j_grinder",
    "j_ant_pan",
    "j_ant_tilt",
)
SEGMENTS = (
    Segment("unstow", 3.0, {"j_shou_pitch": 0.1}, {"j_shou_pitch": 50.0}),  # 5 W: 15 J
    Segment(  # +2 W and -6 W: signed -16 J, |.| 32 J
        "guarded_move",
        4.0,
        {"j_shou_pitch": 0.1, "j_prox_pitch": -0.2},
        {"j_shou_pitch": 20.0, "j_prox_pitch": 30.0},
    ),
    Segment("grind", 2.5, {"j_grinder": 0.1}, {"j_grinder": 1.0}),  # 0.1 W: 0.25 J
)
EXPECTED_J = {"unstow": (15.0, 15.0), "guarded_move": (-16.0, 32.0), "grind": (0.25, 0.25)}
START_S = 10.0
GROUND_Z = -0.155
CONFIG = {
    "name": "synthetic",
    "terrain": "flat",
    "seed": 0,
    "x": 1.65,
    "y": 0.0,
    "expected_ground": GROUND_Z,
    "trench_depth": 0.10,
    "trench_length": 0.3,
    "parallel": True,
    "bottom_grind_depth": 0.05,
    "node_params": {},
}
CONTACT_S = START_S + 3.0 + 3.0  # in the guarded move


def _flat() -> HeightMap:
    return HeightMap.flat(GROUND_Z, half_extent=1.0, resolution=0.02, centre_x=1.5)


def _trenched(depth: float) -> HeightMap:
    """The flat terrain with the trench of CONFIG carved ``depth`` m deep (12 cm wide)."""
    flat = _flat()
    g = TrenchGeometry.from_config(CONFIG)
    xs, ys = flat.cell_centres()
    X, Y = np.meshgrid(xs, ys)
    rel = np.stack([X - g.start[0], Y - g.start[1]], axis=-1)
    along, across = rel @ g.direction, rel @ g.normal
    inside = (along >= -0.02) & (along <= g.length + 0.02) & (np.abs(across) <= 0.06)
    heights = flat.heights.copy()
    heights[inside] -= depth
    return HeightMap(heights, flat.resolution, flat.origin_x, flat.origin_y)


def _put_terrain(writer, messages, stamp_s, terrain):
    ns = round(stamp_s * 1e9)
    rows, cols = terrain.shape
    ros1_type, md5, msgdef, data = messages.serialize(
        "ow_msgs/msg/HeightMap",
        header=messages.header(ns, "base_link"),
        resolution=terrain.resolution,
        origin_x=terrain.origin_x,
        origin_y=terrain.origin_y,
        rows=rows,
        cols=cols,
        heights=terrain.heights.astype(np.float32).ravel(),
    )
    writer.write("/sim/terrain", ros1_type, md5, msgdef, ns, data)


def _put_detector(writer, messages, stamp_s, signal, average, contact):
    ns = round(stamp_s * 1e9)
    ros1_type, md5, msgdef, data = messages.serialize(
        "ow_msgs/msg/GroundDetectorSignal",
        header=messages.header(ns, "base_link"),
        detector="velocity",
        signal=signal,
        moving_average=average,
        threshold=-0.015,
        contact=contact,
    )
    writer.write("/arm/ground_detector", ros1_type, md5, msgdef, ns, data)


def _write_bags(directory: Path, trench_depth: float = 0.16, detector: bool = True) -> list[Path]:
    """A synthetic run split into 4 s bags: terrain flat at the start, trenched at the end."""
    writer = SplitBagWriter(directory, split_duration_s=4.0, start=datetime(2025, 1, 2, 3, 4, 5))
    messages = BagMessages()
    _put_terrain(writer, messages, START_S, _flat())
    end = write_run(writer, SEGMENTS, JOINTS, start_s=START_S)
    _put_terrain(writer, messages, end, _trenched(trench_depth))
    if detector:
        for k in range(20):
            t = CONTACT_S - 1.0 + 0.05 * k
            contact = k == 15
            _put_detector(writer, messages, t, -0.024 if k < 15 else 0.0, -0.024, contact)
    return writer.close()


def _document() -> dict:
    steps, t = [], START_S
    for segment in SEGMENTS:
        steps.append(
            {
                "step": segment.name,
                "service": f"/arm/{segment.name}",
                "request": {},
                "success": True,
                "message": "done",
                "planning_time_s": 0.01,
                "wall_time_s": 0.1,
                "sim_start_s": t,
                "sim_end_s": t + segment.duration_s,
                "mechanical_energy_j": 0.0,
                "energy_wh": 0.0,
                "peak_power_w": 0.0,
            }
        )
        t += segment.duration_s
    return {
        "success": True,
        "error": "",
        "failed_step": None,
        "wall_time_s": 1.0,
        "sim_time_s": t,
        "real_time_factor": t,
        "peak_memory_mb": 1.0,
        "ground_z": GROUND_Z,
        "config": dict(CONFIG),
        "steps": steps,
    }


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """A run directory with the synthetic bags and its report (renders off)."""
    directory = tmp_path_factory.mktemp("run")
    _write_bags(directory / "bags")
    write_run_report(directory, _document(), renders=False)
    return directory


def _table(markdown: str) -> dict[str, list[str]]:
    rows = [line for line in markdown.splitlines() if line.startswith("| ") and "`" in line]
    return {
        cells[0]: cells for cells in ([c.strip() for c in r.strip("|").split("|")] for r in rows)
    }


def test_every_image_the_report_links_exists_and_the_power_plot_is_linked(run_dir):
    markdown = (run_dir / "report.md").read_text()
    links = image_links(markdown)
    assert "power.png" in links
    assert "trench_profile.png" in links
    assert "guarded_move.png" in links
    for link in links:
        assert (run_dir / link).is_file(), link
    document = json.loads((run_dir / "report.json").read_text())
    assert set(document["figures"].values()) == set(links)
    assert len(list((run_dir / "bags").glob("*.bag"))) == 3  # the plot covers every split bag


def test_report_energies_equal_the_plots_labels_and_the_closed_form(run_dir):
    document = json.loads((run_dir / "report.json").read_text())
    table = _table((run_dir / "report.md").read_text())
    for step in document["steps"]:
        signed, absolute = EXPECTED_J[step["step"]]
        assert step["mechanical_energy_j"] == pytest.approx(signed, abs=1e-6)
        assert step["mechanical_energy_abs_j"] == pytest.approx(absolute, abs=1e-6)
        # The plot's label is made from the same numbers as the table's cells.
        label = step["power_plot_label"].split("\n")
        row = table[step["step"]]
        assert label[0] == step["step"]
        assert label[1] == f"{row[4]} J signed"
        assert label[2] == f"{row[5]} J |.|"
        # Peaks: of the total power with P0 (43 W), and of sum |tau*omega| without it.
        segment = next(s for s in SEGMENTS if s.name == step["step"])
        absolute_w = sum(abs(segment.effort[j] * w) for j, w in segment.velocity.items())
        assert step["peak_power_w"] == pytest.approx(segment.power_w() + 43.0)
        assert step["peak_mechanical_power_w"] == pytest.approx(absolute_w)


def test_a_run_without_bags_links_no_image(tmp_path):
    write_run_report(tmp_path, _document(), renders=False)
    markdown = (tmp_path / "report.md").read_text()
    assert image_links(markdown) == []
    assert "No bag was recorded" in markdown


def test_the_dig_verdict_comes_from_the_profile(run_dir):
    document = json.loads((run_dir / "report.json").read_text())
    assert document["trench"]["worked"] is True
    assert document["trench"]["depth_reached_m"] == pytest.approx(0.16, abs=1e-6)
    assert "The dig worked" in (run_dir / "report.md").read_text()


def test_a_mission_stopped_before_the_grind_has_no_trench_verdict(tmp_path):
    _write_bags(tmp_path / "bags")
    document = _document()
    document["steps"] = document["steps"][:2]
    document["success"] = False
    write_run_report(tmp_path, document, renders=False)
    markdown = (tmp_path / "report.md").read_text()
    assert "trench_profile.png" not in image_links(markdown)
    assert "dig worked" not in markdown and "did NOT reach" not in markdown
    assert "stopped before the grind" in markdown
    for link in image_links(markdown):
        assert (tmp_path / link).is_file(), link


@pytest.mark.parametrize(
    ("depth", "worked"),
    [(0.16, True), (0.10, True), (0.10 - DEPTH_TOLERANCE_M + 1e-4, True), (0.05, False)],
)
def test_trench_profile_along_and_across(depth, worked):
    profile = trench_profile(_flat(), _trenched(depth), CONFIG, GROUND_Z)
    assert profile.floor_z == pytest.approx(GROUND_Z - depth, abs=1e-9)
    assert profile.worked is worked
    assert profile.requested_floor_z == pytest.approx(GROUND_Z - 0.10)
    assert profile.requested_bottom_z == pytest.approx(GROUND_Z - 0.15)
    assert np.allclose(profile.along_before, GROUND_Z)
    # Across the middle: carved within 6 cm of the line, untouched beyond 8 cm.
    assert np.allclose(profile.across_after[np.abs(profile.across_m) <= 0.05], GROUND_Z - depth)
    assert np.allclose(profile.across_after[np.abs(profile.across_m) >= 0.08], GROUND_Z)
    # Along: untouched beyond the trench's ends.
    assert np.allclose(profile.along_after[profile.along_m <= -0.05], GROUND_Z)


@pytest.mark.parametrize(("found", "ground"), [(None, GROUND_Z), (-0.21, -0.21)])
def test_the_cameras_frame_the_trench_at_the_ground_found_or_else_the_configured(found, ground):
    points = np.array(report_module.framed_trench({"config": CONFIG, "ground_z": found}))
    # Its floor below the requested depth and the bottom grind, its top 5 cm above the ground.
    assert sorted(set(points[:, 2])) == pytest.approx([ground - 0.15, ground + 0.05])
    g = TrenchGeometry.from_config(CONFIG)
    along = (points[:, :2] - g.start) @ g.direction
    assert sorted(set(np.round(along, 9))) == pytest.approx([-0.1, g.length + 0.1])


def test_read_recording_gives_first_and_last_terrain_and_joint_states(run_dir):
    recording = read_recording(sorted((run_dir / "bags").glob("*.bag")))
    assert len(recording.terrains) == 2
    assert np.allclose(recording.terrains[0][1].heights, _flat().heights, atol=1e-6)
    assert np.allclose(recording.terrains[-1][1].heights, _trenched(0.16).heights, atol=1e-6)
    assert recording.joint_names == list(JOINTS)
    assert len(recording.joint_t) == 951  # 9.5 s at 100 Hz, none lost by the splits
    assert recording.terrain_at(START_S + 1.0) is recording.terrains[0][1]


def test_the_recorded_detector_is_used_when_the_bags_have_it(run_dir):
    recording = read_recording(sorted((run_dir / "bags").glob("*.bag")))
    trace = detector_trace(recording, START_S + 3.0, START_S + 7.0, 0.3)
    assert trace is not None and trace.source == "recorded"
    assert trace.contact_s == pytest.approx(CONTACT_S - 1.0 + 0.75)
    assert len(trace.t_s) == 20


def test_no_detector_and_no_contact_gives_no_figure_and_a_note(tmp_path):
    _write_bags(tmp_path / "bags", detector=False)
    recording = read_recording(sorted((tmp_path / "bags").glob("*.bag")))
    assert detector_trace(recording, START_S + 3.0, START_S + 7.0, 0.3) is None
    write_run_report(tmp_path, _document(), renders=False)
    markdown = (tmp_path / "report.md").read_text()
    assert "guarded_move.png" not in image_links(markdown)
    assert "no detector figure" in markdown


@pytest.mark.parametrize(
    ("t0", "t1", "max_frames", "min_step", "count"),
    [(0.0, 100.0, 200, 0.1, 200), (0.0, 10.0, 200, 0.1, 101), (5.0, 5.3, 50, 0.1, 4)],
)
def test_frame_times_are_bounded_evenly_spaced_and_cover_the_span(
    t0, t1, max_frames, min_step, count
):
    times = frame_times(t0, t1, max_frames, min_step)
    assert len(times) == count
    assert times[0] == t0 and times[-1] == pytest.approx(t1)
    assert np.allclose(np.diff(times), (t1 - t0) / (count - 1))


@pytest.mark.parametrize(("t0", "t1", "max_frames"), [(1.0, 1.0, 10), (0.0, 1.0, 1)])
def test_frame_times_refuses_an_empty_span_or_too_few_frames(t0, t1, max_frames):
    with pytest.raises(ReplayError, match=f"max_frames={max_frames}"):
        frame_times(t0, t1, max_frames, 0.1)


def test_frames_show_the_last_joint_state_at_or_before_their_time_and_name_the_step(run_dir):
    recording = read_recording(sorted((run_dir / "bags").glob("*.bag")))
    k = 123
    t = float(recording.joint_t[k])
    assert recording.joints_at(t + 0.005) == recording.joints_at(t)
    assert recording.joints_at(t - 0.005) == dict(
        zip(JOINTS, recording.joint_positions[k - 1].tolist(), strict=True)
    )
    steps = [("unstow", 10.0, 13.0), ("grind", 14.0, 15.0)]
    assert step_at(steps, 12.0) == "unstow"
    assert step_at(steps, 13.5) == "between steps"


def test_a_short_replay_has_its_frames_captions_and_rate(run_dir, tmp_path):
    from PIL import Image

    recording = read_recording(sorted((run_dir / "bags").glob("*.bag")))
    steps = [("unstow", 10.0, 13.0), ("guarded_move", 13.0, 17.0), ("grind", 17.0, 19.5)]
    result = make_replay(
        recording,
        steps,
        tmp_path / "r.gif",
        max_frames=4,
        fps=10.0,
        width=160,
        height=120,
        workers=1,
    )
    assert result.frames == 4 and result.fps == 10.0
    with Image.open(tmp_path / "r.gif") as gif:
        assert gif.n_frames == 4
        assert gif.info["duration"] == 100  # ms: 10 frames per second
        assert gif.size == (result.width, result.height)
        assert gif.size[1] > 120  # the caption band above the scene


def test_workers_make_the_same_gif_byte_for_byte_and_count_their_cpu(run_dir, tmp_path):
    recording = read_recording(sorted((run_dir / "bags").glob("*.bag")))
    steps = [("unstow", 10.0, 13.0), ("guarded_move", 13.0, 17.0), ("grind", 17.0, 19.5)]
    made = {}
    for workers in (1, 2, 3):
        seen: list[tuple[int, int]] = []
        result = make_replay(
            recording,
            steps,
            tmp_path / f"w{workers}.gif",
            max_frames=7,
            width=160,
            height=120,
            title="synthetic",
            on_frame=lambda i, n, seen=seen: seen.append((i, n)),
            workers=workers,
        )
        assert seen == [(i, 7) for i in range(7)]
        assert result.frames == 7
        assert result.cpu_seconds > 0 and result.seconds > 0
        made[workers] = (tmp_path / f"w{workers}.gif").read_bytes()
    assert made[2] == made[1] and made[3] == made[1]


def test_a_replay_started_renders_while_the_caller_works_and_is_finished_once(run_dir, tmp_path):
    from ow_mission.replay import start_replay

    recording = read_recording(sorted((run_dir / "bags").glob("*.bag")))
    with start_replay(recording, [], tmp_path / "r.gif", max_frames=4, width=160) as rendering:
        result = rendering.finish()
        with pytest.raises(ReplayError, match="finished already"):
            rendering.finish()
    assert result.frames == 4 and (tmp_path / "r.gif").is_file()
    with start_replay(recording, [], tmp_path / "c.gif", max_frames=4, width=160) as rendering:
        rendering.cancel()
        with pytest.raises(ReplayError, match="cancelled already"):
            rendering.finish()
    assert not (tmp_path / "c.gif").exists()


def test_a_report_with_renders_lists_its_figures_in_order_with_the_replay_last(tmp_path):
    """The replay renders in workers while the other figures are made; the report lists it
    where it always was, after the stills, with every frame."""
    _write_bags(tmp_path / "bags")
    document = write_run_report(tmp_path, _document(), renders=True)
    assert list(document["figures"]) == [
        "power",
        "trench_profile",
        "guarded_move",
        "still_00",
        "still_01",
        "replay",
    ]
    assert document["replay"]["frames"] == 96  # 9.5 s of joint states, a frame every 0.1 s
    assert document["replay"]["cpu_seconds_to_make"] > 0
    markdown = (tmp_path / "report.md").read_text()
    for link in image_links(markdown):
        assert (tmp_path / link).is_file(), link
    assert image_links(markdown)[-1] == "replay.gif"


def _numbers(document: dict) -> dict:
    """report.json without what only the figures add or what is timed."""
    skip = {"figures", "figure_notes", "figures_pending", "report_seconds", "figures_seconds"}
    return {k: v for k, v in json.loads(json.dumps(document)).items() if k not in skip}


def test_the_numbers_written_before_the_figures_are_the_reports(tmp_path):
    """figures: after_exit: the mission writes the numbers without drawing (report.json marked
    pending, no image); completing it draws the figures and changes no number."""
    _write_bags(tmp_path / "bags")
    first = write_run_report(tmp_path, _document(), renders=False, draw=False)
    assert first["figures_pending"] is True
    assert first["figures"] == {}
    # What the synthetic bags cannot show, as ever: no regolith budget, no battery.
    assert list(first["figure_notes"]) == ["regolith", "sample", "battery"]
    assert list(tmp_path.glob("*.png")) == []
    markdown = (tmp_path / "report.md").read_text()
    assert image_links(markdown) == []
    assert "--wait" in markdown and "figures.log" in markdown
    assert first["trench"]["worked"] is True and "faults" in first
    assert first["guarded_move_detector"]["contact_s"] is not None
    numbers = _numbers(first)

    done = write_run_report(tmp_path, json.loads((tmp_path / "report.json").read_text()))
    assert "figures_pending" not in done
    assert set(done["figures"]) >= {"power", "trench_profile", "guarded_move", "replay"}
    assert done["report_seconds"] == first["report_seconds"]  # the mission's; this one's:
    assert done["figures_seconds"] > 0
    assert _numbers({k: v for k, v in done.items() if k != "replay"}) == numbers
    assert done["figure_notes"] == first["figure_notes"]
    assert "--wait" not in (tmp_path / "report.md").read_text()


def test_the_numbers_read_the_joint_states_only_when_they_need_them(tmp_path, monkeypatch):
    """The numbers read the bags without /joint_states (half the messages) when /power and the
    detector were recorded; without a recorded detector they read them too, to replay it, and
    the numbers are those of the whole report."""
    _write_bags(tmp_path / "bags", detector=False)
    read = report_module.read_messages
    asked: list[set] = []

    def spy(bags, topics):
        asked.append(set(topics))
        return read(bags, topics)

    monkeypatch.setattr(report_module, "read_messages", spy)
    first = write_run_report(tmp_path, _document(), renders=False, draw=False)
    assert "/joint_states" not in asked[0] and asked[1:] == [{"/joint_states"}]
    document = json.loads((tmp_path / "report.json").read_text())
    done = write_run_report(tmp_path, document, renders=False)
    assert "/joint_states" in asked[2]  # the whole report reads everything at once
    assert _numbers(done) == _numbers(first)
    assert done["figure_notes"]["guarded_move"] == first["figure_notes"]["guarded_move"]
    with_detector = tmp_path / "with_detector"
    _write_bags(with_detector / "bags")
    messages = report_module.read_report_messages(
        sorted((with_detector / "bags").glob("*.bag")), joint_states=False
    )
    assert "/joint_states" not in messages and messages["/power"]
    assert not report_module._needs_joint_states(messages, _document())
    assert report_module._needs_joint_states({"/power": messages["/power"]}, _document())


def test_the_figures_process_draws_them_and_a_waiter_gets_them(tmp_path):
    _write_bags(tmp_path / "bags")
    write_run_report(tmp_path, _document(), renders=False, draw=False)
    proc = start_figures(tmp_path, renders=False)
    assert figures_status(tmp_path) in ("drawing", "drawn")
    document = wait_for_figures(tmp_path, timeout_s=120.0)
    assert proc.wait(timeout=60.0) == 0
    assert figures_status(tmp_path) == "drawn"
    assert list(document["figures"]) == ["power", "trench_profile", "guarded_move"]
    assert not (tmp_path / "figures.pid").exists()
    markdown = (tmp_path / "report.md").read_text()
    assert image_links(markdown) == list(document["figures"].values())
    assert figures_main(["--wait", str(tmp_path)]) == 0


def test_pending_figures_nobody_draws_are_an_error_naming_the_log(tmp_path):
    _write_bags(tmp_path / "bags")
    write_run_report(tmp_path, _document(), renders=False, draw=False)
    gone = subprocess.Popen(["true"])
    gone.wait()
    (tmp_path / "figures.pid").write_text(f"{gone.pid}\n")
    assert figures_status(tmp_path) == "lost"
    with pytest.raises(FiguresError, match=r"no process is making them.*figures\.log"):
        wait_for_figures(tmp_path)
    assert figures_main(["--wait", str(tmp_path)]) == 1
    with subprocess.Popen(["sleep", "30"]) as slow:
        (tmp_path / "figures.pid").write_text(f"{slow.pid}\n")
        try:
            with pytest.raises(FiguresError, match=r"not drawn within 0.3 s"):
                wait_for_figures(tmp_path, timeout_s=0.3)
        finally:
            slow.kill()


def test_figures_nobody_was_to_draw_are_drawn_when_asked_for(tmp_path):
    """figures: none (a campaign's missions): the numbers only, no process; the report and a
    waiter say how to draw the figures, and that command draws them from the bags."""
    _write_bags(tmp_path / "bags")
    document = _document()
    document["config"].update(figures="none", renders=False)  # the command follows renders
    first = write_run_report(tmp_path, document, renders=False, draw=False)
    assert first["figures_pending"] is True and first["figures"] == {}
    assert figures_status(tmp_path) == "not_drawn"
    command = f"python -m ow_mission.figures {tmp_path}"
    with pytest.raises(FiguresError, match=rf"figures: none.*`{command}`"):
        wait_for_figures(tmp_path)
    assert figures_main(["--wait", str(tmp_path)]) == 1
    markdown = (tmp_path / "report.md").read_text()
    assert "`figures: none`" in markdown and "python -m ow_mission.figures <run dir>" in markdown
    assert "--wait" not in markdown  # nothing is coming by itself
    told: list[str] = []
    tell_figures(None, tmp_path, wait=False, say=told.append)
    assert command in told[-1]
    assert figures_main([str(tmp_path)]) == 0  # what the report says to run
    assert figures_status(tmp_path) == "drawn"
    done = wait_for_figures(tmp_path)
    assert list(done["figures"]) == ["power", "trench_profile", "guarded_move"]
    assert _numbers(done) == _numbers(first)
    assert image_links((tmp_path / "report.md").read_text()) == list(done["figures"].values())


def test_a_figures_process_that_fails_says_so_in_the_report(tmp_path, monkeypatch):
    _write_bags(tmp_path / "bags")
    write_run_report(tmp_path, _document(), renders=False, draw=False)
    (tmp_path / "figures.pid").write_text("1\n")

    def broken(*args, **kwargs):
        raise RuntimeError("no display")

    monkeypatch.setattr(report_module, "_figures_from_bags", broken)
    assert make_figures(tmp_path, renders=False) == 1
    document = json.loads((tmp_path / "report.json").read_text())
    assert "figures_pending" not in document
    assert "RuntimeError: no display" in document["figure_notes"]["figures"]
    assert "RuntimeError: no display" in (tmp_path / "report.md").read_text()
    assert not (tmp_path / "figures.pid").exists()
    assert figures_status(tmp_path) == "drawn"


def test_a_replay_needs_a_process_to_render(run_dir, tmp_path):
    recording = read_recording(sorted((run_dir / "bags").glob("*.bag")))
    with pytest.raises(ReplayError, match="workers=0"):
        make_replay(recording, [], tmp_path / "r.gif", workers=0)


def test_unreadable_bags_give_one_note_naming_the_file_and_no_figure(tmp_path):
    bags = _write_bags(tmp_path / "bags")
    (tmp_path / "bags" / "zz_junk.bag").write_bytes(b"not a bag")
    with pytest.raises(ReplayError, match=r"cannot read .*zz_junk\.bag"):
        read_recording([*bags, tmp_path / "bags" / "zz_junk.bag"])
    document = write_run_report(tmp_path, _document(), renders=False)
    assert list(document["figure_notes"]) == ["bags"]
    assert "zz_junk.bag" in document["figure_notes"]["bags"]
    assert document["figures"] == {} and "faults" not in document
    assert image_links((tmp_path / "report.md").read_text()) == []


def _ndc(camera: Camera, points: np.ndarray) -> np.ndarray:
    view = np.reshape(
        pb.computeViewMatrixFromYawPitchRoll(
            camera.target, camera.distance, camera.yaw, camera.pitch, 0.0, 2
        ),
        (4, 4),
    ).T
    projection = np.reshape(
        pb.computeProjectionMatrixFOV(50.0, camera.width / camera.height, 0.05, 30.0), (4, 4)
    ).T
    clip = (projection @ view @ np.c_[points, np.ones(len(points))].T).T
    return clip[:, :2] / clip[:, 3:4]


@pytest.mark.parametrize(("yaw", "pitch"), [(35.0, -25.0), (70.0, -55.0), (-120.0, -10.0)])
def test_a_fitted_camera_sees_every_point_and_fills_the_frame(yaw, pitch):
    rng = np.random.default_rng(1)
    points = rng.uniform([-0.5, -1.0, -0.3], [2.5, 1.0, 1.8], size=(40, 3))
    camera = fit_camera(points, yaw=yaw, pitch=pitch, width=1024, height=768, margin=0.04)
    ndc = _ndc(camera, points)
    assert np.all(np.abs(ndc) <= 0.92 + 1e-6)  # 4 % of the width on each side
    # Tight: some point touches the margin in x or y.
    assert np.max(np.abs(ndc)) == pytest.approx(0.92, abs=1e-3)
    right, up, forward = camera_axes(yaw, pitch)
    assert np.allclose([right @ up, right @ forward, up @ forward], 0.0, atol=1e-6)  # float32


def test_a_still_shows_no_heightfield_texture():
    """The heightfield's checker texture drew a hard-edged blue half-plane: a flat terrain must
    render in one colour family (grey-white), with no saturated blue region."""
    from ow_mission.render import render_scene

    image = render_scene(
        {},
        HeightMap.flat(GROUND_Z, half_extent=1.5, resolution=0.05, centre_x=1.0),
        Camera((1.5, 0.0, GROUND_Z), 1.2, 35.0, -60.0, 160, 120),
        URDF_PATH,
    ).astype(int)
    blue = (image[:, :, 2] - image[:, :, 0] > 40) & (image[:, :, 2] > 120)
    assert blue.mean() < 0.01


def _drawn_together(joints: dict[str, float], terrain: HeightMap, camera: Camera) -> np.ndarray:
    """The robot and the terrain in one pybullet client, drawn in one picture."""
    from ow_mission.render import _add_terrain, _draw

    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(URDF_PATH), useFixedBase=True, physicsClientId=client)
        index = {
            pb.getJointInfo(body, i, physicsClientId=client)[1].decode(): i
            for i in range(pb.getNumJoints(body, physicsClientId=client))
        }
        for name, value in joints.items():
            pb.resetJointState(body, index[name], value, physicsClientId=client)
        _add_terrain(terrain, client)
        return _draw(client, camera, shadow=False)[0]
    finally:
        pb.disconnect(client)


def test_a_picture_without_shadows_is_the_robot_over_its_terrain_by_depth_pixel_for_pixel():
    """Without shadows the robot is drawn alone and laid over the terrain drawn once: the same
    pixels as both drawn together, with the scoop below the surface hidden by it."""
    from ow_description.description import SCOOP_BELOW_GROUND, UNSTOWED
    from ow_mission.render import SceneRenderer

    heights = np.full((60, 60), GROUND_Z)
    heights[25:35, 10:50] -= 0.03  # a trench
    terrain = HeightMap(heights, 0.05, 0.0, -1.5)
    camera = Camera((1.8, 0.0, GROUND_Z), 2.0, 35.0, -35.0, 200, 150)
    # The whole lander: its body and the dock (drawn once per camera) behind and before the arm.
    whole = Camera((0.6, 0.0, 0.0), 3.2, 150.0, -25.0, 200, 150)
    with SceneRenderer() as scene:
        scene.set_terrain(terrain)
        for view in (whole, camera):
            for joints in (dict(UNSTOWED), dict(SCOOP_BELOW_GROUND)):  # the terrain drawn once
                scene.set_joints(joints)
                layered = scene.render(view, shadow=False)
                assert np.array_equal(layered, _drawn_together(joints, terrain, view))
        # The lander's body, hidden in the robot's client for those, is back for a shadowed one.
        shadowed = scene.render(whole, shadow=True)
        with SceneRenderer() as fresh:
            fresh.set_joints(dict(SCOOP_BELOW_GROUND))
            fresh.set_terrain(terrain)
            assert np.array_equal(shadowed, fresh.render(whole, shadow=True))
        scene.set_terrain(None)
        robot_alone = scene.render(camera, shadow=False)
    background = robot_alone[0, 0]
    robot_pixels = np.any(robot_alone != background, axis=2)
    hidden = robot_pixels & np.all(layered != robot_alone, axis=2)
    assert hidden.sum() > 20  # the buried scoop (and what the terrain hides) is not drawn


def _rss_mb() -> float:
    status = Path("/proc/self/status").read_text().splitlines()
    return next(int(line.split()[1]) for line in status if line.startswith("VmRSS:")) / 1024


def test_a_renderer_taking_terrain_after_terrain_does_not_grow():
    """A replay goes through every terrain the mission carved. pybullet keeps a removed
    heightfield's shape and mesh (about 9 MB each at this size) until its client is emptied:
    a replay renderer grew by hundreds of MB before each change emptied it."""
    from ow_mission.render import SceneRenderer

    rng = np.random.default_rng(7)
    camera = Camera((1.8, 0.0, GROUND_Z), 2.5, 35.0, -35.0, 160, 120)
    with SceneRenderer() as scene:
        sizes = []
        for k in range(24):
            heights = GROUND_Z + 0.02 * rng.random((126, 126))
            scene.set_terrain(HeightMap(heights, 0.05, -1.0, -3.0))
            scene.render(camera, shadow=k % 2 == 0)  # both clients take the terrain
            sizes.append(_rss_mb())
    assert sizes[-1] - sizes[3] < 40.0, [round(mb) for mb in sizes]


def test_a_shadowed_picture_after_a_terrain_change_keeps_the_pose():
    """The robot's client is emptied and the robot loaded again when its terrain changes: the
    pose set before comes back with it."""
    from ow_description.description import UNSTOWED
    from ow_mission.render import SceneRenderer

    camera = Camera((1.8, 0.0, GROUND_Z), 2.0, 35.0, -35.0, 200, 150)
    first = HeightMap(np.full((40, 40), GROUND_Z), 0.05, 0.5, -1.0)
    second = HeightMap(np.full((40, 40), GROUND_Z - 0.02), 0.05, 0.5, -1.0)
    with SceneRenderer() as scene:
        scene.set_joints(dict(UNSTOWED))
        scene.set_terrain(first)
        scene.render(camera)
        scene.set_terrain(second)
        again = scene.render(camera)
    with SceneRenderer() as fresh:
        fresh.set_joints(dict(UNSTOWED))
        fresh.set_terrain(second)
        assert np.array_equal(again, fresh.render(camera))


def test_the_detector_is_replayed_from_joint_states_when_not_recorded():
    """A scoop tip descending at 25 mm/s that stops at the ground at t = 14 s: the paper's
    detector replayed on FK of the joint states fires within a few /tf periods of the stop."""
    from ow_description.description import UNSTOWED
    from ow_description.model import LanderModel
    from ow_mission.recording import Recording

    model = LanderModel()
    q = model.q_from(dict(UNSTOWED))
    t = np.arange(10.0, 16.0, 0.01)
    stop_s, speed = 14.0, 0.025
    names = list(model.model.names)[1:]
    rows = []
    for ti in t:
        z = 0.0 - speed * (min(ti, stop_s) - 10.0)
        q = model.ik("l_scoop_tip", [1.65, 0.0, z], q)
        rows.append([q[model.index(name)] for name in names])
    recording = Recording(
        [], t, names, np.vstack(rows), contacts=[(stop_s + 0.1, np.array([1.65, 0.0, -0.1]))]
    )
    trace = detector_trace(recording, 10.0, 16.0, relative_tolerance=0.3)
    assert trace is not None and trace.source == "replayed"
    assert trace.contact_s is not None
    assert stop_s <= trace.contact_s <= stop_s + 0.2
    assert np.nanmax(trace.threshold) == pytest.approx(-speed * 0.7, rel=0.05)
    steady = (trace.t_s > 10.5) & (trace.t_s < 13.5)
    assert np.allclose(trace.signal[steady], -speed, rtol=0.02)


def test_stills_are_planned_after_their_steps_in_order(tmp_path):
    from ow_mission.stills import STILLS, plan_stills

    steps = [
        {"step": "unstow", "sim_end_s": 5.0, "success": True},
        {"step": "guarded_move", "sim_end_s": 12.25, "success": True},
        {"step": "grind", "sim_end_s": 30.0, "success": False},
    ]
    stills = plan_stills(tmp_path, steps)
    assert [(s.role, s.path.name, s.t_s) for s in stills] == [
        ("still_00", "00_guarded_move.png", 12.25),
        ("still_01", "01_grind.png", 30.0),
    ]
    assert stills[0].caption == f"After guarded_move (t = 12.2 s sim): {STILLS['guarded_move']}."
    assert stills[1].caption.endswith("(the step FAILED).")


def test_stills_render_in_their_own_process_and_a_failure_names_what_is_missing(run_dir, tmp_path):
    from ow_mission.stills import Still, StillsRendering

    recording = read_recording(sorted((run_dir / "bags").glob("*.bag")))
    good = Still("still_00", tmp_path / "a" / "00_x.png", 12.0, "")
    done = StillsRendering([good], recording, [(1.6, 0.0, -0.15)]).finish()
    assert done == [good]
    from PIL import Image

    assert Image.open(good.path).size == (1024, 768)
    bad = Still("still_01", tmp_path / "b" / "01_y.png", 12.0, "")
    bad.path.mkdir(parents=True)  # a directory where the file must go: the child fails
    with pytest.raises(RuntimeError, match=r"failed: IsADirectoryError: .*; missing: 01_y.png"):
        StillsRendering([bad], recording, []).finish()


def test_the_stills_and_the_replay_in_one_pool_are_the_same_files_and_leave_it_running(
    run_dir, tmp_path
):
    """The report renders both in two processes; the files are those each makes alone, and
    neither finishing nor cancelling shuts the shared pool down."""
    from ow_mission.replay import render_pool, start_replay
    from ow_mission.stills import Still, StillsRendering

    recording = read_recording(sorted((run_dir / "bags").glob("*.bag")))
    steps = [("unstow", 10.0, 13.0), ("guarded_move", 13.0, 17.0)]
    kwargs = {"max_frames": 6, "width": 160, "height": 120, "workers": 2}
    alone = [Still("still_00", tmp_path / "alone" / "00.png", 12.0, "")]
    shared = [Still("still_00", tmp_path / "shared" / "00.png", 12.0, "")]
    StillsRendering(alone, recording, [(1.6, 0.0, -0.15)]).finish()
    make_replay(recording, steps, tmp_path / "alone.gif", **kwargs)
    with render_pool(2) as pool:
        stills = StillsRendering(shared, recording, [(1.6, 0.0, -0.15)], pool)
        rendering = start_replay(recording, steps, tmp_path / "shared.gif", pool=pool, **kwargs)
        assert stills.finish() == shared
        assert rendering.finish().frames == 6
        start_replay(recording, steps, tmp_path / "c.gif", pool=pool, **kwargs).cancel()
        # One part: the pool's process renders every frame and writes the GIF itself.
        seen: list[tuple[int, int]] = []
        whole = start_replay(
            recording,
            steps,
            tmp_path / "whole.gif",
            pool=pool,
            on_frame=lambda i, n: seen.append((i, n)),
            **{**kwargs, "workers": 1},
        ).finish()
        assert (whole.frames, whole.width) == (6, 160) and whole.cpu_seconds > 0
        assert seen == [(i, 6) for i in range(6)]
        assert pool.submit(sum, [1, 2]).result() == 3  # still open
    assert shared[0].path.read_bytes() == alone[0].path.read_bytes()
    assert (tmp_path / "shared.gif").read_bytes() == (tmp_path / "alone.gif").read_bytes()
    assert (tmp_path / "whole.gif").read_bytes() == (tmp_path / "alone.gif").read_bytes()
    assert not (tmp_path / "c.gif").exists()


def test_the_report_renders_in_its_pool_of_two(tmp_path, monkeypatch):
    """One pool of RENDER_PROCESSES for the stills and the replay's parts, shut down after."""
    pools = []
    make_pool = report_module.render_pool

    def recording_pool(workers):
        pools.append((workers, make_pool(workers)))
        return pools[-1][1]

    monkeypatch.setattr(report_module, "render_pool", recording_pool)
    _write_bags(tmp_path / "bags")
    document = write_run_report(tmp_path, _document(), renders=True)
    assert "replay" in document["figures"] and "still_00" in document["figures"]
    assert [workers for workers, _ in pools] == [report_module.RENDER_PROCESSES] == [2]
    with pytest.raises(RuntimeError, match="after shutdown"):
        pools[0][1].submit(sum, [1])


@pytest.mark.parametrize("collecting", [True, False])
def test_the_report_pauses_the_cyclic_collector_and_leaves_it_as_it_was(
    tmp_path, monkeypatch, collecting
):
    import gc

    seen = []
    original = report_module._report_messages

    def watched(*args, **kwargs):
        seen.append(gc.isenabled())
        return original(*args, **kwargs)

    monkeypatch.setattr(report_module, "_report_messages", watched)
    was = gc.isenabled()
    (gc.enable if collecting else gc.disable)()
    try:
        write_run_report(tmp_path, _document(), renders=False)
        assert seen == [False]
        assert gc.isenabled() is collecting
    finally:
        (gc.enable if was else gc.disable)()


def test_a_render_process_gives_its_free_heap_back():
    """What a closed pybullet client leaves is free heap that plain free() keeps while a later
    block pins the heap's top; release_free_memory returns those pages to the system."""
    import ctypes

    from ow_mission.replay import release_free_memory

    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        pytest.skip("no glibc here")
    libc.malloc.restype = ctypes.c_void_p
    libc.free.argtypes = [ctypes.c_void_p]

    def rss_mb() -> float:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
        raise AssertionError("no VmRSS")

    blocks = [libc.malloc(4096) for _ in range(20_000)]  # ~80 MB, below mmap's threshold
    for block in blocks:
        ctypes.memset(block, 1, 4096)
    for block in blocks[:-1]:
        libc.free(block)
    held = rss_mb()
    release_free_memory()
    assert rss_mb() < held - 50.0
    libc.free(blocks[-1])


# ------------------------------------------------------------------ the delivered sample
#: The budget of a run that scooped twice: m^3 by account, the ingested sample's by layer.
LAYERS = ["irradiated", "pristine"]
MATERIALS = ["ICE", "MG_HYDRATES", "SALT"]


def _account(types, volume: float, by_layer: tuple[float, float]):
    irradiated, pristine = by_layer
    by_material = [0.85 * irradiated + pristine, 0.10 * irradiated, 0.05 * irradiated]
    return types["ow_msgs/msg/RegolithAccount"](
        volume=volume,
        volume_um3=round(volume * 1e18),
        mass=997.0 * by_material[0] + 2660.0 * by_material[1] + 2160.0 * by_material[2],
        layer_volumes=np.array(by_layer),
        material_volumes=np.array(by_material),
    )


def _put_budget(writer, messages, stamp_s, ingested: tuple[float, float]):
    """One /regolith/budget: 1.3e-3 m^3 excavated, what is not ingested deposited."""
    ns = round(stamp_s * 1e9)
    types = messages.store.types
    volume = sum(ingested)
    excavated = 1.3e-3
    accounts = {
        "excavated": _account(types, excavated, (excavated - ingested[1], ingested[1])),
        "in_scoop": _account(types, 0.0, (0.0, 0.0)),
        "in_dock": _account(types, 0.0, (0.0, 0.0)),
        "ingested": _account(types, volume, ingested),
        "spilled": _account(types, 0.0, (0.0, 0.0)),
        "deposited": _account(types, excavated - volume, (excavated - volume, 0.0)),
    }
    ros1_type, md5, msgdef, data = messages.serialize(
        "ow_msgs/msg/RegolithBudget",
        header=messages.header(ns),
        layers=LAYERS,
        top_layer=LAYERS[0],
        materials=MATERIALS,
        **accounts,
    )
    writer.write("/regolith/budget", ros1_type, md5, msgdef, ns, data, latching=True)


def _put_ingested(writer, messages, stamp_s, volume: float, shares: list[float]):
    from rosbags.typesys import get_types_from_msg

    store = messages.store
    if "ow_materials/msg/BulkExcavation" not in store.types:
        root = Path(__file__).resolve().parents[3] / "src" / "ow_materials" / "msg"
        for name in ("MaterialConcentration", "BulkExcavation"):
            text = (root / f"{name}.msg").read_text()
            store.register(get_types_from_msg(text, f"ow_materials/msg/{name}"))
    types = store.types
    ns = round(stamp_s * 1e9)
    composition = [
        types["ow_materials/msg/MaterialConcentration"](id=i, name=name, proportion=share)
        for i, (name, share) in enumerate(zip(MATERIALS, shares, strict=True))
    ]
    ros1_type, md5, msgdef, data = messages.serialize(
        "ow_materials/msg/BulkExcavation",
        header=messages.header(ns),
        volume=volume,
        composition=composition,
    )
    writer.write("/ground_truth/material_ingested", ros1_type, md5, msgdef, ns, data)


def _sample_run(directory: Path, ingested: tuple[float, float]) -> dict:
    """A synthetic run whose last budget ingested ``ingested`` m^3 (irradiated, pristine)."""
    writer = SplitBagWriter(directory / "bags", split_duration_s=4.0)
    messages = BagMessages()
    end = write_run(writer, SEGMENTS, JOINTS, start_s=START_S)
    _put_budget(writer, messages, START_S, (0.0, 0.0))
    _put_budget(writer, messages, end, ingested)
    if sum(ingested) > 0:
        irradiated, pristine = ingested
        total = irradiated + pristine
        shares = [(0.85 * irradiated + pristine) / total, 0.1 * irradiated / total]
        _put_ingested(writer, messages, end, total, [*shares, 0.05 * irradiated / total])
    writer.close()
    document = _document()
    document["ingestion"] = {
        "sample_ingested": sum(ingested) > 0,
        "succeeded": True,
        "message": "Sample ingested" if sum(ingested) > 0 else "No sample was present in dock",
        "sim_time_s": end,
        "wall_time_s": 0.01,
    }
    return write_run_report(directory, document, renders=False, draw=False)


def test_the_report_gives_the_ingested_samples_volume_composition_and_top_layer_share(tmp_path):
    document = _sample_run(tmp_path, (2.0e-4, 6.0e-4))
    sample = document["sample"]
    assert sample["ingested"] is True
    assert sample["volume_m3"] == pytest.approx(8.0e-4)
    assert sample["top_layer"] == "irradiated"
    # the share of the volume from the top layer: layer_volumes[top] / volume
    assert sample["top_layer_share"] == pytest.approx(0.25)
    assert sample["layers"] == pytest.approx({"irradiated": 0.25, "pristine": 0.75})
    assert sample["composition"] == pytest.approx(
        {"ICE": (0.85 * 2e-4 + 6e-4) / 8e-4, "MG_HYDRATES": 0.025, "SALT": 0.0125}
    )
    assert sum(sample["composition"].values()) == pytest.approx(1.0)
    assert sample["budget_m3"]["excavated"] == pytest.approx(1.3e-3)
    assert sample["dock_share"] == pytest.approx(8.0e-4 / 1.3e-3)
    truth = sample["ground_truth"]
    assert truth["volume_m3"] == pytest.approx(8.0e-4)
    assert truth["composition"] == pytest.approx(sample["composition"], abs=1e-6)
    assert json.loads((tmp_path / "report.json").read_text())["sample"] == sample
    text = (tmp_path / "report.md").read_text()
    assert "## Sample" in text
    assert "DockIngestSample after the delivery: Sample ingested." in text
    assert "Ingested **0.0008 m³**" in text
    assert "**25.0 %** of it from the top layer `irradiated`" in text
    assert "61.5 % of the excavated volume reached the dock" in text


def test_a_run_that_ingested_nothing_says_so(tmp_path):
    document = _sample_run(tmp_path, (0.0, 0.0))
    sample = document["sample"]
    assert (sample["ingested"], sample["volume_m3"]) == (False, 0.0)
    assert sample["composition"] is sample["top_layer_share"] is None
    assert sample["ground_truth"] is None
    text = (tmp_path / "report.md").read_text()
    assert "DockIngestSample after the delivery: No sample was present in dock." in text
    assert "No regolith was ingested: the dock held none after the delivery." in text


def test_a_run_without_a_budget_has_no_sample_section_but_a_note(tmp_path):
    writer = SplitBagWriter(tmp_path / "bags", split_duration_s=4.0)
    write_run(writer, SEGMENTS, JOINTS, start_s=START_S)
    writer.close()
    document = write_run_report(tmp_path, _document(), renders=False, draw=False)
    assert document["sample"] is None
    note = document["figure_notes"]["sample"]
    assert note == "no /regolith/budget in the bags: no sample section."
    assert "## Sample" not in (tmp_path / "report.md").read_text()
