"""Kinematics, dynamics and collision checking of the lander (pinocchio + coal), no ROS.

Conventions (used across the project):
* ``q`` is the full configuration, shape (9,) rad, in *pinocchio's* joint order; never index it
  by position. Use :meth:`LanderModel.q_from` / :meth:`LanderModel.joint_values` to go between
  ``{joint name: angle}`` and ``q``, and :attr:`LanderModel.arm_idx` for the six arm joints.
* ``X_a_b`` is the pose of frame b expressed in frame a, a 4x4 homogeneous matrix; every pose here
  is ``X_base_<frame>`` with ``base_link`` as frame a (REP 103/105).
* Jacobians are "local world aligned": rows (v_x, v_y, v_z, w_x, w_y, w_z) of the frame's origin in
  base_link axes, columns one per joint of ``q``.
* Gravity is Europa's, 1.315 m/s^2 along -z of base_link, unless given.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ow_lander.description import ARM_JOINTS, BASE_FRAME, EUROPA_GRAVITY, URDF_PATH
from ow_lander.errors import IKError, ModelError
from ow_lander.terrain import HeightMap

FloatArray = npt.NDArray[np.float64]

#: IK gives up on a start whose error (m + rad) fell by less than IK_STALL_GAIN (relative) over
#: the last IK_STALL_ITERATIONS iterations: converging starts gain far more (damped least
#: squares converges in 5-20 iterations from a start that leads to a solution).
IK_STALL_ITERATIONS = 5
IK_STALL_GAIN = 0.01

_EYE = {3: np.eye(3), 6: np.eye(6)}

#: Link pairs that never need checking: adjacent or overlapping by design (OceanWATERS SRDF).
DISABLED_COLLISION_PAIRS: frozenset[frozenset[str]] = frozenset(
    frozenset(pair)
    for pair in (
        ("base_link", "l_ant_foot"),
        ("base_link", "l_shou"),
        ("l_ant_foot", "l_ant_panel"),
        ("l_ant_foot", "l_prox"),
        ("l_ant_foot", "l_shou"),
        ("l_dist", "l_prox"),
        ("l_dist", "l_wrist"),
        ("l_hand", "l_scoop"),
        ("l_hand", "l_grinder"),
        ("l_hand", "l_wrist"),
        ("l_prox", "l_shou"),
        ("l_scoop", "l_wrist"),
        ("l_grinder", "l_wrist"),
        # Rigidly attached to each other (both on the lander body).
        ("base_link", "lander_sample_dock0"),
        ("l_ant_panel", "lander_sample_dock0"),
        ("l_ant_foot", "lander_sample_dock0"),
    )
)

#: m, side of the square blocks over which the terrain's highest point is pooled for the per-link
#: bounding-sphere test (a link whose sphere is above the highest point under it is skipped).
TERRAIN_BLOCK_M = 0.25

#: Links of the arm that can hit the terrain, base to tool.
ARM_LINKS: tuple[str, ...] = (
    "l_shou",
    "l_prox",
    "l_dist",
    "l_wrist",
    "l_hand",
    "l_scoop",
    "l_grinder",
)


@dataclass(frozen=True)
class CollisionReport:
    """Why a configuration is (not) valid.

    Attributes:
        pairs: (link, link) pairs in contact, empty when none.
        terrain_link: the link reaching deepest below the terrain, or None.
        terrain_penetration: m, how far that link's lowest sample point is below the terrain
            (<= 0 when no link is below it).
    """

    pairs: tuple[tuple[str, str], ...]
    terrain_link: str | None
    terrain_penetration: float

    @property
    def in_collision(self) -> bool:
        """True when any pair touches or any checked link is below the terrain."""
        return bool(self.pairs) or self.terrain_link is not None

    def describe(self) -> str:
        """A sentence for a person: what touches what."""
        parts = [f"{a} touches {b}" for a, b in self.pairs]
        if self.terrain_link is not None:
            parts.append(
                f"{self.terrain_link} is {self.terrain_penetration * 1000:.0f} mm below the terrain"
            )
        return "; ".join(parts) if parts else "collision-free"


class _LinkSamples(NamedTuple):
    """Terrain sample points of one link: ``points`` (n, 3) m and their bounding sphere
    (``centre`` (3,) m, ``radius`` m), in the frame of ``joint``, the joint moving the link."""

    link: str
    joint: int
    points: FloatArray
    centre: FloatArray
    radius: float


def _sample_points(geometry: coal.CollisionGeometry) -> FloatArray:
    """(n, 3) m, points on a primitive's surface in its own frame, for terrain checks."""
    if isinstance(geometry, coal.Box):
        half = np.asarray(geometry.halfSide)
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        # Corners plus the centres of the four bottom-ish edges in every direction.
        local = np.vstack([signs * half, np.diag(half), -np.diag(half)])
    elif isinstance(geometry, coal.Cylinder):
        angles = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
        rim = np.stack([geometry.radius * np.cos(angles), geometry.radius * np.sin(angles)], axis=1)
        local = np.vstack(
            [
                np.column_stack([rim, np.full(len(rim), z)])
                for z in (-geometry.halfLength, geometry.halfLength)
            ]
        )
    else:  # pragma: no cover - the URDF only uses boxes and cylinders
        msg = f"unsupported collision geometry {type(geometry).__name__}"
        raise ModelError(msg)
    return np.asarray(local, dtype=np.float64)


