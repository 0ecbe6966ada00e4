"""The lander's battery: ProgPy cell model, UKF state estimate and end-of-discharge prediction.

This succeeds OceanWATERS' GSAP prognoser (``Battery`` model, UKF observer, Monte-Carlo
predictor, 1 Hz) with NASA's ProgPy, without ROS::

    battery = Battery(BatteryConfig())          # 6S1P pack at SOC 0.95, 20 degrees C
    state = battery.update(load_w=60.0, dt_s=1.0)
    state.soc, state.rul_s, state.temperature_c, state.voltage_v

Each :meth:`Battery.update`:

1. draws the electrical load (the caller's total, with P0 and the motors' losses, plus any
   injected :attr:`~Battery.extra_load_w`) from the connected cells, each delivering an equal
   share; the power becomes the model's current input through the cell's own voltage at the
   start of the step (``i = p / v``), re-evaluated every ``MAX_STEP_S``;
2. steps the "true" cell (ProgPy's :class:`~progpy.models.BatteryElectroChemEOD`, see
   :mod:`ow_power.battery_model`) and reads its voltage and temperature as the measurements,
   exact unless the configuration asks for seeded noise;
3. updates ProgPy's :class:`~progpy.state_estimators.UnscentedKalmanFilter` once, with the
   mean current over the update and the measurements at its end;
4. reads the state of charge and the temperature from the estimate and predicts the end of
   discharge under the present load (:func:`ow_power.battery_prediction.predict_eod`).

The fault hooks (:meth:`Battery.set_extra_load`, :meth:`Battery.disconnect_cells`,
:meth:`Battery.lose_capacity`, :meth:`Battery.force_thermal_failure`,
:meth:`Battery.force_soc`) change the true cell and, where they change the state, the estimate
with it, as a detected event would: :attr:`Battery.state` shows the fault at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from progpy.state_estimators import UnscentedKalmanFilter
from progpy.uncertain_data import MultivariateNormalDist

from ow_power.battery_model import (
    STATES,
    TB,
    ZERO_C_K,
    discharge_to,
    lose_charge,
    make_cell_model,
    negative_charge_c,
    set_ambient_k,
    state_at_soc,
)
from ow_power.battery_prediction import predict_eod
from ow_power.config import BatteryConfig
from ow_power.errors import PowerError

#: s, longest explicit step of the cell model (its fastest time constant, the ohmic drop's
#: ``to``, is 6 s); longer updates are split into equal steps of at most this.
MAX_STEP_S = 1.0

#: Cells that may be disconnected (OceanWATERS' ``battery_nodes_to_disconnect``: 0-3).
MAX_DISCONNECTED_CELLS = 3

#: Highest temperature a thermal failure may force, degrees C.
MAX_FORCED_TEMPERATURE_C = 200.0

#: UKF process noise per update, variance per state (K^2, V^2, C^2 in the order of
#: :data:`ow_power.battery_model.STATES`): small against each state's scale, so the filter
#: follows the model between measurements and corrects slowly drifting differences.
PROCESS_NOISE = {
    "tb": 1e-4,
    "Vo": 1e-10,
    "Vsn": 1e-10,
    "Vsp": 1e-10,
    "qnB": 1e-2,
    "qnS": 1e-2,
    "qpB": 1e-2,
    "qpS": 1e-2,
}

#: Floor of the UKF measurement variances (degrees C^2, cell V^2): exact measurements still need
#: a positive-definite innovation covariance.
MIN_TEMPERATURE_VARIANCE = 1e-4
MIN_VOLTAGE_VARIANCE = 1e-8


@dataclass(frozen=True)
class BatteryState:
    """The battery after an update.

    Attributes:
        time_s: s of simulated time since the battery was made.
        soc: state of charge estimate, 0 (empty) to 1 (full).
        rul_s: s, predicted time to end of discharge at the present load (``math.inf`` when no
            load is drawn, 0 once discharged).
        temperature_c: degrees C, estimated cell temperature.
        voltage_v: V, measured pack voltage (connected cells in series).
        current_a: A, mean current of the last update (the pack's and every connected cell's:
            they are in series).
        load_w: W, power drawn during the last update (the caller's load plus the extra load).
        cells_connected: cells still delivering power.
        depleted: True once the pack reached its end-of-discharge voltage; it then delivers
            nothing.
    """

    time_s: float
    soc: float
    rul_s: float
    temperature_c: float
    voltage_v: float
    current_a: float
    load_w: float
    cells_connected: int
    depleted: bool


class SteppedUKF(UnscentedKalmanFilter):
    """ProgPy's UKF, one prediction per :meth:`estimate`, with its sigma points evaluated together.

    The filter (filterpy's, set up by ProgPy: sigma points, weights, Q, R) is unchanged; three
    things differ from the parent's ``estimate``:

    * it predicts once from ``self.t`` to ``t``, in ``steps`` explicit model steps: the parent
      loops ``while self.t < t: self.t += dt``, which predicts a second time whenever a step
      rounds below ``t`` (ProgPy's default ``t0`` is -1e-10, so its very first estimate over
      1 s predicts 2 s);
    * ProgPy's battery model is vectorized, so all sigma points go through ``next_state`` and
      ``output`` in one call each, and the filter takes each point's result from that batch
      (keyed by the point's bytes; a point not in the batch is evaluated alone): a third of
      the cost of one call per point;
    * the model's noise is not switched off and on for every sigma point (it is off already).
    """

    t: float  # s, time of the estimate (set by the parent)

    def __init__(self, model: Any, x0: Any, **kwargs: Any) -> None:
        self._input: Any = None
        self._steps = 1
        super().__init__(model, x0, **kwargs)

    def _measure(self, x: NDArray) -> NDArray:
        return self._outputs(np.array(x, dtype=float)[:, None])[:, 0]

    def _state_transition(self, x: NDArray, dt: float) -> NDArray:
        return self._moved(np.array(x, dtype=float)[:, None], dt)[:, 0]

    def _moved(self, columns: NDArray, dt: float) -> NDArray:
        """States (8, k) after ``dt`` s at the present input, in ``self._steps`` steps."""
        state = self.model.StateContainer(columns)
        for _ in range(self._steps):
            state = self.model.next_state(state, self._input, dt / self._steps)
        return np.asarray(state.matrix)

    def _outputs(self, columns: NDArray) -> NDArray:
        return np.asarray(self.model.output(self.model.StateContainer(columns)).matrix)

    def estimate(self, t: float, u: Any, z: Any, **kwargs: Any) -> None:
        """Predict from ``self.t`` to ``t`` with input ``u``, then update with the output ``z``.

        Args:
            t: s, the time of ``z``; after ``self.t``.
            u: the model's input (InputContainer) over the interval.
            z: the measured outputs (OutputContainer) at ``t``.
            **kwargs: ``steps`` (int, default 1), model steps the prediction is split into.
        """
        f = self.filter
        dt = t - self.t
        self._input = u
        self._steps = int(kwargs.get("steps", 1))
        sigmas = f.points_fn.sigma_points(f.x, f.P)
        moved = dict(
            zip((p.tobytes() for p in sigmas), self._moved(sigmas.T.copy(), dt).T, strict=True)
        )
        f.predict(
            dt=dt,
            fx=lambda x, step: (
                moved[x.tobytes()] if x.tobytes() in moved else self._state_transition(x, step)
            ),
        )
        outputs = self._outputs(f.sigmas_f.T.copy()).T
        seen = dict(zip((p.tobytes() for p in f.sigmas_f), outputs, strict=True))
        f.update(
            np.asarray(z.matrix[:, 0]),
            hx=lambda x: seen[x.tobytes()] if x.tobytes() in seen else self._measure(x),
        )
        self.t = t


def _finite(value: float, name: str, unit: str) -> float:
    number = float(value)
    if not math.isfinite(number):
        msg = f"{name} must be finite, got {value!r} {unit}"
        raise PowerError(msg)
    return number


class Battery:
    """The lander's pack: ``cells_in_series`` ProgPy cells, a UKF estimate, EOD prediction.

    Args:
        config: pack figures, initial state and measurement noise (see
            :class:`~ow_power.config.BatteryConfig`).

    Raises:
        PowerError: the initial cell voltage is not above the end-of-discharge voltage.
    """

    def __init__(self, config: BatteryConfig) -> None:
        self.config = config
        self._model = make_cell_model(config)
        self._veod = float(self._model.parameters["VEOD"])
        self._ambient_k = config.temperature_c + ZERO_C_K
        self._truth = state_at_soc(self._model, config.initial_soc, self._ambient_k)
        self._rng = np.random.default_rng(config.noise_seed)
        n = config.cells_in_series
        process_noise = np.diag([PROCESS_NOISE[s] for s in STATES])
        measurement_noise = np.diag(
            [
                max(config.temperature_noise_c**2, MIN_TEMPERATURE_VARIANCE),
                max((config.voltage_noise_v / n) ** 2, MIN_VOLTAGE_VARIANCE),
            ]
        )
        x0 = MultivariateNormalDist(STATES, self._truth, process_noise)
        self._estimator = SteppedUKF(self._model, x0, Q=process_noise, R=measurement_noise, t0=0.0)
        self._time_s = 0.0
        self._cells_connected = n
        self._extra_load_w = 0.0
        self._depleted = False
        self._measured = self._measure()
        if self._measured[1] <= self._veod:
            msg = (
                f"initial cell voltage {self._measured[1]:.3f} V at SOC {config.initial_soc:g} "
                f"is not above the end-of-discharge voltage {self._veod:g} V per cell"
            )
            raise PowerError(msg)
        self._state = self._snapshot(load_w=0.0, current_a=0.0)

    # ------------------------------------------------------------------------------ reading
    @property
    def state(self) -> BatteryState:
        """The battery after the last update (at construction: at rest, no load)."""
        return self._state

    @property
    def extra_load_w(self) -> float:
        """W, injected load added to every update's load (``high_power_draw``)."""
        return self._extra_load_w

    @property
    def cells_connected(self) -> int:
        """Cells still delivering power."""
        return self._cells_connected

    @property
    def capacity_c(self) -> float:
        """C, the charge between SOC 1 and SOC 0 (the negative electrode's maximum)."""
        return float(self._model.parameters["qnMax"])

    @property
    def true_soc(self) -> float:
        """The simulated cell's charge over its maximum (what the estimate tracks), 0-1."""
        return negative_charge_c(self._truth) / self.capacity_c

    # ------------------------------------------------------------------------------ running
    def update(self, load_w: float, dt_s: float) -> BatteryState:
        """Draw ``load_w`` (plus the extra load) for ``dt_s`` s, then estimate and predict.

        Args:
            load_w: W, electrical load of the lander over the interval (motors' electrical
                power and P0), >= 0.
            dt_s: s of simulated time, > 0.

        Returns:
            The battery after the interval (also :attr:`state`). Once depleted, the battery
            delivers nothing and only its clock moves.

        Raises:
            PowerError: a load below 0 or not finite, a step not above 0.
        """
        load = _finite(load_w, "load_w", "W")
        if load < 0.0:
            msg = f"load_w = {load:g} W is below 0 W (charging is not modelled)"
            raise PowerError(msg)
        dt = _finite(dt_s, "dt_s", "s")
        if dt <= 0.0:
            msg = f"dt_s = {dt:g} s must be above 0 s"
            raise PowerError(msg)
        total_w = load + self._extra_load_w
        if self._depleted:
            self._time_s += dt
            self._state = self._snapshot(load_w=total_w, current_a=0.0)
            return self._state
        cell_w = total_w / self._cells_connected
        steps = max(1, math.ceil(dt / MAX_STEP_S - 1e-9))
        step = dt / steps
        charge_c, taken = 0.0, 0
        voltage = self._truth_voltage()
        while taken < steps and not self._depleted:
            current = cell_w / voltage
            u = self._model.InputContainer(np.array([[current]]))
            x = self._model.StateContainer(self._truth[:, None])
            self._truth = np.asarray(self._model.next_state(x, u, step).matrix[:, 0])
            charge_c += current * step
            taken += 1
            voltage = self._truth_voltage()
            self._depleted = voltage < self._veod
        # The estimate sees the mean current (the charge drawn) and the measurements at the end.
        mean_current = charge_c / (taken * step)
        self._measured = self._measure()
        self._estimator.estimate(
            self._estimator.t + taken * step,
            self._model.InputContainer(np.array([[mean_current]])),
            self._model.OutputContainer(self._measured[:, None]),
            steps=taken,
        )
        self._time_s += dt
        self._state = self._snapshot(load_w=total_w, current_a=mean_current)
        return self._state

    # -------------------------------------------------------------------------- fault hooks
    def set_extra_load(self, power_w: float) -> None:
        """Add ``power_w`` W to the load of every following update (``high_power_draw``).

        The extra load stays until set again (0 removes it).

        Raises:
            PowerError: ``power_w`` below 0 W or not finite.
        """
        power = _finite(power_w, "extra load", "W")
        if power < 0.0:
            msg = f"extra load {power:g} W is below 0 W"
            raise PowerError(msg)
        self._extra_load_w = power

    def disconnect_cells(self, count: int) -> None:
        """Leave ``count`` cells disconnected in all (``battery_nodes_to_disconnect``).

        The remaining cells share the whole load, so each drains faster, and the pack voltage
        drops to theirs. Irreversible: cells once disconnected stay so; asking again for the
        same count changes nothing.

        Args:
            count: cells disconnected in total, 0 to :data:`MAX_DISCONNECTED_CELLS` (and fewer
                than the pack has).

        Raises:
            PowerError: ``count`` not an integer, out of range, or below the cells already
                disconnected.
        """
        limit = min(MAX_DISCONNECTED_CELLS, self.config.cells_in_series - 1)
        if isinstance(count, bool) or not isinstance(count, int | np.integer):
            msg = f"cells to disconnect must be an integer, got {count!r}"
            raise PowerError(msg)
        if not 0 <= count <= limit:
            msg = f"cells to disconnect = {count} is outside [0, {limit}]"
            raise PowerError(msg)
        disconnected = self.config.cells_in_series - self._cells_connected
        if count < disconnected:
            msg = (
                f"cells to disconnect = {count} is below the {disconnected} already "
                "disconnected: disconnection is irreversible"
            )
            raise PowerError(msg)
        self._cells_connected = self.config.cells_in_series - int(count)
        self._measured = self._measure()
        self._state = self._snapshot(load_w=self._state.load_w, current_a=self._state.current_a)

    def lose_capacity(self, fraction: float) -> None:
        """Lose ``fraction`` of the charge still in every cell at once (capacity loss).

        The lithium lost leaves the cycle, so the state of charge drops by that fraction of
        itself, and the end of discharge comes earlier.

        Args:
            fraction: share of the present charge lost, in [0, 1).

        Raises:
            PowerError: ``fraction`` outside [0, 1) or not finite.
        """
        share = _finite(fraction, "capacity loss", "")
        if not 0.0 <= share < 1.0:
            msg = f"capacity loss {share:g} is outside [0, 1)"
            raise PowerError(msg)
        self._truth = lose_charge(self._truth, share)
        self._estimator.filter.x = lose_charge(self._estimator.filter.x, share)
        self._refresh()

    def force_soc(self, soc: float) -> None:
        """Discharge every cell at once to a charge-based state of charge ``soc`` (low SOC).

        Args:
            soc: 0 to the present charge-based state of charge (:attr:`true_soc`); charging is
                not modelled.

        Raises:
            PowerError: ``soc`` not finite, below 0 or above the present state of charge.
        """
        target = _finite(soc, "forced SOC", "")
        if not 0.0 <= target <= self.true_soc:
            msg = f"forced SOC {target:g} is outside [0, {self.true_soc:.6g}] (the present SOC)"
            raise PowerError(msg)
        qn = target * self.capacity_c
        self._truth = discharge_to(self._model, self._truth, qn)
        estimate = self._estimator.filter.x
        self._estimator.filter.x = discharge_to(
            self._model, estimate, min(qn, negative_charge_c(estimate))
        )
        self._refresh()

    def force_thermal_failure(self, temperature_c: float) -> None:
        """Heat every cell to ``temperature_c`` at once and hold it there (thermal failure).

        The cells' surroundings take that temperature, so the cells stay at it (plus their own
        heating) until :meth:`clear_thermal_failure`.

        Args:
            temperature_c: degrees C, above -273.15 and at most
                :data:`MAX_FORCED_TEMPERATURE_C`.

        Raises:
            PowerError: ``temperature_c`` out of that range or not finite.
        """
        temperature = _finite(temperature_c, "forced temperature", "degC")
        if not -ZERO_C_K < temperature <= MAX_FORCED_TEMPERATURE_C:
            msg = (
                f"forced temperature {temperature:g} degC is outside "
                f"(-273.15, {MAX_FORCED_TEMPERATURE_C:g}] degC"
            )
            raise PowerError(msg)
        kelvin = temperature + ZERO_C_K
        set_ambient_k(self._model, kelvin)
        self._truth = np.array(self._truth)
        self._truth[TB] = kelvin
        estimate = np.array(self._estimator.filter.x)
        estimate[TB] = kelvin
        self._estimator.filter.x = estimate
        self._refresh()

    def clear_thermal_failure(self) -> None:
        """Give the cells back their configured surroundings; they cool with a 100 s constant."""
        set_ambient_k(self._model, self._ambient_k)

    # ------------------------------------------------------------------------------ helpers
    def _truth_voltage(self) -> float:
        return float(self._model.output(self._model.StateContainer(self._truth[:, None]))["v"])

    def _measure(self) -> NDArray:
        """(2,) measured cell temperature (degrees C) and voltage (V), noise added if asked."""
        z = np.asarray(
            self._model.output(self._model.StateContainer(self._truth[:, None])).matrix[:, 0],
            dtype=float,
        )
        config = self.config
        if config.temperature_noise_c > 0.0:
            z[0] += self._rng.normal(0.0, config.temperature_noise_c)
        if config.voltage_noise_v > 0.0:
            z[1] += self._rng.normal(0.0, config.voltage_noise_v) / config.cells_in_series
        return z

    def _refresh(self) -> None:
        """New measurements and outputs after a hook changed the state."""
        self._measured = self._measure()
        if self._truth_voltage() < self._veod:
            self._depleted = True
        self._state = self._snapshot(load_w=self._state.load_w, current_a=self._state.current_a)

    def _snapshot(self, load_w: float, current_a: float) -> BatteryState:
        model = self._model
        estimate = model.StateContainer(np.asarray(self._estimator.filter.x, dtype=float)[:, None])
        soc = float(np.clip(model.event_state(estimate)["EOD"], 0.0, 1.0))
        temperature_c = float(model.output(estimate)["t"])
        if self._depleted:
            rul_s = 0.0
        else:
            cell_w = load_w / self._cells_connected
            rul_s = predict_eod(model, np.asarray(self._estimator.filter.x, dtype=float), cell_w)
        return BatteryState(
            time_s=self._time_s,
            soc=soc,
            rul_s=rul_s,
            temperature_c=temperature_c,
            voltage_v=float(self._measured[1]) * self._cells_connected,
            current_a=current_a,
            load_w=load_w,
            cells_connected=self._cells_connected,
            depleted=self._depleted,
        )
