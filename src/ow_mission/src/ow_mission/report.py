"""A mission run's report, made from its bags after the run (no ROS).

:func:`write_run_report` takes the run's ``report.json`` document (the steps as the mission ran
them) and its ``bags/``, and writes: ``power.png`` (power with the steps' signed and
absolute-value mechanical energies), ``trench_profile.png`` (terrain before and after along and
across the trench, with the requested depths), ``regolith.png`` (where the excavated regolith is
over the mission: :mod:`ow_mission.regolith_plot`), ``guarded_move.png`` (the ground detector, the
paper's Figure 11), stills in ``renders/`` and ``replay.gif`` (the whole mission, animated),
``battery.png`` and the faults section (:mod:`ow_mission.fault_report`), the delivered sample
(:mod:`ow_mission.sample_report`: volume, composition, top layer's share, the regolith budget), then
``report.md`` linking each figure that exists, and ``report.json`` with the energies from the bags
and the figures' file names. ``python -m ow_mission.report RUN_DIR`` rebuilds them for a run.

The bags are read once for all of it (:func:`read_report_messages`: each file opened, each
message type parsed and each message deserialised once), and the replay's frames are rendered
by two worker processes while this one makes the other figures.
"""

from __future__ import annotations

import functools
import gc
import json
import sys
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ow_bringup.node_config import stack_parameters
from ow_mission.bag_prefetch import BagPrefetch
from ow_mission.recording import Recording, recording_from_messages
from ow_mission.replay import ReplayRendering, render_pool, start_replay
from ow_mission.report_files import Figures, markdown, write_report_files
from ow_mission.sample_report import SAMPLE_TOPICS, sample_section
from ow_mission.stills import StillsRendering, plan_stills
from ow_mission.workspace_capture import capture_figure
from ow_power.bagread import TopicMessages, read_messages
from ow_power.errors import BagReadError
from ow_runtime.names import REGOLITH_BUDGET

if TYPE_CHECKING:
    from ow_mission.mission_config import MissionConfig
    from ow_power.analysis import Analysis


#: Processes rendering the stills and the replay: the stills in one, the replay in the other,
#: which writes its GIF too (its frames never come to this process).
RENDER_PROCESSES = 2


def step_windows(document: Mapping[str, Any]) -> list[tuple[str, float, float]]:
    """(step name, start s, end s) of every step of ``report.json``."""
    return [
        (str(s["step"]), float(s["sim_start_s"]), float(s["sim_end_s"])) for s in document["steps"]
    ]


def trench_points(config: Mapping[str, Any], ground_z: float) -> list[tuple[float, float, float]]:
    """m, base_link: the trench's corners at the ground and below the requested depth, for the
    cameras to frame."""
    from ow_mission.plots import TrenchGeometry

    g = TrenchGeometry.from_config(config)
    bottom = ground_z - float(config["trench_depth"]) - float(config["bottom_grind_depth"])
    points = []
    for along in (-0.1, g.length + 0.1):
        for across in (-0.15, 0.15):
            xy = g.start + g.direction * along + g.normal * across
            for z in (bottom, ground_z + 0.05):
                points.append((float(xy[0]), float(xy[1]), float(z)))
    return points


def framed_trench(document: Mapping[str, Any]) -> list[tuple[float, float, float]]:
    """:func:`trench_points` of ``report.json``'s trench: at the ground the mission found, or
    at the configured one when it found none."""
    config = document["config"]
    ground = document.get("ground_z") or float(config["expected_ground"])
    return trench_points(config, ground)


def _attempt(figures: Figures, role: str, make: Callable[[], str | None]) -> None:
    """Run ``make`` (it returns a note, or None when the figure was written); a figure that
    fails must never cost the user the rest of the report."""
    try:
        note = make()
    except Exception as exc:
        note = f"the {role} figure could not be made: {type(exc).__name__}: {exc}"
        traceback.print_exc(file=sys.stderr)
    if note:
        figures.notes[role] = note


