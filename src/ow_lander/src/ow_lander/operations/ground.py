"""The operations that put a tool in the ground (paper section 3): the guarded move, grinding, and
the linear and circular digs. No ROS.

Each ``plan_*`` function takes the :class:`~ow_lander.operations.motions.ArmMotions` to plan with,
the current configuration ``q: (9,) rad`` (pinocchio order), the terrain and the request's values,
and returns an :class:`~ow_lander.operations.operation_plan.OperationPlan` whose segments in the
ground have the speed class :attr:`~ow_description.trajectory.Speed.DIG` (the descent
:attr:`~ow_description.trajectory.Speed.GUARDED`). Points are in base_link, m. Bad requests raise
:class:`~ow_lander.errors.PlanningError` with a message naming the value and the limit.

OceanWATERS' task actions (HEAD) send ``centred: true``: then (x, y) is the centre of the trench
(grind: midway between the two passes; linear dig: the middle of the cut; circular dig: the
lowest point of the sweep, as without it), depths and lengths are not limited (OceanWATERS never
checks them; what cannot be planned fails in planning), and the grinder may turn about its own
axis, as OceanWATERS' grinder joint lets it. Its ArmFindSurface sends the scoop's ``rotation``
for the guarded move.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ow_description.description import (
    ARM_JOINTS,
    GRINDER_LINK,
    GRINDER_TIP_FRAME,
    MAX_GRIND_DEPTH,
    MAX_LENGTH,
    MAX_SCOOP_DEPTH,
    SCOOP_LINK,
    SCOOP_TIP_FRAME,
)
from ow_description.errors import IKError
from ow_description.terrain import HeightMap
from ow_description.trajectory import PathSegment, Speed
from ow_lander.errors import PlanningError
from ow_lander.operations.motions import (
    DOWN,
    TURN_STEP_RAD,
    ArmMotions,
    align,
    angle_between,
    line,
    rz,
    turned,
)
from ow_lander.operations.operation_plan import OperationPlan, check_finite
from ow_lander.operations.registry import OPERATIONS
from ow_lander.operations.workspace import GRIND_PASS_SHIFT, grind_axes
from ow_lander.planning.validity import CheckContext

FloatArray = npt.NDArray[np.float64]

#: m, height above the ground of the tool before it goes down and after it comes up.
APPROACH_HEIGHT = 0.2
#: m, the end of a linear cut over which the scoop curls from its cutting attitude to level
#: (bottom down, mouth up), the tip at the cut's depth: it lifts out holding what it cut.
CURL_LENGTH = 0.05
#: rad, sweep of the circular dig (OceanWATERS: 2 pi / 3 of the distal pitch).
CIRCULAR_SWEEP = 2 * math.pi / 3
#: rad, (shoulder pitch, prox, dist, hand, scoop) of the reference configurations, aimed by the
#: shoulder yaw: OceanWATERS' joint-space pre-configurations, used as tool orientations, IK seeds
#: and via points.
#: Dig linear: scoop yaw pi/2 (OceanWATERS) and the mouth pitched down into the cut by the first
#: of these distal pitches that the arm can hold along the whole cut (OceanWATERS' 40 degree
#: "dig in" attitude cannot be held along a cut at ground level by this arm).
DIG_LINEAR_PITCHES = tuple(math.radians(d) for d in (-30, -45, -15, 0, -60))
GRIND_POSE = (math.pi / 2, -math.pi / 2, 0.0, 4 * math.pi / 3, 0.0)
GUARDED_POSE = (math.pi / 2, -math.pi / 2, 0.0, 0.0, 0.0)
#: Circular dig references: parallel sweeps the distal pitch, perpendicular the hand yaw.
CIRCULAR_PARALLEL_POSE = (math.pi / 2, -math.pi / 2, -19 * math.pi / 54, 0.0, math.pi / 2)
CIRCULAR_PERPENDICULAR_POSE = (math.pi / 2, -math.pi / 2, 0.0, 0.0, 0.0)

#: Request fields are float32: 0.1 arrives as 0.10000000149. Limits are compared with this slack.
FLOAT32_SLACK = 1e-6
#: The joints that place the grinder tip with the grinder free to turn about its axis (its own
#: joint, which OceanWATERS plans with; ours spins it and leaves it out of the arm's plans).
GRINDER_AXIS_JOINTS = (*ARM_JOINTS[:5], "j_grinder")
#: m, how far a guarded descent may end short of its requested end without a note.
DESCENT_SHORTFALL_NOTED = 1e-3


def effective_parameters(operation: str, request: Mapping[str, Any]) -> dict[str, Any]:
    """The request's values, replaced by the operation's defaults
    (:attr:`~ow_lander.operations.registry.OperationSpec.defaults`) when ``use_defaults`` is
    true."""
    values = {k: v for k, v in request.items() if k not in ("use_defaults", "delete_prev_traj")}
    if request.get("use_defaults"):
        values.update(OPERATIONS[operation].defaults)
    return values


def _depth(depth: float, limit: float, tool: str) -> None:
    if depth < 0:
        msg = f"depth={depth:.3f} m must not be negative (it is measured down from the ground)"
        raise PlanningError(msg)
    if depth > limit + FLOAT32_SLACK:
        msg = f"depth={depth:.3f} m is deeper than the {tool} can go (max {limit:.2f} m)"
        raise PlanningError(msg)


def _length(length: float) -> None:
    if not 0 < length <= MAX_LENGTH + FLOAT32_SLACK:
        msg = f"length={length:.3f} m must be in (0, {MAX_LENGTH}] m"
        raise PlanningError(msg)


def plan_guarded_move(
    m: ArmMotions, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
) -> OperationPlan:
    """Approach: the scoop tip to (x, y, z), its bottom turned against ``direction``; then
    the guarded descent: a straight line of ``search_distance`` along -direction.

    The scoop's orientation is ``rotation`` ((3, 3), base_link) when the request has one and the
    arm can take it there, else the arm's aimed one with its bottom turned against
    ``direction`` (noted). The descent goes as deep as the arm can without the rest of it
    touching the terrain (noted when that is short of ``search_distance``)."""
    p = effective_parameters("guarded_move", request)
    check_finite(p, "x", "y", "z", "direction_x", "direction_y", "direction_z", "search_distance")
    normal = np.array([p["direction_x"], p["direction_y"], p["direction_z"]], dtype=float)
    if np.linalg.norm(normal) < 1e-6:
        msg = "direction=(0, 0, 0) is a zero vector; give the surface normal, e.g. (0, 0, 1)"
        raise PlanningError(msg)
    normal /= np.linalg.norm(normal)
    if p["search_distance"] <= 0:
        msg = f"search_distance={p['search_distance']:.3f} m must be > 0"
        raise PlanningError(msg)
    target = np.array([p["x"], p["y"], p["z"]], dtype=float)
    yaw = m.yaw(p["x"], p["y"])
    start = m.start(q, terrain)
    ctx = m.context(q, terrain)
    reference = m.reference(yaw, GUARDED_POSE)
    aimed = align(m.rotation(reference, q, SCOOP_TIP_FRAME), 2, -normal)
    notes = []
    if "rotation" in p:
        asked = np.asarray(p["rotation"], dtype=np.float64)
        try:
            R0, goal = asked, m.planner.solve_ik(SCOOP_TIP_FRAME, target, asked, reference, ctx)
        except PlanningError as error:
            R0, goal = aimed, m.planner.solve_ik(SCOOP_TIP_FRAME, target, aimed, reference, ctx)
            notes.append(
                f"the scoop is turned about the normal from the orientation asked ({error})"
            )
    else:
        R0, goal = aimed, m.planner.solve_ik(SCOOP_TIP_FRAME, target, aimed, reference, ctx)
    approach = m.approach(start, goal, reference, ctx)
    dig = m.context(q, terrain, SCOOP_LINK)
    end = target - normal * float(p["search_distance"])
    descent = m.cartesian(approach[-1], SCOOP_TIP_FRAME, end, lambda _: R0, dig, partial=True)
    shortfall = float(np.linalg.norm(m.position(descent[-1], q, SCOOP_TIP_FRAME) - end))
    if shortfall > DESCENT_SHORTFALL_NOTED:
        notes.append(
            f"the descent ends {shortfall:.3f} m short of its end: deeper, the arm would touch "
            "the terrain or leave its reach"
        )
    segments = [
        PathSegment("approach", approach),
        PathSegment("guarded", descent, Speed.GUARDED),
    ]
    return OperationPlan("guarded_move", segments, p, notes)


def plan_grind(
    m: ArmMotions, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
) -> OperationPlan:
    """Two grinder passes of ``length`` at ``depth`` below the ground, grinder vertical,
    the first from (x, y) (``centred``: the passes' centre is (x, y), see
    :func:`_grind_centred`)."""
    p = effective_parameters("grind", request)
    check_finite(p, "x", "y", "depth", "length", "ground_position")
    centred = bool(p.get("centred"))
    if not centred:
        _depth(p["depth"], MAX_GRIND_DEPTH, "grinder")
        _length(p["length"])
    x, y, ground = float(p["x"]), float(p["y"]), float(p["ground_position"])
    yaw = m.yaw(x, y)
    along, beside = grind_axes(yaw, bool(p["parallel"]))
    direction = np.array([*along, 0.0])
    shift = np.array([*beside, 0.0])
    length = float(p["length"])
    first = np.array([x, y, ground - float(p["depth"])])
    if centred:
        first = first - direction * length / 2 - shift * GRIND_PASS_SHIFT / 2
    corners = [
        first,
        first + direction * length,
        first + direction * length + shift * GRIND_PASS_SHIFT,
        first + shift * GRIND_PASS_SHIFT,
    ]
    for corner in corners if centred else corners[1:3]:
        m.yaw(*corner[:2])
    reference = m.reference(yaw, GRIND_POSE)
    rise = APPROACH_HEIGHT + float(p["depth"])
    if centred:
        return OperationPlan("grind", _grind_centred(m, q, terrain, reference, corners, rise), p)
    start = m.start(q, terrain)
    R0 = m.rotation(reference, q, GRINDER_TIP_FRAME)

    def vertical(point: FloatArray) -> FloatArray:
        return rz(m.yaw(point[0], point[1]) - yaw) @ R0

    above = corners[0] + [0.0, 0.0, rise]
    ctx = m.context(q, terrain)
    dig = m.context(q, terrain, GRINDER_LINK)
    goal = m.planner.solve_ik(GRINDER_TIP_FRAME, above, R0, reference, ctx)
    segments = [PathSegment("approach", m.approach(start, goal, reference, ctx))]
    arm = segments[0].waypoints[-1]
    labels = ("descend", "pass_1", "shift", "pass_2")
    for label, corner in zip(labels, corners, strict=True):
        path = m.cartesian(arm, GRINDER_TIP_FRAME, corner, vertical, dig)
        segments.append(PathSegment(label, path, Speed.DIG))
        arm = path[-1]
    exit_point = corners[3] + [0.0, 0.0, rise]
    path = m.cartesian(arm, GRINDER_TIP_FRAME, exit_point, vertical, dig)
    segments.append(PathSegment("retract", path))
    return OperationPlan("grind", segments, p)


def _grind_centred(
    m: ArmMotions,
    q: FloatArray,
    terrain: HeightMap | None,
    reference: FloatArray,
    corners: list[FloatArray],
    rise: float,
) -> list[PathSegment]:
    """OceanWATERS' grind (the passes between ``corners`` (3,) m): the grinder vertical and
    free to turn about its axis (OceanWATERS plans it with the grinder joint), placed at the
    first corner on the branch of ``reference`` (6,) rad; it goes down to it and up from the
    last corner straight along z, from and to ``rise`` m above them or as high as the arm
    reaches on that branch (close to the lander, less high: OceanWATERS changes branch on
    the way down, which a straight line cannot)."""
    start = m.start(q, terrain)
    R_axis = m.rotation(reference, q, GRINDER_TIP_FRAME)
    ctx = m.context(q, terrain)
    dig = m.context(q, terrain, GRINDER_LINK)
    R_first = _grinder_rotations(m, q, reference, [corners[0]], R_axis)[0]
    down = m.planner.solve_ik(GRINDER_TIP_FRAME, corners[0], R_first, reference, dig)
    descend = _grinder_rise(m, q, down, rise, R_axis, dig)[::-1]
    approach = m.approach(start, descend[0], reference, ctx)
    # The approach may end a whole turn of the hand yaw away from the descent's top (the same
    # pose): the descent turns with it.
    turn = approach[-1] - descend[0]
    if not np.allclose(turn, 0.0):
        descend = descend + turn
        blocked = m.planner.first_invalid(descend, dig)
        if blocked is not None:
            msg = f"the grinder's descent is blocked: {m.planner.explain(blocked, dig)}"
            raise PlanningError(msg)
    segments = [PathSegment("approach", approach), PathSegment("descend", descend, Speed.DIG)]
    arm = descend[-1]
    for label, corner in zip(("pass_1", "shift", "pass_2"), corners[1:], strict=True):
        points = line(m.position(arm, q, GRINDER_TIP_FRAME), corner, _step(m))
        rotations = _grinder_rotations(m, q, arm, points, R_axis)
        path = m.planner.plan_cartesian(arm, GRINDER_TIP_FRAME, points, rotations, dig)
        segments.append(PathSegment(label, path, Speed.DIG))
        arm = path[-1]
    retract = _grinder_rise(m, q, arm, rise, R_axis, dig)
    if len(retract) > 1:
        segments.append(PathSegment("retract", retract))
    # Where the rise stops short, still in or at the terrain: on out of it as any operation
    # that starts there does.
    lift = m.lift_off(m.planner.full(retract[-1], q), terrain)
    if lift is not None:
        segments.append(PathSegment("lift_off", lift))
    return segments


def _step(m: ArmMotions) -> float:
    return float(m.planner.config.cartesian_step_m)


def _grinder_rise(
    m: ArmMotions,
    q: FloatArray,
    arm: FloatArray,
    rise: float,
    R_axis: FloatArray,
    ctx: CheckContext,
) -> FloatArray:
    """(n, 6) rad: the grinder tip straight up from where it is at ``arm`` (6,) rad, by
    ``rise`` m or as far as the arm goes on its branch (free about the grinder's axis); just
    ``arm`` when it cannot go up at all."""
    here = m.position(arm, q, GRINDER_TIP_FRAME)
    points = line(here, here + np.array([0.0, 0.0, rise]), _step(m))
    rotations = _grinder_rotations(m, q, arm, points, R_axis, partial=True)
    if not rotations:
        return np.array([arm])
    reached = points[: len(rotations)]
    try:
        return m.planner.plan_cartesian(
            arm, GRINDER_TIP_FRAME, reached, rotations, ctx, partial=True
        )
    except PlanningError:  # not even its first step
        return np.array([arm])


def _grinder_rotations(
    m: ArmMotions,
    q: FloatArray,
    arm: FloatArray,
    points: list[FloatArray],
    R_axis: FloatArray,
    partial: bool = False,
) -> list[FloatArray]:
    """(3, 3) each, base_link: the grinder tip's orientation at each of ``points`` with its
    axis (the tip's x) along ``R_axis``'s, turned about the axis as the arm reaches it from
    ``arm`` (6,) rad, each point seeded by the previous (the grinder joint turns it freely).
    With ``partial``, those of the points up to the first the arm cannot reach.

    Raises:
        PlanningError: a point the grinder tip cannot reach with its axis so (not partial).
    """
    model = m.model
    grinder = model.index("j_grinder")
    current = m.planner.full(arm, q)
    rotations = []
    for point in points:
        try:
            solved = model.ik(
                GRINDER_TIP_FRAME, point, current, R_axis, GRINDER_AXIS_JOINTS, restarts=0
            )
        except IKError as error:
            if partial:
                break
            raise PlanningError(str(error)) from error
        solved[grinder] = q[grinder]
        rotations.append(model.fk(solved, GRINDER_TIP_FRAME)[:3, :3])
        current = solved
    return rotations


def plan_dig_linear(
    m: ArmMotions, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
) -> OperationPlan:
    """Rasping cut: the scoop dips in to ``depth``, cuts ``length`` radially from (x, y)
    (``centred``: through (x, y), its middle), lifts out."""
    p = effective_parameters("dig_linear", request)
    check_finite(p, "x", "y", "depth", "length", "ground_position")
    centred = bool(p.get("centred"))
    if not centred:
        _depth(p["depth"], MAX_SCOOP_DEPTH, "scoop")
        _length(p["length"])
    x, y, ground = float(p["x"]), float(p["y"]), float(p["ground_position"])
    yaw = m.yaw(x, y)
    heading = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    bottom = ground - float(p["depth"])
    cut_start = np.array([x, y, bottom])
    if centred:
        cut_start -= heading * float(p["length"]) / 2
        m.yaw(*cut_start[:2])
    cut_end = cut_start + heading * p["length"]
    m.yaw(*cut_end[:2])
    start = m.start(q, terrain)
    errors = []
    for pitch in DIG_LINEAR_PITCHES:
        reference = m.reference(yaw, (math.pi / 2, -math.pi / 2, pitch, 0.0, math.pi / 2))
        try:
            segments = _linear_cut(m, q, terrain, start, reference, cut_start, cut_end, ground)
        except PlanningError as error:
            errors.append(str(error))
            continue
        p["scoop_pitch_deg"] = round(math.degrees(pitch))
        return OperationPlan("dig_linear", segments, p)
    msg = f"no scoop attitude can make this cut; with the preferred one: {errors[0]}"
    raise PlanningError(msg)


def _linear_cut(
    m: ArmMotions,
    q: FloatArray,
    terrain: HeightMap | None,
    start: FloatArray,
    reference: FloatArray,
    cut_start: FloatArray,
    cut_end: FloatArray,
    ground: float,
) -> list[PathSegment]:
    """Approach, lower and dip in with the scoop attitude of ``reference`` (turned with the
    shoulder yaw); cut, curling the scoop level over the cut's last ``CURL_LENGTH`` (the tip at
    the cut's depth); lift out and retract with the scoop level: it leaves the trench with
    what it cut (:func:`_curl`)."""
    yaw = float(reference[0])
    heading = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    R0 = m.rotation(reference, q, SCOOP_TIP_FRAME)
    R_level = align(R0, 2, DOWN)

    def cutting(point: FloatArray) -> FloatArray:
        return rz(m.yaw(point[0], point[1]) - yaw) @ R0

    def level(point: FloatArray) -> FloatArray:
        return rz(m.yaw(point[0], point[1]) - yaw) @ R_level

    # Dip in and lift out at 45 degrees between 5 cm above the ground and the cut's depth.
    rise = ground + 0.05 - float(cut_start[2])
    entry = cut_start - heading * rise + [0.0, 0.0, rise]
    above = entry + np.array([0.0, 0.0, APPROACH_HEIGHT - 0.05])
    out = cut_end + heading * rise + [0.0, 0.0, rise]
    ctx = m.context(q, terrain)
    dig = m.context(q, terrain, SCOOP_LINK)
    goal = m.planner.solve_ik(SCOOP_TIP_FRAME, above, R0, reference, ctx)
    segments = [PathSegment("approach", m.approach(start, goal, reference, ctx))]
    arm = segments[0].waypoints[-1]
    for label, point in (("lower", entry), ("dip_in", cut_start)):
        path = m.cartesian(arm, SCOOP_TIP_FRAME, point, cutting, dig if label == "dip_in" else ctx)
        segments.append(PathSegment(label, path, Speed.FREE if label == "lower" else Speed.DIG))
        arm = path[-1]
    length = float(np.linalg.norm(cut_end - cut_start))
    curl_start = cut_end - (cut_end - cut_start) * min(1.0, CURL_LENGTH / length)
    cut = [arm[None, :]]
    if length > CURL_LENGTH:
        cut.append(m.cartesian(arm, SCOOP_TIP_FRAME, curl_start, cutting, dig)[1:])
    cut.append(_curl(m, cut[-1][-1], curl_start, cut_end, cutting, level, dig)[1:])
    segments.append(PathSegment("cut", np.vstack(cut), Speed.DIG))
    arm = segments[-1].waypoints[-1]
    steps = (
        ("lift_out", out, Speed.DIG),
        ("retract", out + np.array([0.0, 0.0, APPROACH_HEIGHT - 0.05]), Speed.FREE),
    )
    for label, point, speed in steps:
        path = m.cartesian(arm, SCOOP_TIP_FRAME, point, level, dig)
        segments.append(PathSegment(label, path, speed))
        arm = path[-1]
    return segments


def _curl(
    m: ArmMotions,
    arm: FloatArray,
    start: FloatArray,
    end: FloatArray,
    cutting: Callable[[FloatArray], FloatArray],
    level: Callable[[FloatArray], FloatArray],
    ctx: CheckContext,
) -> FloatArray:
    """(n, 6) rad from ``arm``: the scoop tip along the straight line from ``start`` to
    ``end`` (3,) m while the scoop turns evenly from its ``cutting`` orientation to ``level``
    (each a function of the tip's position), at most ``TURN_STEP_RAD`` per waypoint.

    The simulation keeps a scoop's fill while it digs, whatever its attitude, and spills what
    lies above its lip as soon as the dig ends (docs/regolith.md): a scoop leaving the trench at
    its cutting attitude (its lip tilted ~32 degrees) loses half of a full load there. Curled
    level while still cutting forward (mouth first, so the dig goes on), it keeps the load.
    """
    turn = angle_between(cutting(start), level(end))
    n = max(1, math.ceil(float(np.linalg.norm(end - start)) / _step(m) - 1e-9))
    n = max(n, math.ceil(turn / TURN_STEP_RAD - 1e-9))
    points = [start + (end - start) * (i / n) for i in range(1, n + 1)]
    rotations = [turned(cutting(p), level(p), i / n) for i, p in enumerate(points, start=1)]
    return m.planner.plan_cartesian(arm, SCOOP_TIP_FRAME, points, rotations, ctx)


def plan_dig_circular(
    m: ArmMotions, q: FloatArray, terrain: HeightMap | None, request: Mapping[str, Any]
) -> OperationPlan:
    """A 120 degree scoop sweep whose lowest point is at (x, y, ground - depth): about the
    wrist (distal pitch) when parallel, about the hand (hand yaw) when perpendicular."""
    p = effective_parameters("dig_circular", request)
    check_finite(p, "x", "y", "depth", "ground_position")
    if not p.get("centred"):
        _depth(p["depth"], MAX_SCOOP_DEPTH, "scoop")
    x, y, ground = float(p["x"]), float(p["y"]), float(p["ground_position"])
    yaw = m.yaw(x, y)
    parallel = bool(p["parallel"])
    joint = ARM_JOINTS.index("j_dist_pitch" if parallel else "j_hand_yaw")
    reference = m.reference(
        yaw, CIRCULAR_PARALLEL_POSE if parallel else CIRCULAR_PERPENDICULAR_POSE
    )
    # Centre the sweep on the scoop tip's lowest point, turning the way its mouth faces.
    angles = np.linspace(-math.pi, math.pi, 361)
    lowest, sign = _lowest(m, reference, q, joint, angles)
    reference[joint] += lowest - sign * CIRCULAR_SWEEP / 2
    reference_aimed = reference.copy()
    target = np.array([x, y, ground - float(p["depth"])])
    start = m.start(q, terrain)
    ctx = m.context(q, terrain)
    dig = m.context(q, terrain, SCOOP_LINK)
    sweep = sign * np.linspace(0.0, CIRCULAR_SWEEP, 121)
    R_hand = m.rotation(reference, q, "l_hand")
    hand = m.position(reference, q, "l_hand")
    arm = reference
    for _ in range(4):
        tips = []
        for a in sweep:
            swept = arm.copy()
            swept[joint] += a
            tips.append(m.position(swept, q, SCOOP_TIP_FRAME))
        deepest = min(tips, key=lambda t: t[2])
        error = target - deepest
        if np.linalg.norm(error) < 5e-4:
            break
        hand = hand + error
        R = rz(m.yaw(hand[0], hand[1]) - yaw) @ R_hand
        arm = m.planner.solve_ik("l_hand", hand, R, arm, ctx)
    else:
        msg = f"cannot place the sweep's lowest point at ({x:.3f}, {y:.3f}, {target[2]:.3f}) m"
        raise PlanningError(msg)
    approach = m.approach(start, arm, reference_aimed, ctx)
    arm = approach[-1]
    end = arm.copy()
    end[joint] += sweep[-1]
    swept = m.planner.plan_joint_sweep(arm, end, dig)
    segments = [PathSegment("approach", approach), PathSegment("sweep", swept, Speed.DIG)]
    return OperationPlan("dig_circular", segments, p)


def _lowest(
    m: ArmMotions, reference: FloatArray, q: FloatArray, joint: int, angles: FloatArray
) -> tuple[float, float]:
    """(offset of ``joint`` putting the scoop tip lowest, direction of turning that moves
    the tip the way the scoop's mouth faces there)."""
    best = (np.inf, 0.0)
    for a in angles:
        arm = reference.copy()
        arm[joint] += a
        best = min(best, (float(m.position(arm, q, SCOOP_TIP_FRAME)[2]), float(a)))
    arm = reference.copy()
    arm[joint] += best[1]
    ahead = arm.copy()
    ahead[joint] += 1e-3
    velocity = m.position(ahead, q, SCOOP_TIP_FRAME) - m.position(arm, q, SCOOP_TIP_FRAME)
    mouth = m.rotation(arm, q, SCOOP_TIP_FRAME)[:, 0]
    return best[1], 1.0 if float(velocity @ mouth) >= 0 else -1.0
