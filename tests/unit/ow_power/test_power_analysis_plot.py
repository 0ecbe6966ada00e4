"""The power plot: the windows it labels, with the energies of their labels, and labels that do
not overlap; on a synthetic run split into several bags, without ROS."""

from datetime import datetime

import matplotlib
import pytest

from ow_power.analysis import (
    analyze,
    energy_label,
    plot_power,
    stack_labels,
    window_figures,
    window_labels,
)
from ow_power.bagwriter import SplitBagWriter
from ow_power.synthetic import Segment, write_run

matplotlib.use("Agg")

JOINTS = ("j_shou_pitch", "j_prox_pitch")
SEGMENTS = (
    Segment("unstow", 3.0, {"j_shou_pitch": 0.1}, {"j_shou_pitch": 50.0}),  # 5 W
    Segment(  # +2 W and -6 W: net -4 W, |.| 8 W
        "guarded_move",
        4.0,
        {"j_shou_pitch": 0.1, "j_prox_pitch": -0.2},
        {"j_shou_pitch": 20.0, "j_prox_pitch": 30.0},
    ),
)


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    directory = tmp_path_factory.mktemp("bags")
    writer = SplitBagWriter(directory, split_duration_s=2.0, start=datetime(2025, 1, 2, 3, 4, 5))
    write_run(writer, SEGMENTS, JOINTS, start_s=10.0)
    writer.close()
    return analyze([directory])


def test_labels_carry_signed_and_absolute_energy_and_both_peaks(result, tmp_path):
    labels = plot_power(result, tmp_path / "p.png")
    assert (tmp_path / "p.png").is_file()
    assert [label.name for label in labels] == ["unstow", "guarded_move"]
    guarded = labels[1]
    assert guarded.mechanical_energy_j == pytest.approx(-16.0)
    assert guarded.mechanical_energy_abs_j == pytest.approx(32.0)
    assert guarded.peak_power_w == pytest.approx(8.0)  # sum |tau*omega|, no P0
    assert guarded.peak_total_power_w == pytest.approx(-4.0 + 43.0)  # with P0
    assert guarded.text == "guarded_move\n-16.0 J signed\n32.0 J |.|"
    assert guarded.text == energy_label("guarded_move", -16.0, 32.0)


def test_windows_given_by_the_caller_are_labelled_with_their_own_energies(result, tmp_path):
    windows = [("first half", 10.0, 13.0), ("second", 13.0, 17.0), ("tail", 16.5, 17.0)]
    labels = plot_power(result, tmp_path / "p.png", windows=windows)
    assert [(label.name, label.start_s, label.end_s) for label in labels] == windows
    for label in labels:
        figures = window_figures(result.power, label.start_s, label.end_s)
        assert label.mechanical_energy_j == figures["mechanical_energy_j"]
        assert label.mechanical_energy_abs_j == figures["mechanical_energy_abs_j"]


def test_the_labels_without_the_plot_are_the_plots(result, tmp_path):
    """A mission that leaves its figures for later takes its energies from window_labels."""
    windows = [("first half", 10.0, 13.0), ("second", 13.0, 17.0)]
    assert window_labels(result, windows) == plot_power(result, tmp_path / "p.png", windows=windows)
    assert window_labels(result) == plot_power(result, tmp_path / "q.png")
    assert not (tmp_path / "r.png").exists()


def test_the_run_is_read_from_every_split_bag(result):
    assert len(result.bags) == 4  # 7 s in 2 s files


def test_stacked_labels_do_not_overlap():
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3))
    ax.plot([0, 10], [0, 1])
    texts = [
        ax.text(
            x,
            0.99,
            energy_label(f"step_{i}", 1.0, 2.0),
            transform=ax.get_xaxis_transform(),
            ha="center",
            va="top",
            fontsize=7,
        )
        for i, x in enumerate([1.0, 1.3, 1.6, 5.0, 5.2, 9.0])
    ]
    rows = stack_labels(fig, ax, texts)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in texts]
    assert rows >= 2
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not a.overlaps(b)
    # Every label above the data: the line's top (y = 1) is below the lowest label.
    top_of_data = ax.transData.transform((10, 1))[1]
    assert all(box.y0 >= top_of_data for box in boxes)
    plt.close(fig)
