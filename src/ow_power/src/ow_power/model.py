"""The paper's power model (section 4, eqs. 1-4), free of ROS.

For the k-th joint state, with torque tau_i(k) (N m, the joint state's ``effort``) and velocity
dtheta_i(k) (rad/s):

* eq. 1, joint power: ``P_i(k) = tau_i(k) * dtheta_i(k)`` (W, signed: negative when the joint
  brakes a load, e.g. lowering the arm under gravity);
* eq. 2, total power: ``P(k) = sum_i P_i(k) + P0`` (W);
* eqs. 3-4, energy: ``E = sum_k P(k) * dt_k`` (J) with ``dt_k = t_k - t_(k-1)`` from the message
  stamps (s of simulation time): the power of a message is held over the interval that ends at
  it, so the first message adds no energy.

Next to them: the absolute-value variant the original OceanWATERS code used,
``sum_i |tau_i * dtheta_i|`` (motors cannot regenerate), and an electrical estimate
``sum_i |tau_i * dtheta_i| / efficiency + P0``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ow_power.config import PowerConfig
from ow_power.errors import PowerError


def joint_power(
    names: Sequence[str],
    velocity: ArrayLike,
    effort: ArrayLike,
    joints: Sequence[str] = (),
) -> tuple[tuple[str, ...], NDArray[np.float64]]:
    """Eq. 1 for the selected joints of one joint state, looked up by name.

    Args:
        names: joint names of the message, in message order.
        velocity: (n,) rad/s, in the order of ``names``.
        effort: (n,) N m, in the order of ``names``.
        joints: joints to return, in this order; empty means all of ``names`` in message order.

    Returns:
        The joint names and their power tau_i * dtheta_i, (m,) W, in the same order.

    Raises:
        PowerError: arrays of different lengths, a requested joint absent, or a non-finite value.
    """
    velocity_arr = np.asarray(velocity, dtype=float)
    effort_arr = np.asarray(effort, dtype=float)
    if not (len(names) == velocity_arr.shape[0] == effort_arr.shape[0]):
        msg = (
            f"joint state has {len(names)} names, {velocity_arr.shape[0]} velocities and "
            f"{effort_arr.shape[0]} efforts; power needs one velocity and one effort per joint"
        )
        raise PowerError(msg)
    if joints:
        index = {name: i for i, name in enumerate(names)}
        missing = [j for j in joints if j not in index]
        if missing:
            msg = f"joint {missing[0]!r} is not in the joint state (it has {list(names)})"
            raise PowerError(msg)
        order = [index[j] for j in joints]
        selected = tuple(joints)
        velocity_arr, effort_arr = velocity_arr[order], effort_arr[order]
    else:
        selected = tuple(names)
    power = effort_arr * velocity_arr
    if not np.all(np.isfinite(power)):
        bad = selected[int(np.flatnonzero(~np.isfinite(power))[0])]
        msg = f"joint {bad!r} has a non-finite velocity or effort"
        raise PowerError(msg)
    return selected, power


def interval_s(previous_s: float, stamp_s: float, max_dt_s: float = math.inf) -> float:
    """The dt_k of eq. 4 between two stamps: ``stamp_s - previous_s``, 0 when that is negative or
    longer than ``max_dt_s`` (s). The rule of :class:`PowerIntegrator`, which takes one stamp at
    a time; :func:`intervals_s` applies it to a series with the same arithmetic."""
    dt = stamp_s - previous_s
    return 0.0 if dt < 0.0 or dt > max_dt_s else dt


def intervals_s(t_s: ArrayLike, max_dt_s: float = math.inf) -> NDArray[np.float64]:
    """The dt_k of eq. 4 for a series of stamps (:func:`interval_s` on each consecutive pair).

    Args:
        t_s: (N,) s, stamps in message order.
        max_dt_s: s, longer intervals (and negative ones) count as 0.

    Returns:
        (N,) s: ``t_k - t_(k-1)``, 0 for the first stamp and for skipped intervals.
    """
    t = np.asarray(t_s, dtype=float)
    dt = np.zeros_like(t)
    if t.size > 1:
        dt[1:] = np.diff(t)
    dt[(dt < 0.0) | (dt > max_dt_s)] = 0.0
    return dt


def integrate_j(t_s: ArrayLike, power_w: ArrayLike, max_dt_s: float = math.inf) -> float:
    """Eq. 4: ``sum_k P(k) * dt_k``, the power of a sample held over the interval ending at it.

    Args:
        t_s: (N,) s, stamps.
        power_w: (N,) W, power at each stamp.
        max_dt_s: s, intervals longer than this are not integrated.

    Returns:
        J, the energy.
    """
    return float(np.sum(np.asarray(power_w, dtype=float) * intervals_s(t_s, max_dt_s)))


@dataclass(frozen=True)
class PowerSample:
    """Power and cumulative energy after one joint state.

    Attributes:
        stamp_s: s, simulation time of the joint state.
        names: joint names, in the order of ``joint_power_w``.
        joint_power_w: (m,) W, eq. 1 per joint.
        mechanical_power_w: W, sum of ``joint_power_w`` (eq. 2 without P0).
        mechanical_power_abs_w: W, sum of the absolute joint powers.
        auxiliary_power_w: W, P0 plus the loads drawn besides the motors (:mod:`ow_power.loads`).
        total_power_w: W, eq. 2 (with ``auxiliary_power_w`` for P0).
        electrical_power_w: W, ``mechanical_power_abs_w / efficiency + auxiliary_power_w``.
        dt_s: s, interval this sample was integrated over (0 for the first sample and after a
            gap longer than ``max_dt_s`` or a stamp that went backwards).
        energy_j: J, cumulative eq. 4 (with P0).
        mechanical_energy_j: J, cumulative mechanical energy.
        mechanical_energy_abs_j: J, cumulative absolute-value variant.
        electrical_energy_j: J, cumulative electrical estimate.
    """

    stamp_s: float
    names: tuple[str, ...]
    joint_power_w: NDArray[np.float64]
    mechanical_power_w: float
    mechanical_power_abs_w: float
    auxiliary_power_w: float
    total_power_w: float
    electrical_power_w: float
    dt_s: float
    energy_j: float
    mechanical_energy_j: float
    mechanical_energy_abs_j: float
    electrical_energy_j: float


class PowerIntegrator:
    """Eqs. 1-4 over a stream of joint states, with the energy accumulated since construction.

    Not thread-safe: feed it from one thread (one subscriber callback).
    """

    def __init__(self, config: PowerConfig) -> None:
        """Start with zero energy.

        Args:
            config: P0, efficiency, joints and the longest interval to integrate.
        """
        self.config = config
        self._last_stamp_s: float | None = None
        self._energy_j = 0.0
        self._mechanical_j = 0.0
        self._mechanical_abs_j = 0.0
        self._electrical_j = 0.0
        #: Intervals not integrated because they were longer than ``max_dt_s`` or negative.
        self.skipped_intervals = 0

    def update(
        self,
        stamp_s: float,
        names: Sequence[str],
        velocity: ArrayLike,
        effort: ArrayLike,
        load_w: float = 0.0,
    ) -> PowerSample:
        """Add one joint state.

        A stamp equal to the previous one adds no energy; an interval longer than ``max_dt_s``
        or a stamp earlier than the previous one (a simulation reset) is skipped and counted in
        :attr:`skipped_intervals`; integration resumes from this stamp.

        Args:
            stamp_s: s, simulation time of the joint state.
            names: joint names of the message.
            velocity: (n,) rad/s.
            effort: (n,) N m.
            load_w: W, loads drawn besides the motors (:mod:`ow_power.loads`), added to P0
                like it and held over the interval like the joints' power.

        Returns:
            The sample's power and the energies accumulated so far.

        Raises:
            PowerError: see :func:`joint_power`; a non-finite stamp. Nothing is accumulated then.
        """
        if not math.isfinite(stamp_s):
            msg = f"joint state stamp {stamp_s} is not finite"
            raise PowerError(msg)
        selected, power = joint_power(names, velocity, effort, self.config.joints)
        mechanical = float(np.sum(power))
        mechanical_abs = float(np.sum(np.abs(power)))
        auxiliary = self.config.auxiliary_power_w + load_w
        total = mechanical + auxiliary
        electrical = mechanical_abs / self.config.motor_efficiency + auxiliary

        dt = 0.0
        if self._last_stamp_s is not None:
            dt = interval_s(self._last_stamp_s, float(stamp_s), self.config.max_dt_s)
            if dt == 0.0 and stamp_s != self._last_stamp_s:
                self.skipped_intervals += 1
        self._last_stamp_s = stamp_s
        self._energy_j += total * dt
        self._mechanical_j += mechanical * dt
        self._mechanical_abs_j += mechanical_abs * dt
        self._electrical_j += electrical * dt
        return PowerSample(
            stamp_s=stamp_s,
            names=selected,
            joint_power_w=power,
            mechanical_power_w=mechanical,
            mechanical_power_abs_w=mechanical_abs,
            auxiliary_power_w=auxiliary,
            total_power_w=total,
            electrical_power_w=electrical,
            dt_s=dt,
            energy_j=self._energy_j,
            mechanical_energy_j=self._mechanical_j,
            mechanical_energy_abs_j=self._mechanical_abs_j,
            electrical_energy_j=self._electrical_j,
        )