def read_report_messages(bags: Sequence[Path], joint_states: bool = True) -> TopicMessages:
    """Every topic the report uses (:data:`ow_power.analysis.TOPICS`,
    :data:`ow_mission.recording.TOPICS`, :data:`ow_mission.fault_report.TOPICS`,
    :data:`~ow_mission.sample_report.SAMPLE_TOPICS`), read from
    ``bags`` in one pass; with ``joint_states`` False, all but ``/joint_states`` (half the
    messages): what the report's numbers need when ``/power`` and the detector were recorded
    (:func:`write_run_report` with ``draw=False`` reads them when not).

    Raises:
        BagReadError: a bag cannot be read; the message names it.
    """
    from ow_mission import fault_report, live_dem_report, recording
    from ow_power import analysis

    topics = {*analysis.TOPICS, *recording.TOPICS, *fault_report.TOPICS, *SAMPLE_TOPICS}
    topics.update(live_dem_report.TOPICS)  # recorded by live-DEM missions only
    if not joint_states:
        topics.discard(recording.JOINT_STATES_TOPIC)
    return read_messages(bags, topics)


def report_reader(config: MissionConfig) -> Callable[[Sequence[Path]], TopicMessages]:
    """What a mission's :class:`~ow_mission.bag_prefetch.BagPrefetch` reads of its bags for its
    report: with ``figures: after_exit`` the numbers' topics only, without ``/joint_states``
    (half the messages); with ``inline`` everything."""
    if config.figures == "after_exit":
        return functools.partial(read_report_messages, joint_states=False)
    return read_report_messages


def _needs_joint_states(messages: TopicMessages, document: Mapping[str, Any]) -> bool:
    """Whether the report's numbers need ``/joint_states`` that ``messages`` lacks: without
    ``/power`` the power comes from the joint states, and without a recorded detector sample in
    the guarded move's window the detector is replayed on them."""
    from ow_mission.recording import DETECTOR_TOPIC, JOINT_STATES_TOPIC, stamp_s
    from ow_power.analysis import POWER_TOPIC

    if messages.get(JOINT_STATES_TOPIC):
        return False
    if not messages.get(POWER_TOPIC):
        return True
    step = next((s for s in document["steps"] if s["step"] == "guarded_move"), None)
    if step is None:
        return False
    start, end = float(step["sim_start_s"]), float(step["sim_end_s"])
    stamps = (stamp_s(m) for _, m in messages.get(DETECTOR_TOPIC, ()))
    return not any(start <= t <= end for t in stamps)


def energies_from_bags(
    run_dir: Path, document: dict[str, Any], analysis: Analysis, figures: Figures
) -> None:
    """``power.png`` (when ``figures.draw``), and each step's energies and peaks from the bags'
    power ``analysis`` (:func:`ow_power.analysis.analyze_messages`) written into
    ``document['steps']`` (the same numbers the plot labels)."""
    from ow_power.analysis import plot_power, window_labels

    bags = analysis.bags
    windows = step_windows(document)
    if figures.draw:
        labels = plot_power(analysis, run_dir / "power.png", windows=windows)
    else:
        labels = window_labels(analysis, windows)
    for step, label in zip(document["steps"], labels, strict=True):
        window = analysis_window(analysis, label.start_s, label.end_s)
        step.update(
            mechanical_energy_j=label.mechanical_energy_j,
            mechanical_energy_abs_j=label.mechanical_energy_abs_j,
            energy_wh=window["energy_wh"],
            peak_mechanical_power_w=label.peak_power_w,
            peak_power_w=label.peak_total_power_w,
            power_plot_label=label.text,
        )
    document["energy_source"] = f"bags ({analysis.source}), P0 = {analysis.auxiliary_power_w} W"
    document["auxiliary_power_w"] = analysis.auxiliary_power_w
    if not figures.draw:
        return
    figures.files["power"] = "power.png"
    figures.captions["power"] = (
        f"Arm mechanical power over the mission from {len(bags)} bag(s): signed sum tau*omega "
        "(blue) and sum |tau*omega| (red), P0 left out; each step shaded and labelled with its "
        "signed and absolute-value mechanical energy (the table's numbers); dashed: ground contact."
    )


def analysis_window(analysis: Any, start_s: float, end_s: float) -> dict[str, float]:
    """:func:`ow_power.analysis.window_figures` of ``analysis`` over [start_s, end_s]."""
    from ow_power.analysis import window_figures

    return window_figures(analysis.power, start_s, end_s)


