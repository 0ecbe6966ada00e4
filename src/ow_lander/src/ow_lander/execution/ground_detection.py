"""Guarded-move ground detection of the paper (section 3), free of ROS.

The scoop tip's vertical velocity is smoothed by a moving average of five samples; the mean plus
one standard deviation of the first five velocity samples is the threshold; contact is declared
when the smoothed velocity exceeds it (the descent, a negative z velocity, slows down). The
standard deviation is floored at ``min_tolerance`` (ours, 1 mm/s) and at ``relative_tolerance``
times the mean descent speed (ours): with a perfectly smooth first window the paper's rule would
fire on rounding noise or on the few per cent the tip speed varies along a Cartesian line of
joint-space steps (Gazebo's noise gave the paper's threshold its width).
"""

from __future__ import annotations

from collections import deque

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


class GroundDetector:
    """Feed scoop-tip positions with their times; :meth:`update` says when ground is touched.

    Args:
        window: samples of the moving average and of the threshold (paper: 5).
        min_tolerance: m/s, smallest margin above the first window's mean velocity.
        relative_tolerance: smallest margin as a fraction of that mean's magnitude (ours, see
            the module docstring).
    """

    def __init__(
        self, window: int = 5, min_tolerance: float = 0.001, relative_tolerance: float = 0.0
    ) -> None:
        self.window = window
        self.min_tolerance = min_tolerance
        self.relative_tolerance = relative_tolerance
        self.reset()

    def reset(self) -> None:
        """Forget every sample (call before each descent)."""
        self._last: tuple[float, FloatArray] | None = None
        self._velocities: deque[float] = deque(maxlen=self.window)
        self._first: list[float] = []
        self.threshold: float | None = None
        self.contact: FloatArray | None = None

    def update(self, t: float, position: FloatArray) -> bool:
        """Add a sample of the tip at time ``t`` (s), ``position`` (3,) m in base_link.

        Returns:
            True once contact has been detected (``contact`` holds the tip position then).
        """
        if self.contact is not None:
            return True
        position = np.asarray(position, dtype=np.float64)
        if self._last is not None and t > self._last[0]:
            vz = float(position[2] - self._last[1][2]) / (t - self._last[0])
            self._velocities.append(vz)
            if len(self._first) < self.window:
                self._first.append(vz)
                if len(self._first) == self.window:
                    mean = float(np.mean(self._first))
                    tolerance = max(
                        float(np.std(self._first)),
                        self.min_tolerance,
                        self.relative_tolerance * abs(mean),
                    )
                    self.threshold = mean + tolerance
            elif self.threshold is not None and float(np.mean(self._velocities)) > self.threshold:
                self.contact = position.copy()
        if self._last is None or t > self._last[0]:
            self._last = (t, position)
        return self.contact is not None

    @property
    def velocity(self) -> float | None:
        """m/s, the latest z velocity sample, or None before two positions."""
        return self._velocities[-1] if self._velocities else None

    @property
    def average(self) -> float | None:
        """m/s, the moving average of the z velocity, or None before two positions."""
        return float(np.mean(self._velocities)) if self._velocities else None


class ForceDetector:
    """Contact when the wrist force rises by ``threshold`` N over its first reading (the tare),
    as later OceanWATERS detects the ground with the force/torque sensor at ``j_dist_pitch``.

    Args:
        threshold: N, rise of the force magnitude (of the change from the tare) that is contact.
    """

    def __init__(self, threshold: float) -> None:
        self.threshold = threshold
        self.reset()

    def reset(self) -> None:
        """Forget the tare and any contact."""
        self.tare: FloatArray | None = None
        self.fired = False
        self.contact: FloatArray | None = None
        self.rise = 0.0
        self.peak_rise = 0.0

    def update(self, force: FloatArray, position: FloatArray | None = None) -> bool:
        """Add a force reading (3,) N, with the scoop tip ``position`` (3,) m at that time when
        the caller knows it (else it sets ``contact`` itself once this returns True).

        Returns:
            True once contact has been detected.
        """
        if self.fired:
            return True
        force = np.asarray(force, dtype=np.float64)
        if self.tare is None:
            self.tare = force.copy()
            return False
        self.rise = float(np.linalg.norm(force - self.tare))
        self.peak_rise = max(self.peak_rise, self.rise)
        if self.rise >= self.threshold:
            self.fired = True
            if position is not None:
                self.contact = np.asarray(position, dtype=np.float64).copy()
        return self.fired


class WrenchDetector:
    """A force/torque guard (OceanWATERS' guarded actions): it fires when the wrist force
    magnitude or the torque magnitude, each measured from the first reading (the tare, as
    :class:`ForceDetector`), exceeds its threshold.

    Args:
        force_threshold: N, > 0, largest allowed rise of the force magnitude.
        torque_threshold: N m, > 0, largest allowed rise of the torque magnitude.

    Attributes:
        force: N, magnitude of the force change at the latest reading (0 before any).
        torque: N m, magnitude of the torque change at the latest reading.
        breach: "force" or "torque" once a threshold was exceeded, else None.
        peak_force, peak_torque: N, N m, the largest changes read so far.
    """

    def __init__(self, force_threshold: float, torque_threshold: float) -> None:
        self.force_threshold = force_threshold
        self.torque_threshold = torque_threshold
        self.tare: tuple[FloatArray, FloatArray] | None = None
        self.force = 0.0
        self.torque = 0.0
        self.breach: str | None = None
        self.peak_force = 0.0
        self.peak_torque = 0.0

    def update(self, force: FloatArray, torque: FloatArray) -> bool:
        """Add a reading, ``force`` (3,) N and ``torque`` (3,) N m; True once a threshold has
        been exceeded (the readings after it are ignored)."""
        if self.breach is not None:
            return True
        force = np.asarray(force, dtype=np.float64)
        torque = np.asarray(torque, dtype=np.float64)
        if self.tare is None:
            self.tare = (force.copy(), torque.copy())
            return False
        self.force = float(np.linalg.norm(force - self.tare[0]))
        self.torque = float(np.linalg.norm(torque - self.tare[1]))
        self.peak_force = max(self.peak_force, self.force)
        self.peak_torque = max(self.peak_torque, self.torque)
        if self.force > self.force_threshold:
            self.breach = "force"
        elif self.torque > self.torque_threshold:
            self.breach = "torque"
        return self.breach is not None

    def describe(self) -> str:
        """What fired, with the measured value and the threshold (or that nothing did)."""
        if self.breach == "force":
            return f"force {self.force:.1f} N exceeded force_threshold {self.force_threshold} N"
        if self.breach == "torque":
            return (
                f"torque {self.torque:.2f} N m exceeded torque_threshold "
                f"{self.torque_threshold} N m"
            )
        return (
            f"no force/torque threshold exceeded (largest changes {self.peak_force:.1f} N of "
            f"{self.force_threshold} N, {self.peak_torque:.2f} N m of {self.torque_threshold} N m)"
        )
