"""OceanWATERS' joint telemetry from joint states: the arrays of ``owl_msgs`` ArmJointPositions,
ArmJointVelocities, ArmJointAccelerations, ArmJointTorques and PanTiltPosition, and the ArmPose
(pose of ``l_scoop`` in ``base_link``), as OceanWATERS' state publisher makes them. No ROS.

Array orders (docs/owl_msgs.md):
* arm telemetry, 7 values: :data:`TELEMETRY_ARM_JOINTS`, the ``/joint_states`` order of
  OceanWATERS (joints sorted by name) without the antenna joints: ``j_dist_pitch, j_grinder,
  j_hand_yaw, j_prox_pitch, j_scoop_yaw, j_shou_pitch, j_shou_yaw``;
* pan/tilt, 2 values: ``j_ant_pan, j_ant_tilt``.

Joint states are read by joint name, never by their order: the index arrays from a message's
names to these orders are built once per distinct name list and reused.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ow_description.description import ANTENNA_JOINTS, ARM_JOINTS, GRINDER_JOINT, SCOOP_LINK
from ow_description.model import LanderModel
from ow_lander.errors import OwLanderError

FloatArray = npt.NDArray[np.float64]
IndexArray = npt.NDArray[np.intp]

#: The 7 joints of the arm telemetry arrays, in their order (sorted by name, as OceanWATERS'
#: alphabetical /joint_states without the antenna joints).
TELEMETRY_ARM_JOINTS: tuple[str, ...] = tuple(sorted((*ARM_JOINTS, GRINDER_JOINT)))
#: The 2 joints of PanTiltPosition, in its order.
PAN_TILT_JOINTS: tuple[str, ...] = ANTENNA_JOINTS
#: The frame of ArmPose: its pose is that of :data:`~ow_description.description.SCOOP_LINK` in it.
ARM_POSE_FRAME = "base_link"


class RateGate:
    """Which joint states the telemetry is published for, decided on their stamps alone (so the
    same joint states give the same telemetry messages whatever the machine's load).

    Args:
        rate_hz: Hz of simulation time; 0 passes every stamp.
    """

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self._last = -math.inf

    def due(self, stamp: float) -> bool:
        """Whether :meth:`passes` would pass ``stamp`` (s), without taking it."""
        return self.rate_hz == 0.0 or self._period(stamp) > self._last

    def passes(self, stamp: float) -> bool:
        """True for the first stamp (s) at or after each multiple of the period (a stamp a
        rounding error below a multiple counts as on it)."""
        if self.rate_hz == 0.0:
            return True
        period = self._period(stamp)
        if period <= self._last:
            return False
        self._last = period
        return True

    def _period(self, stamp: float) -> int:
        return math.floor(stamp * self.rate_hz + 1e-6)


class TelemetryError(OwLanderError):
    """A joint state cannot be turned into telemetry (a joint missing, arrays of other sizes)."""


@dataclass(frozen=True)
class Telemetry:
    """The telemetry of one joint state.

    Attributes:
        stamp: s, the joint state's time.
        positions: (7,) rad, :data:`TELEMETRY_ARM_JOINTS` order.
        velocities: (7,) rad/s, same order (NaN when the joint state had no velocities).
        accelerations: (7,) rad/s^2, same order: the finite difference of the velocities since
            the previous joint state; 0 for the first one, after a stamp that did not increase
            and when velocities are missing.
        torques: (7,) N m, same order: the joint state's efforts (NaN when it had none).
        pan_tilt: (2,) rad, ``j_ant_pan``, ``j_ant_tilt``.
        scoop_position: (3,) m, origin of ``l_scoop`` in ``base_link``.
        scoop_orientation: (4,) unit quaternion (x, y, z, w) of ``l_scoop`` in ``base_link``.
    """

    stamp: float
    positions: FloatArray
    velocities: FloatArray
    accelerations: FloatArray
    torques: FloatArray
    pan_tilt: FloatArray
    scoop_position: FloatArray
    scoop_orientation: FloatArray


class TelemetryBuilder:
    """Turns joint states into :class:`Telemetry`, one per joint state, in stamp order.

    Keeps the previous velocities for the finite difference, and pinocchio data for the forward
    kinematics: not thread-safe, one instance per stream of joint states.

    Args:
        model: the lander model whose kinematics give the arm pose (default: a new one).
    """

    def __init__(self, model: LanderModel | None = None) -> None:
        lander = model or LanderModel()
        self._model = lander.model
        self._data = lander.model.createData()
        self._scoop = lander.frame_id(SCOOP_LINK)
        self._nq = lander.nq
        self._q_index = np.array([lander.index(j) for j in lander.joint_names], dtype=np.intp)
        self._q_joints = lander.joint_names
        self._names: tuple[str, ...] | None = None
        self._arm: IndexArray = np.zeros(0, dtype=np.intp)
        self._pan_tilt: IndexArray = np.zeros(0, dtype=np.intp)
        self._to_q: IndexArray = np.zeros(0, dtype=np.intp)
        self._previous: tuple[float, FloatArray] | None = None

    def reset(self) -> None:
        """Forget the previous joint state: the next accelerations are 0."""
        self._previous = None

    def _index(self, names: Sequence[str]) -> None:
        """Build the index arrays from a joint state's name list to the telemetry orders and to
        pinocchio's ``q``."""
        names = tuple(names)
        position = {name: i for i, name in enumerate(names)}
        missing = [j for j in self._q_joints if j not in position]
        if missing:
            msg = f"joint state lacks joint(s) {missing}; it names {list(names)}"
            raise TelemetryError(msg)
        self._arm = np.array([position[j] for j in TELEMETRY_ARM_JOINTS], dtype=np.intp)
        self._pan_tilt = np.array([position[j] for j in PAN_TILT_JOINTS], dtype=np.intp)
        to_q = np.empty(self._nq, dtype=np.intp)
        to_q[self._q_index] = [position[j] for j in self._q_joints]
        self._to_q = to_q
        self._names = names

    def update(
        self,
        stamp: float,
        names: Sequence[str],
        position: Sequence[float],
        velocity: Sequence[float] = (),
        effort: Sequence[float] = (),
    ) -> Telemetry:
        """The telemetry of one joint state.

        Args:
            stamp: s, the joint state's time.
            names: its joint names (any order; every lander joint must be there).
            position: rad, one per name.
            velocity: rad/s, one per name, or empty (not measured).
            effort: N m, one per name, or empty.

        Returns:
            The telemetry; the accelerations use the previous call's velocities and stamp.

        Raises:
            TelemetryError: a lander joint is missing, or an array's length differs from the
                names' (the state is skipped; the previous one is kept for the difference).
        """
        self._check(names, position, velocity, effort)
        q_all = np.asarray(position, dtype=np.float64)
        arm = self._arm
        if len(velocity):
            velocities = np.asarray(velocity, dtype=np.float64)[arm]
            accelerations = self._difference(stamp, velocities)
        else:
            velocities = np.full(len(arm), np.nan)
            accelerations = np.zeros(len(arm))
            self._previous = None
        torques = (
            np.asarray(effort, dtype=np.float64)[arm] if len(effort) else np.full(len(arm), np.nan)
        )
        pin.forwardKinematics(self._model, self._data, q_all[self._to_q])
        X = pin.updateFramePlacement(self._model, self._data, self._scoop)
        return Telemetry(
            stamp,
            q_all[arm],
            velocities,
            accelerations,
            torques,
            q_all[self._pan_tilt],
            X.translation.copy(),
            pin.Quaternion(X.rotation).coeffs().copy(),
        )

    def skip(
        self,
        stamp: float,
        names: Sequence[str],
        position: Sequence[float],
        velocity: Sequence[float] = (),
        effort: Sequence[float] = (),
    ) -> None:
        """Take a joint state whose telemetry is not wanted: it counts for the next
        accelerations as in :meth:`update`, without the rest of :meth:`update`'s work (a
        publisher at 10 Hz skips nine states in ten).

        Raises:
            TelemetryError: as :meth:`update` (the state is skipped, the previous one kept).
        """
        self._check(names, position, velocity, effort)
        if len(velocity):
            self._previous = (stamp, np.asarray(velocity, dtype=np.float64)[self._arm])
        else:
            self._previous = None

    def _check(
        self,
        names: Sequence[str],
        position: Sequence[float],
        velocity: Sequence[float],
        effort: Sequence[float],
    ) -> None:
        """Index ``names`` if they changed; raise TelemetryError for an array of another length
        (velocity and effort may be empty)."""
        if names != self._names and tuple(names) != self._names:
            self._index(names)
        n = len(names)
        for what, values, optional in (
            ("position", position, False),
            ("velocity", velocity, True),
            ("effort", effort, True),
        ):
            if len(values) != n and not (optional and len(values) == 0):
                msg = f"joint state has {len(values)} {what} values for {n} joints"
                raise TelemetryError(msg)

    def _difference(self, stamp: float, velocities: FloatArray) -> FloatArray:
        """rad/s^2, (v - v_previous) / (t - t_previous); 0 without a previous, earlier state."""
        previous, self._previous = self._previous, (stamp, velocities)
        if previous is None or stamp <= previous[0]:
            return np.zeros(len(velocities))
        return (velocities - previous[1]) / (stamp - previous[0])