def trench_figure(
    run_dir: Path, document: dict[str, Any], recording: Recording, figures: Figures
) -> str | None:
    """``trench_profile.png`` (when ``figures.draw``) and ``document['trench']``; a note when
    it cannot be made."""
    from ow_mission.plots import plot_trench, trench_profile

    if not any(s["step"] == "grind" for s in document["steps"]):
        return "the mission stopped before the grind: no trench to profile."
    if not recording.terrains:
        return "no /sim/terrain in the bags: no trench profile."
    before, after = recording.terrains[0][1], recording.terrains[-1][1]
    profile = trench_profile(before, after, document["config"], document.get("ground_z"))
    document["trench"] = {
        "worked": profile.worked,
        "floor_z": profile.floor_z,
        "deepest_z": profile.deepest_z,
        "ground_z": profile.ground_z,
        "depth_reached_m": profile.depth_reached_m,
        "requested_floor_z": profile.requested_floor_z,
        "requested_bottom_z": profile.requested_bottom_z,
        "verdict": profile.verdict(),
    }
    if not figures.draw:
        return None
    plot_trench(profile, run_dir / "trench_profile.png")
    figures.files["trench_profile"] = "trench_profile.png"
    figures.captions["trench_profile"] = (
        "The trench from the bags: top view of how much the terrain was lowered (last "
        "/sim/terrain minus the first), and the terrain before and after along the trench line "
        "and across its middle, with the requested floor (ground found - trench_depth) and the "
        "bottom grind depth below it."
    )
    return None


def regolith_figure(
    run_dir: Path, document: dict[str, Any], messages: TopicMessages, figures: Figures
) -> str | None:
    """``regolith.png`` (when ``figures.draw``): where the excavated regolith is over the
    mission, from the bags' ``/regolith/budget``; a note when they have none."""
    from ow_mission.regolith_plot import plot_regolith, regolith_series

    budgets = messages.get(REGOLITH_BUDGET, [])
    if not budgets:
        return f"no {REGOLITH_BUDGET} in the bags: no regolith figure."
    if not figures.draw:
        return None
    series = regolith_series(budgets, step_windows(document))
    plot_regolith(series, run_dir / "regolith.png")
    closes = (
        "equals it to the µm³ in every budget: the budget closes"
        if series.unbalanced == 0
        else f"does NOT equal it in {series.unbalanced} of the {len(series.t_s)} budgets"
    )
    figures.files["regolith"] = "regolith.png"
    figures.captions["regolith"] = (
        "Where the regolith the scoop excavated is over the mission, from the bags' "
        f"{REGOLITH_BUDGET} (each budget held until the next), each step shaded: in the scoop, "
        "in the dock, ingested, spilled and deposited stacked in cm³ (1 cm³ = 1e-6 m³), the "
        f"excavated volume dashed (the stack's top {closes}); at the end "
        f"{series.final_cm3('excavated'):.4g} cm³ excavated, "
        f"{series.final_cm3('ingested'):.4g} cm³ ingested."
    )
    if series.layer_shares("excavated") is not None:
        figures.captions["regolith"] += (
            " Right: the share of the ingested sample (when there is one) and of all that was "
            "excavated from each terrain layer, at the end."
        )
    return None


def live_dem_part(
    run_dir: Path, document: dict[str, Any], messages: TopicMessages, figures: Figures
) -> str | None:
    """A ``terrain_forces: yade`` mission's live DEM section (:mod:`ow_mission.live_dem_report`)
    and, when ``figures.draw``, its figure; a note when the bags have no live forces."""
    from ow_mission import live_dem_report

    path = run_dir / live_dem_report.FIGURE if figures.draw else None
    windows = step_windows(document)
    note = live_dem_report.live_dem_section(document, messages, windows, path)
    if path is not None and path.is_file():
        figures.files[live_dem_report.FIGURE_ROLE] = live_dem_report.FIGURE
        figures.captions[live_dem_report.FIGURE_ROLE] = live_dem_report.FIGURE_CAPTION
    return note