class TerrainBlocks:
    """The highest terrain point per square block of a height map (max-pooled), for fast
    conservative tests: no bilinear height inside a block exceeds the block's maximum.

    Args:
        terrain: the height map.
        block: m, requested block side (rounded to whole cells).
    """

    def __init__(self, terrain: HeightMap, block: float = TERRAIN_BLOCK_M) -> None:
        self.terrain = terrain
        self.top = float(np.max(terrain.heights))
        self._cells = max(1, round(block / terrain.resolution))
        rows, cols = terrain.shape
        k = self._cells
        # Block (i, j) spans node rows i*k..(i+1)*k and columns j*k..(j+1)*k, both ends included:
        # bilinear heights between cell centres are bounded by the surrounding nodes.
        row_starts = range(0, rows - 1, k)
        col_starts = range(0, cols - 1, k)
        self.maxima = np.array(
            [
                [float(terrain.heights[r : r + k + 1, c : c + k + 1].max()) for c in col_starts]
                for r in row_starts
            ]
        )

    def highest(self, x: float, y: float, radius: float) -> float:
        """m, an upper bound of the terrain height over the square of half-side ``radius`` m
        around (x, y) m (beyond the grid the terrain continues as its edge)."""
        terrain, k = self.terrain, self._cells
        scale = 1.0 / (terrain.resolution * k)
        last_r, last_c = self.maxima.shape[0] - 1, self.maxima.shape[1] - 1
        c0 = min(max(int((x - radius - terrain.origin_x) * scale), 0), last_c)
        c1 = min(max(int((x + radius - terrain.origin_x) * scale), 0), last_c)
        r0 = min(max(int((y - radius - terrain.origin_y) * scale), 0), last_r)
        r1 = min(max(int((y + radius - terrain.origin_y) * scale), 0), last_r)
        return float(self.maxima[r0 : r1 + 1, c0 : c1 + 1].max())


