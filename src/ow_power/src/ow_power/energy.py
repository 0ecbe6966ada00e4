"""Energy integration and the arm's work-energy balance, free of ROS.

The balance checks the power model against the simulation: over a motion from t0 to t1, the work
the joint motors did, ``W = sum_k sum_i tau_i(k) * dtheta_i(k) * dt_k``, equals the rise of the
arm's potential and kinetic energy plus what the joint damping and Coulomb friction dissipated,
``sum_k sum_i (d_i * dtheta_i(k)**2 + f_i * |dtheta_i(k)|) * dt_k`` (plus any work done on the
terrain, zero in free space). The energies come from the workspace's one model of the lander,
:class:`ow_description.model.LanderModel` (pinocchio, from the URDF), the one the arm services use.

Gravity is Europa's (``ow_description.description.EUROPA_GRAVITY``, as in the simulation) unless
given: pinocchio's default is the Earth's 9.81 m/s^2, which would overstate every potential-energy
change 7.5 times. Where the
simulation publishes the damping torque it applied (``/sim/joint_damping``), pass it as
``damping_effort``: the losses are then ``-sum damping_effort * dtheta * dt`` exactly, rather than
the URDF's ``d * dtheta**2`` (the simulation's implicit damper gives a smaller torque on the light
wrist joints at speed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ow_description.description import EUROPA_GRAVITY, URDF_PATH
from ow_power.errors import PowerError
from ow_power.model import integrate_j

if TYPE_CHECKING:
    from ow_description.model import LanderModel


def dissipated_work_j(
    t_s: ArrayLike,
    velocity: ArrayLike,
    damping: ArrayLike,
    friction: ArrayLike | None = None,
    max_dt_s: float = math.inf,
) -> float:
    """Work turned into heat by viscous damping and Coulomb friction in the joints.

    Args:
        t_s: (N,) s, stamps.
        velocity: (N, n) rad/s, joint velocities.
        damping: (n,) N m s/rad, viscous damping per joint.
        friction: (n,) N m, Coulomb friction torque per joint (default none).
        max_dt_s: s, intervals longer than this are not integrated.

    Returns:
        J, ``sum_k sum_i (d_i * w_i**2 + f_i * |w_i|) * dt_k`` (never negative).
    """
    w = np.atleast_2d(np.asarray(velocity, dtype=float))
    loss_w = w**2 @ np.asarray(damping, dtype=float)
    if friction is not None:
        loss_w = loss_w + np.abs(w) @ np.asarray(friction, dtype=float)
    return integrate_j(t_s, loss_w, max_dt_s)


@dataclass(frozen=True)
class EnergyBalance:
    """Work done by the joints against where it went, over one motion.

    Attributes:
        work_j: J, mechanical energy the motors delivered (signed, eq. 4 without P0).
        potential_rise_j: J, potential energy at the end minus at the start.
        kinetic_rise_j: J, kinetic energy at the end minus at the start.
        dissipated_j: J, damping and friction losses.
    """

    work_j: float
    potential_rise_j: float
    kinetic_rise_j: float
    dissipated_j: float

    @property
    def accounted_j(self) -> float:
        """J, potential + kinetic rise + dissipated: what the work should equal."""
        return self.potential_rise_j + self.kinetic_rise_j + self.dissipated_j

    @property
    def relative_error(self) -> float:
        """``|work - accounted| / |accounted|`` (inf when nothing is accounted for)."""
        if self.accounted_j == 0.0:
            return math.inf if self.work_j else 0.0
        return abs(self.work_j - self.accounted_j) / abs(self.accounted_j)


class ArmEnergyModel:
    """Potential and kinetic energy, damping and friction of the lander from its URDF.

    The energies are those of :class:`ow_description.model.LanderModel` (its pinocchio model).
    Joints are matched by name; joints of the URDF that a joint state does not list are held at
    their neutral position (0 rad), and joint-state names the URDF lacks are ignored.

    Attributes:
        gravity: m/s^2, magnitude of gravity along -z of ``base_link``.
        lander: the lander model the energies come from.
        damping: N m s/rad, viscous damping per joint name (URDF ``<dynamics damping>``).
        friction: N m, Coulomb friction per joint name (URDF ``<dynamics friction>``).
    """

    def __init__(self, urdf_path: Path | str | None = None, gravity: float | None = None) -> None:
        """Load the model.

        Args:
            urdf_path: URDF file; default the lander of ``ow_description.description``.
            gravity: m/s^2, along -z of ``base_link``; default Europa's
                (``ow_description.description.EUROPA_GRAVITY``, the simulation's default).

        Raises:
            PowerError: the URDF cannot be loaded, or ``gravity`` is not finite.
        """
        # pinocchio is heavy: the import waits until a balance is wanted.
        from ow_description.errors import ModelError
        from ow_description.model import LanderModel

        if gravity is None:
            gravity = EUROPA_GRAVITY
        if not math.isfinite(gravity):
            msg = f"gravity={gravity} m/s^2 is not a finite number"
            raise PowerError(msg)
        if urdf_path is None:
            urdf_path = URDF_PATH
        try:
            self.lander: LanderModel = LanderModel(Path(urdf_path), float(gravity))
        except (ModelError, RuntimeError, ValueError) as exc:
            msg = f"cannot load URDF {urdf_path}: {exc}"
            raise PowerError(msg) from exc
        self.gravity = float(gravity)
        model = self.lander.model
        names = list(model.names)[1:]
        self._idx_v = {n: model.joints[model.getJointId(n)].idx_v for n in names}
        self.damping = {n: float(model.damping[self._idx_v[n]]) for n in names}
        self.friction = {n: float(model.friction[self._idx_v[n]]) for n in names}

    def _vectors(
        self, names: Sequence[str], position: ArrayLike, velocity: ArrayLike | None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        pos = np.asarray(position, dtype=float)
        vel = np.zeros_like(pos) if velocity is None else np.asarray(velocity, dtype=float)
        known = [(i, name) for i, name in enumerate(names) if name in self._idx_v]
        q = self.lander.q_from({name: pos[i] for i, name in known})
        v = np.zeros(self.lander.model.nv)
        for i, name in known:
            v[self._idx_v[name]] = vel[i]
        return q, v

    def potential_energy_j(self, names: Sequence[str], position: ArrayLike) -> float:
        """J, gravitational potential energy of all links at a configuration.

        Args:
            names: joint names.
            position: (n,) rad, in the order of ``names``.
        """
        q, _ = self._vectors(names, position, None)
        return self.lander.potential_energy(q)

    def kinetic_energy_j(
        self, names: Sequence[str], position: ArrayLike, velocity: ArrayLike
    ) -> float:
        """J, kinetic energy of all links at a configuration and joint velocity.

        Args:
            names: joint names.
            position: (n,) rad.
            velocity: (n,) rad/s.
        """
        import pinocchio as pin

        q, v = self._vectors(names, position, velocity)
        return float(pin.computeKineticEnergy(self.lander.model, self.lander.data, q, v))

    def balance(
        self,
        t_s: ArrayLike,
        names: Sequence[str],
        position: ArrayLike,
        velocity: ArrayLike,
        effort: ArrayLike,
        max_dt_s: float = math.inf,
        damping_effort: ArrayLike | None = None,
    ) -> EnergyBalance:
        """The work-energy balance of a recorded motion (e.g. from a bag's ``/joint_states``).

        Args:
            t_s: (N,) s, stamps.
            names: (n,) joint names of the columns below.
            position: (N, n) rad.
            velocity: (N, n) rad/s.
            effort: (N, n) N m, the torque the joint motor applied.
            max_dt_s: s, intervals longer than this are not integrated.
            damping_effort: (N, n) N m, the passive damping torque the simulation applied
                (``/sim/joint_damping``, same stamps and columns); when given, the losses are
                ``-sum damping_effort * velocity * dt`` instead of the URDF damping and friction.

        Returns:
            The balance between the first and the last sample.

        Raises:
            PowerError: fewer than two samples, or ``damping_effort`` of another shape.
        """
        pos = np.atleast_2d(np.asarray(position, dtype=float))
        vel = np.atleast_2d(np.asarray(velocity, dtype=float))
        tau = np.atleast_2d(np.asarray(effort, dtype=float))
        if pos.shape[0] < 2:
            msg = f"an energy balance needs at least two joint states, got {pos.shape[0]}"
            raise PowerError(msg)
        if damping_effort is None:
            known = [i for i, n in enumerate(names) if n in self._idx_v]
            damping = np.array([self.damping[names[i]] for i in known])
            friction = np.array([self.friction[names[i]] for i in known])
            dissipated = dissipated_work_j(t_s, vel[:, known], damping, friction, max_dt_s)
        else:
            damper = np.atleast_2d(np.asarray(damping_effort, dtype=float))
            if damper.shape != vel.shape:
                msg = (
                    f"damping_effort has shape {damper.shape}, the velocities {vel.shape}; "
                    "they must come from the same stamps and joints"
                )
                raise PowerError(msg)
            dissipated = -integrate_j(t_s, np.sum(damper * vel, axis=1), max_dt_s)
        return EnergyBalance(
            work_j=integrate_j(t_s, np.sum(tau * vel, axis=1), max_dt_s),
            potential_rise_j=self.potential_energy_j(names, pos[-1])
            - self.potential_energy_j(names, pos[0]),
            kinetic_rise_j=self.kinetic_energy_j(names, pos[-1], vel[-1])
            - self.kinetic_energy_j(names, pos[0], vel[0]),
            dissipated_j=dissipated,
        )