def guarded_move_figure(
    run_dir: Path, document: dict[str, Any], recording: Recording, figures: Figures
) -> str | None:
    """``guarded_move.png`` (the paper's Figure 11; when ``figures.draw``) and
    ``document['guarded_move_detector']``; a note when they cannot be made."""
    from ow_mission.plots import detector_trace, plot_guarded_move

    step = next((s for s in document["steps"] if s["step"] == "guarded_move"), None)
    if step is None:
        return "the mission stopped before the guarded move: no detector figure."
    execution = stack_parameters({}, document["config"].get("node_params", {}))["arm_services"][
        "execution"
    ]
    trace = detector_trace(
        recording,
        float(step["sim_start_s"]),
        float(step["sim_end_s"]),
        float(execution["ground_relative_tolerance"]),
    )
    if trace is None:
        return (
            "no /arm/ground_detector in the bags and no ground contact to replay the detector "
            "against: no detector figure."
        )
    source = (
        "recorded on /arm/ground_detector"
        if trace.source == "recorded"
        else "replayed offline (no /arm/ground_detector in the bags): the paper's detector "
        "(ow_lander.execution.ground_detection.GroundDetector) on the scoop tip's z velocity "
        "from forward kinematics of /joint_states at the /tf rate"
    )
    detected = "none" if trace.contact_s is None else f"t = {trace.contact_s:.2f} s"
    result = "none" if trace.result_s is None else f"t = {trace.result_s:.2f} s"
    document["guarded_move_detector"] = {
        "source": trace.source,
        "detector": trace.detector,
        "contact_s": trace.contact_s,
        "result_s": trace.result_s,
    }
    if not figures.draw:
        return None
    plot_guarded_move(trace, run_dir / "guarded_move.png")
    figures.files["guarded_move"] = "guarded_move.png"
    figures.captions["guarded_move"] = (
        f"Guarded move ground detection (the paper's Figure 11), {source}: signal, moving "
        f"average, threshold; detected at {detected} (the arm services' contact on "
        f"/guarded_move_result: {result})."
    )
    return None


def start_stills(
    run_dir: Path,
    document: dict[str, Any],
    recording: Recording,
    pool: ProcessPoolExecutor | None = None,
) -> StillsRendering:
    """Start rendering the stills (1024x768, framed on the whole arm and the trench) at the end
    of the steps of :data:`ow_mission.stills.STILLS`, from the bags, in ``pool`` (None: a
    process of their own); :func:`stills_figure` files them."""
    stills = plan_stills(run_dir / "renders", document["steps"])
    return StillsRendering(stills, recording, framed_trench(document), pool)


def stills_figure(rendering: StillsRendering, figures: Figures) -> str | None:
    """The stills of :func:`start_stills`, once rendered."""
    for still in rendering.finish():
        figures.files[still.role] = f"renders/{still.path.name}"
        figures.captions[still.role] = still.caption
    return None


def start_replay_figure(
    run_dir: Path,
    document: dict[str, Any],
    recording: Recording,
    pool: ProcessPoolExecutor | None = None,
) -> ReplayRendering:
    """Start rendering ``replay.gif`` (the whole mission, from the bags): in one of ``pool``'s
    processes, which writes the GIF too (None: in two processes of its own, the GIF written
    here); :func:`replay_figure` finishes it."""
    return start_replay(
        recording,
        step_windows(document),
        run_dir / "replay.gif",
        around=framed_trench(document),
        title=str(document["config"].get("name", "mission")),
        workers=1 if pool is not None else 2,
        pool=pool,
    )


def replay_figure(
    document: dict[str, Any], rendering: ReplayRendering, figures: Figures
) -> str | None:
    """``replay.gif`` of :func:`start_replay_figure`, once its frames are rendered."""
    result = rendering.finish()
    document["replay"] = {
        "file": "replay.gif",
        "frames": result.frames,
        "fps": result.fps,
        "width": result.width,
        "height": result.height,
        "seconds_to_make": result.seconds,
        "cpu_seconds_to_make": result.cpu_seconds,
        "sim_span_s": result.sim_span_s,
    }
    figures.files["replay"] = "replay.gif"
    figures.captions["replay"] = (
        f"The whole mission replayed from /joint_states and /sim/terrain: {result.frames} frames "
        f"at {result.fps:g} frames/s over {result.sim_span_s:.0f} s of simulated time, "
        f"{result.width}x{result.height} px (made in {result.seconds:.1f} s, "
        f"{result.cpu_seconds:.1f} s of CPU)."
    )
    return None


def faults_section(
    run_dir: Path, document: dict[str, Any], messages: TopicMessages, figures: Figures
) -> str | None:
    """``document['faults']`` (:func:`ow_mission.fault_report.fault_summary`) and
    ``battery.png`` (when ``figures.draw``) from the bags' ``messages`` (none without bags); a
    note when they have no battery data (the section is still made)."""
    from ow_mission.fault_report import (
        RUL_TOPIC,
        SOC_TOPIC,
        fault_recording_from_messages,
        fault_summary,
        plot_battery,
    )

    recording = fault_recording_from_messages(messages)
    document["faults"] = fault_summary(document, recording)
    if not recording.soc and not recording.rul:
        return f"no {SOC_TOPIC} or {RUL_TOPIC} in the bags: no battery figure."
    if not figures.draw:
        return None
    plot_battery(recording, document["faults"], step_windows(document), run_dir / "battery.png")
    figures.files["battery"] = "battery.png"
    figures.captions["battery"] = (
        f"The battery over the mission from the bags: state of charge ({SOC_TOPIC}) and "
        f"remaining useful life ({RUL_TOPIC}, ProgPy's prediction), each step shaded; red "
        "dashed: a scheduled fault applied, orange dotted: a fault bit first set."
    )
    return None