class LanderModel:
    """The lander arm: forward and inverse kinematics, dynamics, and collision checks.

    Not thread-safe: each thread should own its instance (pinocchio data is shared state).

    Args:
        urdf_path: robot description to load (default: the project's lander URDF).
        gravity: m/s^2, magnitude of gravity along -z of base_link.
    """

    def __init__(self, urdf_path: Path = URDF_PATH, gravity: float = EUROPA_GRAVITY) -> None:
        path = Path(urdf_path)
        if not path.is_file():
            msg = f"robot description {path} does not exist"
            raise ModelError(msg)
        self.model = pin.buildModelFromUrdf(str(path))
        self.model.gravity.linear = np.array([0.0, 0.0, -gravity])
        self.data = self.model.createData()
        self.geom_model = pin.buildGeomFromUrdf(self.model, str(path), pin.GeometryType.COLLISION)
        self.joint_names: tuple[str, ...] = tuple(self.model.names)[1:]
        self._q_index = {
            name: self.model.joints[self.model.getJointId(name)].idx_q for name in self.joint_names
        }
        self.arm_idx = np.array([self._q_index[name] for name in ARM_JOINTS], dtype=np.intp)
        self.lower = np.array(self.model.lowerPositionLimit, dtype=np.float64)
        self.upper = np.array(self.model.upperPositionLimit, dtype=np.float64)
        self.velocity_limit = np.array(self.model.velocityLimit, dtype=np.float64)
        self.effort_limit = np.array(self.model.effortLimit, dtype=np.float64)
        self._full_turn = self.upper - self.lower >= 2 * np.pi - 1e-6
        self._geom_link = [
            self.model.frames[g.parentFrame].name for g in self.geom_model.geometryObjects
        ]
        self._setup_collision_pairs()
        self.geom_data = pin.GeometryData(self.geom_model)
        # Axis-aligned boxes before the narrow phase: same answers as computeCollisions over all
        # pairs, ~6x faster for a yes/no query (the planner's validity checks).
        self._broadphase = pin.BroadPhaseManager_NaiveCollisionManager(
            self.model, self.geom_model, self.geom_data
        )
        self._terrain_blocks: TerrainBlocks | None = None
        # Terrain sample points of each link, expressed in the frame of the joint that moves it,
        # and their bounding sphere.
        self._terrain_samples: dict[str, _LinkSamples] = {}
        for link in set(self._geom_link):
            objects = [
                g
                for i, g in enumerate(self.geom_model.geometryObjects)
                if self._geom_link[i] == link
            ]
            points = np.vstack(
                [
                    _sample_points(g.geometry) @ g.placement.rotation.T + g.placement.translation
                    for g in objects
                ]
            )
            centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
            radius = float(np.max(np.linalg.norm(points - centre, axis=1)))
            self._terrain_samples[link] = _LinkSamples(
                link, int(objects[0].parentJoint), points, centre, radius
            )
        self._terrain_link_sets: dict[tuple[str, ...], tuple[_LinkSamples, ...]] = {}

    # ----------------------------------------------------------------- configuration helpers
    @property
    def nq(self) -> int:
        """Number of joints (9)."""
        return int(self.model.nq)

    def index(self, joint: str) -> int:
        """Position of ``joint`` in ``q``.

        Raises:
            ModelError: no joint of that name.
        """
        try:
            return int(self._q_index[joint])
        except KeyError:
            msg = f"unknown joint {joint!r}; the lander's joints are {', '.join(self.joint_names)}"
            raise ModelError(msg) from None

    def q_from(self, values: Mapping[str, float], base: FloatArray | None = None) -> FloatArray:
        """Configuration (9,) rad from ``{joint: angle}``; joints not named keep ``base`` (or 0)."""
        q = np.zeros(self.nq) if base is None else np.array(base, dtype=np.float64)
        for name, value in values.items():
            q[self.index(name)] = value
        return q

    def joint_values(self, q: FloatArray, joints: Iterable[str] | None = None) -> dict[str, float]:
        """``{joint: angle}`` (rad) of ``q`` for ``joints`` (default all)."""
        return {name: float(q[self.index(name)]) for name in (joints or self.joint_names)}

    def within_limits(self, q: FloatArray, tolerance: float = 1e-9) -> bool:
        """True when every joint of ``q`` lies within its URDF limits."""
        return bool(np.all(q >= self.lower - tolerance) and np.all(q <= self.upper + tolerance))

    def limit_violations(self, q: FloatArray, joints: Iterable[str] = ARM_JOINTS) -> list[str]:
        """Human-readable descriptions of the joints of ``q`` outside their limits."""
        out = []
        for name in joints:
            i = self.index(name)
            if not self.lower[i] - 1e-9 <= q[i] <= self.upper[i] + 1e-9:
                out.append(
                    f"{name}={q[i]:.3f} rad is outside [{self.lower[i]:.3f}, {self.upper[i]:.3f}]"
                )
        return out

    def frame_id(self, frame: str) -> int:
        """pinocchio id of ``frame``.

        Raises:
            ModelError: no frame of that name.
        """
        if not self.model.existFrame(frame):
            msg = f"unknown frame {frame!r}"
            raise ModelError(msg)
        return int(self.model.getFrameId(frame))

    # ----------------------------------------------------------------------------- kinematics
    def fk(self, q: FloatArray, frame: str) -> FloatArray:
        """``X_base_frame``: pose (4, 4) of ``frame`` in base_link at configuration ``q``."""
        fid = self.frame_id(frame)
        pin.forwardKinematics(self.model, self.data, q)
        return np.asarray(pin.updateFramePlacement(self.model, self.data, fid).homogeneous)

    def position(self, q: FloatArray, frame: str) -> FloatArray:
        """(3,) m, origin of ``frame`` in base_link."""
        return self.fk(q, frame)[:3, 3].copy()

    def jacobian(self, q: FloatArray, frame: str) -> FloatArray:
        """(6, 9) frame Jacobian of ``frame``'s origin, local-world-aligned (see module doc)."""
        fid = self.frame_id(frame)
        return np.asarray(
            pin.computeFrameJacobian(self.model, self.data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        )

    def ik(
        self,
        frame: str,
        position: FloatArray,
        q0: FloatArray,
        rotation: FloatArray | None = None,
        joints: Iterable[str] = ARM_JOINTS,
        position_tolerance: float = 1e-4,
        rotation_tolerance: float = 1e-3,
        max_iterations: int = 200,
        restarts: int = 40,
        seed: int = 0,
    ) -> FloatArray:
        """Damped-least-squares inverse kinematics for the origin of ``frame``.

        Starts at ``q0`` and, if that fails, from ``restarts`` seeded random configurations
        within the joint limits. Joints not in ``joints`` keep their value from ``q0``.

        Args:
            frame: frame to place, e.g. ``l_scoop_tip`` or ``l_grinder_tip``.
            position: (3,) m, target origin in base_link.
            q0: (9,) rad, initial guess (also the value of the joints not moved).
            rotation: (3, 3) target orientation in base_link, or None for position only.
            joints: joints IK may move.
            position_tolerance: m, accepted position error.
            rotation_tolerance: rad, accepted orientation error.
            max_iterations: iterations per start.
            restarts: random starts tried after ``q0``.
            seed: seed of those random starts (same inputs, same answer).

        Returns:
            (9,) rad configuration within the joint limits reaching the target.

        Raises:
            IKError: no start converged; the message gives the best residual reached.
        """
        target = np.asarray(position, dtype=np.float64)
        if target.shape != (3,) or not np.all(np.isfinite(target)):
            msg = f"IK target position {position} must be 3 finite numbers"
            raise IKError(msg)
        cols = np.array([self.index(j) for j in joints], dtype=np.intp)
        fid = self.frame_id(frame)
        # Random starts are drawn only when needed, in the same order: same seed, same answer.
        rng = np.random.default_rng(seed) if restarts > 0 else None
        best = (np.inf, np.inf)
        for attempt in range(restarts + 1):
            q_start = np.array(q0, dtype=np.float64)
            if attempt > 0 and rng is not None:
                q_start[cols] = rng.uniform(self.lower[cols], self.upper[cols])
            q, pos_err, rot_err = self._dls(
                fid,
                target,
                rotation,
                q_start,
                cols,
                position_tolerance,
                rotation_tolerance,
                max_iterations,
            )
            if pos_err <= position_tolerance and rot_err <= rotation_tolerance:
                return q
            best = min(best, (pos_err, rot_err))
        what = "pose" if rotation is not None else "position"
        msg = (
            f"{frame} cannot reach the {what} "
            f"({target[0]:.3f}, {target[1]:.3f}, {target[2]:.3f}) m in base_link within the "
            f"joint limits: best error {best[0] * 1000:.1f} mm"
            + (f", {best[1]:.3f} rad" if rotation is not None else "")
        )
        raise IKError(msg)

    def _dls(
        self,
        fid: int,
        target: FloatArray,
        rotation: FloatArray | None,
        q: FloatArray,
        cols: npt.NDArray[np.intp],
        position_tolerance: float,
        rotation_tolerance: float,
        max_iterations: int,
    ) -> tuple[FloatArray, float, float]:
        rows = 6 if rotation is not None else 3
        eye = _EYE[rows]
        model, data = self.model, self.data
        lower, upper = self.lower[cols], self.upper[cols]
        pos_err = rot_err = np.inf
        checkpoint = np.inf
        for iteration in range(max_iterations):
            # The Jacobian call also runs the forward kinematics the frame placement needs.
            J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
            X = pin.updateFramePlacement(model, data, fid)
            e = target - X.translation
            pos_err = float(np.sqrt(e @ e))
            rot_err = 0.0
            if rotation is not None:
                w = pin.log3(rotation @ X.rotation.T)
                rot_err = float(np.sqrt(w @ w))
                e = np.concatenate([e, w])
            if pos_err <= position_tolerance and rot_err <= rotation_tolerance:
                break
            if iteration % IK_STALL_ITERATIONS == 0:
                # A start that stopped improving sits in a local minimum (a joint limit, a
                # singularity); it would spend all its iterations there.
                if pos_err + rot_err > (1.0 - IK_STALL_GAIN) * checkpoint:
                    break
                checkpoint = pos_err + rot_err
            J = J[:rows, cols]
            # Levenberg-Marquardt damping: robust far away and near singularities (q = 0 is a
            # wrist singularity), vanishing close to the solution for fast final convergence.
            damping = 1e-6 + 1e-2 * (pos_err * pos_err + rot_err * rot_err)
            dq = J.T @ np.linalg.solve(J @ J.T + damping * eye, e)
            # Bounded steps keep the linearisation honest far from the target.
            step = float(np.abs(dq).max())
            if step > 0.5:
                dq *= 0.5 / step
            q = q.copy()
            moved = q[cols] + dq
            if np.any(moved < lower) or np.any(moved > upper):
                moved = self._into_limits(moved, cols)
            q[cols] = moved
        return q, pos_err, rot_err

    def _into_limits(self, values: FloatArray, cols: npt.NDArray[np.intp]) -> FloatArray:
        """Bring joint values into their limits: wrap joints whose range spans a full turn (they
        are continuous in the original), clip the others."""
        lower, upper = self.lower[cols], self.upper[cols]
        wrapped = lower + np.mod(values - lower, 2 * np.pi)
        return np.where(self._full_turn[cols], wrapped, np.clip(values, lower, upper))

    # ------------------------------------------------------------------------------- dynamics
    def gravity_torques(self, q: FloatArray) -> FloatArray:
        """(9,) N m, joint torques that hold ``q`` against gravity."""
        return np.asarray(pin.computeGeneralizedGravity(self.model, self.data, q)).copy()

    def rnea(self, q: FloatArray, v: FloatArray, a: FloatArray) -> FloatArray:
        """(9,) N m, inverse dynamics: torques giving acceleration ``a`` (rad/s^2) at q, v."""
        return np.asarray(pin.rnea(self.model, self.data, q, v, a)).copy()

    def potential_energy(self, q: FloatArray) -> float:
        """J, gravitational potential energy of the moving links (base_link z = 0 reference)."""
        return float(pin.computePotentialEnergy(self.model, self.data, q))

    # ------------------------------------------------------------------------------ collision
    def _setup_collision_pairs(self) -> None:
        gm = self.geom_model
        objects = gm.geometryObjects
        for i in range(len(objects)):
            for j in range(i + 1, len(objects)):
                a, b = self._geom_link[i], self._geom_link[j]
                same_body = objects[i].parentJoint == objects[j].parentJoint
                if same_body or frozenset((a, b)) in DISABLED_COLLISION_PAIRS:
                    continue
                gm.addCollisionPair(pin.CollisionPair(i, j))

    def collision_report(
        self,
        q: FloatArray,
        terrain: HeightMap | None = None,
        terrain_links: Iterable[str] = ARM_LINKS,
        terrain_margin: float = 0.0,
        stop_at_first: bool = False,
    ) -> CollisionReport:
        """Check ``q`` against self-collision, the lander body, the dock and the terrain.

        Args:
            q: (9,) rad configuration.
            terrain: height map to check against, or None for no terrain.
            terrain_links: links that must stay above the terrain (e.g. leave out the scoop while
                it digs).
            terrain_margin: m, clearance required above the terrain.
            stop_at_first: return at the first contact found (faster, incomplete report).
        """
        pin.updateGeometryPlacements(self.model, self.data, self.geom_model, self.geom_data, q)
        pairs: list[tuple[str, str]] = []
        if pin.computeCollisions(self.geom_model, self.geom_data, stop_at_first):
            for k, result in enumerate(self.geom_data.collisionResults):
                if result.isCollision():
                    cp = self.geom_model.collisionPairs[k]
                    pair = (self._geom_link[cp.first], self._geom_link[cp.second])
                    if pair not in pairs:
                        pairs.append(pair)
                    if stop_at_first:
                        break
        terrain_link: str | None = None
        depth = 0.0
        if terrain is not None and not (stop_at_first and pairs):
            terrain_link, depth = self._terrain_penetration(terrain, terrain_links, terrain_margin)
        return CollisionReport(tuple(pairs), terrain_link, depth)

    def in_collision(
        self,
        q: FloatArray,
        terrain: HeightMap | None = None,
        terrain_links: Iterable[str] = ARM_LINKS,
        terrain_margin: float = 0.0,
    ) -> bool:
        """True when ``q`` collides (see :meth:`collision_report`); stops at the first contact."""
        if pin.computeCollisions(self.model, self.data, self._broadphase, q, True):
            return True
        if terrain is None:
            return False
        hit = self._terrain_penetration(terrain, terrain_links, terrain_margin, first_only=True)
        return hit[0] is not None

    def _terrain_penetration(
        self,
        terrain: HeightMap,
        terrain_links: Iterable[str],
        terrain_margin: float,
        first_only: bool = False,
    ) -> tuple[str | None, float]:
        """(deepest link or None, m below the terrain) at the configuration last placed in
        ``self.data`` (joint placements ``oMi`` must be up to date); with ``first_only`` the
        first link found below the terrain instead of the deepest."""
        # Most configurations are well clear of the ground: a link whose bounding sphere lies
        # above the highest terrain point (of the whole map, then of the blocks under the
        # sphere) is skipped, and heights are interpolated only under the sample points that
        # could be below the terrain.
        blocks = self._blocks(terrain)
        top_everywhere = blocks.top + terrain_margin
        oMi = self.data.oMi
        deepest: str | None = None
        depth = 0.0
        for link, joint, local, centre, radius in self._link_samples(terrain_links):
            placement = oMi[joint]
            world = placement.act(centre)
            lowest = world[2] - radius
            if lowest > top_everywhere:
                continue
            top = blocks.highest(world[0], world[1], radius) + terrain_margin
            if lowest > top:
                continue
            pts = local @ placement.rotation.T + placement.translation
            near = pts[pts[:, 2] < top]
            if near.size == 0:
                continue
            below = float(
                np.max(terrain.height_at(near[:, 0], near[:, 1]) + terrain_margin - near[:, 2])
            )
            if below > depth:
                deepest, depth = link, below
                if first_only:
                    break
        return deepest, depth

    def _link_samples(self, links: Iterable[str]) -> tuple[_LinkSamples, ...]:
        """The sample points of those of ``links`` that have collision geometry (cached)."""
        key = tuple(links)
        found = self._terrain_link_sets.get(key)
        if found is None:
            found = tuple(self._terrain_samples[k] for k in key if k in self._terrain_samples)
            self._terrain_link_sets[key] = found
        return found

    def _blocks(self, terrain: HeightMap) -> TerrainBlocks:
        """The max-pooled blocks of ``terrain`` (cached for the last map seen)."""
        if self._terrain_blocks is None or self._terrain_blocks.terrain is not terrain:
            self._terrain_blocks = TerrainBlocks(terrain)
        return self._terrain_blocks

    def link_names(self) -> list[str]:
        """Names of all links (bodies and frame-only links) in the description."""
        return [f.name for f in self.model.frames if f.type == pin.FrameType.BODY]

    def total_mass(self) -> float:
        """kg, mass of every link including the fixed lander body."""
        return float(sum(inertia.mass for inertia in self.model.inertias))

    def base_frame(self) -> str:
        """Name of the root frame (base_link)."""
        return BASE_FRAME
