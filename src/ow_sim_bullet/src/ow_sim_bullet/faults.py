"""Injected faults where the physics is the simulation's: locked joints and a faulty wrist F/T
sensor. No ROS here: the node hands the simulation thread an
:class:`~ow_faults.injection.FaultSet` (:meth:`BulletSim.apply_faults`).

* A locked joint (``<joint>_joint_locked_failure``, OceanWATERS raises the Gazebo joint's
  friction to 3000) gets a Bullet velocity motor at 0 rad/s whose torque is bounded only by
  :data:`LOCK_TORQUE_NM`, far above any joint's effort limit: the joint does not move whatever
  its controller applies (the controller keeps commanding; the motor's reaction acts on the
  links around it). Released, the motor is off again and the joint's controller holds it where
  it is (:meth:`JointController.release`).
* The wrist force/torque sensor (``ft_sensor_faults``, while ``enable``): ``zero_signal_failure``
  outputs zeros; otherwise ``N(signal_bias_failure, signal_noise_failure**2)`` is added to each
  of the six components. The noise of a sample depends only on ``noise_seed`` and the physics
  step it is taken at, so a faulted run repeats exactly.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import numpy.typing as npt
import pybullet as pb

from ow_faults.injection import LOCKABLE_JOINTS, FaultSet

FloatArray = npt.NDArray[np.float64]

#: N m, the torque bound of a locked joint's velocity motor: five orders of magnitude above the
#: largest effort limit, so no controller or load moves the joint.
LOCK_TORQUE_NM = 1e8
#: N m s/rad, a locked joint's damper in the controller's implicit step: the step then predicts
#: it (nearly) at rest, as the lock keeps it, and the joints coupled to it without most of the
#: phantom motion. Measured (tests/unit/ow_sim_bullet/test_sim_faults.py): with a locked joint's
#: motor saturated, another joint commanded 0.2 rad away ends within 9e-3 rad of it (1.4e-2 rad
#: without this damper; larger values make it worse next to the light scoop).
LOCK_DAMPER = 1e4


class JointLocks:
    """Locks and releases joints of one pybullet body (simulation thread only).

    Args:
        client: pybullet client id.
        robot: body id.
        bullet_index: Bullet joint index of every joint that may be locked, by name.
    """

    def __init__(self, client: int, robot: int, bullet_index: Mapping[str, int]) -> None:
        self._client = client
        self._robot = robot
        self._index = {j: bullet_index[j] for j in LOCKABLE_JOINTS}
        #: the joints locked now.
        self.locked: frozenset[str] = frozenset()

    def set(self, joints: frozenset[str]) -> tuple[frozenset[str], frozenset[str]]:
        """Lock exactly ``joints`` (names of :data:`LOCKABLE_JOINTS`).

        Returns:
            The joints newly locked and the joints released.
        """
        locking, releasing = joints - self.locked, self.locked - joints
        for joint in sorted(locking | releasing):
            pb.setJointMotorControl2(
                self._robot,
                self._index[joint],
                pb.VELOCITY_CONTROL,
                targetVelocity=0.0,
                force=LOCK_TORQUE_NM if joint in locking else 0.0,
                physicsClientId=self._client,
            )
        self.locked = frozenset(joints)
        return locking, releasing

    def flags(self) -> tuple[tuple[str, ...], tuple[bool, ...]]:
        """(names, locked) of every lockable joint, names in alphabetical order."""
        return LOCKABLE_JOINTS, tuple(j in self.locked for j in LOCKABLE_JOINTS)


class WristFaults:
    """The wrist F/T sensor's injected faults.

    Args:
        seed: seed of the noise (with the physics step of each sample).
    """

    def __init__(self, seed: int) -> None:
        self._seed = seed
        self._zero = False
        self._bias = 0.0
        self._noise = 0.0
        #: whether any fault changes the output now.
        self.active = False

    def set(self, faults: FaultSet) -> None:
        """Take the ``ft_sensor_faults`` of ``faults``."""
        self.active = faults.wrist_faulted
        self._zero = faults.zero_signal_failure
        self._bias = faults.signal_bias_failure
        self._noise = faults.signal_noise_failure

    def apply(
        self, force: FloatArray, torque: FloatArray, step: int
    ) -> tuple[FloatArray, FloatArray]:
        """The sensor's output for the true ``force`` (3,) N and ``torque`` (3,) N m, sampled at
        physics step ``step`` (the same step always gets the same noise)."""
        if not self.active:
            return force, torque
        if self._zero:
            return np.zeros(3), np.zeros(3)
        offset = np.full(6, self._bias)
        if self._noise > 0.0:
            rng = np.random.default_rng((self._seed, step))
            offset = offset + rng.normal(0.0, self._noise, 6)
        return force + offset[:3], torque + offset[3:]