def _report_messages(
    bags: Sequence[Path],
    document: Mapping[str, Any],
    figures: Figures,
    prefetch: BagPrefetch | None = None,
) -> TopicMessages | None:
    """:func:`read_report_messages` of ``bags`` (none without bags; with ``prefetch``, of the
    files it did not read), or None with a note when they cannot be read. For the numbers only
    (``figures.draw`` False), ``/joint_states`` only when they need it
    (:func:`_needs_joint_states`)."""
    if not bags:
        figures.notes["bags"] = "No bag was recorded: no figure could be made."
        return {}
    messages: TopicMessages | None = None

    def read() -> str | None:
        nonlocal messages
        try:
            if prefetch is not None:
                messages = prefetch.messages(bags)
            else:
                messages = read_report_messages(bags, joint_states=figures.draw)
            if not figures.draw and _needs_joint_states(messages, document):
                from ow_mission.recording import JOINT_STATES_TOPIC

                messages.update(read_messages(bags, {JOINT_STATES_TOPIC}))
        except BagReadError as exc:
            return f"the bags could not be read, so no figure was made from them: {exc}"
        return None

    _attempt(figures, "bags", read)
    return messages


def _figures_from_bags(
    run_dir: Path,
    document: dict[str, Any],
    bags: Sequence[Path],
    messages: TopicMessages,
    figures: Figures,
    renders: bool,
) -> None:
    """The power plot, then the figures of the replay's :class:`Recording` and the regolith
    figure (of ``messages``' budgets), in the report's order. The stills and the replay are
    rendered by two forked processes from the start (about 2 and 2.5 CPU-s), alongside the other
    figures: this process collects them at the end.
    ``messages`` loses its ``/joint_states`` and ``/power`` once the recording and the power
    analysis are made from them."""
    recording: Recording | None = None
    analysis: Analysis | None = None
    rendering: ReplayRendering | None = None
    stills: StillsRendering | None = None
    pool: ProcessPoolExecutor | None = None

    def read_recording() -> str | None:
        nonlocal recording
        recording = recording_from_messages(messages, bags, joints=figures.draw)
        return None

    def analyze() -> str | None:
        nonlocal analysis
        from ow_power.analysis import analyze_messages

        analysis = analyze_messages(messages, bags)
        return None

    def start(recording: Recording) -> str | None:
        nonlocal rendering, stills, pool
        # Two processes, not one for the stills and two for the replay: each holds a pybullet
        # client with the robot and the terrain (~65-90 MB), and the report's CPU after the
        # fork is the same on two cores (docs/history/performance-journal.md, eighth round).
        pool = render_pool(RENDER_PROCESSES)
        stills = start_stills(run_dir, document, recording, pool)
        rendering = start_replay_figure(run_dir, document, recording, pool)
        return None

    early = Figures()  # notes of the work started first, filed in the report's order below
    _attempt(early, "bags", read_recording)
    _attempt(figures, "power", analyze)
    # Done with the high-rate topics before the renderers are forked: ~70 MB of the report's
    # peak for the default mission, which the renderers' copies of this process would keep.
    from ow_power.analysis import JOINT_STATES_TOPIC, POWER_TOPIC

    for topic in (JOINT_STATES_TOPIC, POWER_TOPIC):
        messages.pop(topic, None)
    if recording is not None and renders and figures.draw:
        _attempt(early, "replay", functools.partial(start, recording))
    try:
        if analysis is not None:
            power = functools.partial(energies_from_bags, run_dir, document, analysis, figures)
            _attempt(figures, "power", power)
        if recording is None:
            figures.notes.update(early.notes)
            return
        makers: list[tuple[str, Callable[[Figures], str | None]]] = [
            ("trench_profile", functools.partial(trench_figure, run_dir, document, recording)),
            ("regolith", functools.partial(regolith_figure, run_dir, document, messages)),
            ("guarded_move", functools.partial(guarded_move_figure, run_dir, document, recording)),
        ]
        for role, maker in makers:
            _attempt(figures, role, functools.partial(maker, figures))
        if stills is not None:
            _attempt(figures, "stills", functools.partial(stills_figure, stills, figures))
        figures.notes.update(early.notes)
        if rendering is not None:
            finish = functools.partial(replay_figure, document, rendering, figures)
            _attempt(figures, "replay", finish)
    finally:
        if rendering is not None:
            rendering.cancel()
        if stills is not None:
            stills.cancel()
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)


def preload(draw: bool = True) -> None:
    """Import what :func:`write_run_report` imports only when it runs: pandas through
    ``ow_power.analysis`` and the faults' section for the numbers, and with ``draw``
    matplotlib with its Agg backend, the plots, PIL and pybullet for the renders. A mission
    does it on a thread while its stack stops (mostly waiting for the nodes to exit), so that
    the imports leave the report's critical path without adding to the stack's memory during
    the steps. The replay's and the stills' forked processes then have them too. A mission
    whose figures are drawn after it exits does not draw: the drawing's imports (~50 MB, and
    CPU the stopping stack wanted) were the peak of its memory."""
    import ow_mission.fault_report
    import ow_power.analysis  # noqa: F401

    if not draw:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot
    import PIL.Image  # noqa: F401
    import pybullet  # noqa: F401

    import ow_mission.plots
    import ow_mission.regolith_plot
    import ow_mission.render  # noqa: F401


def write_run_report(
    run_dir: Path,
    document: dict[str, Any],
    renders: bool = True,
    prefetch: BagPrefetch | None = None,
    draw: bool = True,
) -> dict[str, Any]:
    """Make the figures from ``run_dir/bags``, then write ``report.json`` and ``report.md``.

    Args:
        run_dir: the run directory.
        document: the mission's ``report.json`` document (steps with their windows, config,
            ground found); completed in place with the bags' energies, the trench verdict and
            ``figures`` (role -> file name relative to ``run_dir``).
        renders: also make the stills and the replay (they take most of the time).
        prefetch: the bag files closed before the run ended, read meanwhile (the mission's
            :class:`~ow_mission.bag_prefetch.BagPrefetch`); None reads every file here.
        draw: False writes the numbers only (energies, trench, detector, faults: the same as
            with the figures) and marks the figures pending (``figures_pending``), for
            :func:`ow_mission.figures.start_figures` to make after the mission. A
            document marked pending is completed: its time goes to ``figures_seconds``.

    Returns:
        ``document`` as written.
    """
    run_dir = Path(run_dir)
    figures = Figures(draw=draw)
    capture_figure(run_dir, document, figures)  # first: the mission took it before any step
    completing = bool(document.pop("figures_pending", False)) and draw
    wall0 = time.monotonic()
    bags = sorted((run_dir / "bags").glob("*.bag"))
    # Python's cyclic collector paused while the bags' messages are held (66 000 objects and
    # their arrays for the default mission): each collection walked all of them, and in the
    # forked renderers it wrote to every page they share with this process. The report took
    # 0.8 s less CPU here, and its peak memory 50 MB less (docs/performance.md).
    collecting = gc.isenabled()
    gc.disable()
    try:
        messages = _report_messages(bags, document, figures, prefetch)
        if messages is not None and bags:
            _figures_from_bags(run_dir, document, bags, messages, figures, renders)
        if messages is not None:
            _attempt(figures, "sample", functools.partial(sample_section, document, messages))
            live_dem = functools.partial(live_dem_part, run_dir, document, messages, figures)
            _attempt(figures, "live_dem", live_dem)
            _attempt(
                figures,
                "battery",
                functools.partial(faults_section, run_dir, document, messages, figures),
            )
    finally:
        if collecting:
            gc.enable()
    document["figures"] = dict(figures.files)
    document["figure_notes"] = dict(figures.notes)
    if not draw:
        document["figures_pending"] = True
    document["figures_seconds" if completing else "report_seconds"] = time.monotonic() - wall0
    write_report_files(run_dir, document, markdown(run_dir, document, figures))
    return document


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m ow_mission.report RUN_DIR [--no-renders]``: rebuild a run's report."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        print("usage: python -m ow_mission.report RUN_DIR [--no-renders]")
        return 0 if args else 2
    run_dir = Path(args[0])
    document = json.loads((run_dir / "report.json").read_text())
    done = write_run_report(run_dir, document, renders="--no-renders" not in args)
    print(json.dumps({"figures": done["figures"], "notes": done["figure_notes"]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
