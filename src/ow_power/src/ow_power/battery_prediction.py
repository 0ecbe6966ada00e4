"""End-of-discharge prediction under a constant load: cheap, deterministic, ProgPy's equations.

Simulating ProgPy's model to its end of discharge (``simulate_to_threshold``) takes ~40 000
explicit steps of 1 s from a full pack at the lander's baseline load, 15-18 s of computation:
far too much for a prediction every second of simulated time. GSAP's Monte-Carlo predictor and
ProgPy's ``UnscentedTransformPredictor`` multiply that by their sample counts.

Under a constant power the cell is, after a few time constants, in a quasi-steady state: every
fast state sits where ProgPy's ``dx`` drives it (the ohmic drop ``Vo``, the surface
overpotentials ``Vsn``/``Vsp``: ``nominal = state + tau * d state/dt``), and the surface
concentrations lag the bulk by the steady diffusion gradient. Only the charge moves, at
``dq/dt = -i``. So the time to end of discharge is an integral over the charge still to move,

    RUL = integral from q_eod to q_now of dq / i(q),

with ``i(q)`` the current that draws the power from the quasi-steady voltage ``v(q, i)``
(``p = v i``, a fixed-point iteration) and ``q_eod`` the charge at which that voltage falls to
``VEOD``. :func:`predict_eod` evaluates ``v`` with ProgPy's vectorized ``dx`` and ``output`` on a
grid of charges, then again on a fine grid around the crossing: 1.4-2.6 ms (bench/battery.py).
The temperature is held at its present value. A load step is taken to act at once, so right
after a step up the prediction is slightly pessimistic (the overpotentials take up to ``tsn`` to
build up).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from progpy.models import BatteryElectroChemEOD

from ow_power.battery_model import QNB, QNS, QPB, QPS, STATES, VO, VSN, VSP, negative_charge_c

#: Charges on the coarse grid (present charge to empty) and on the fine grid around the crossing.
COARSE_POINTS = 48
FINE_POINTS = 32

#: Fixed-point iterations of ``i = p / v(q, i)`` on the coarse grid (from ``i = p / v_now``) and
#: on the fine grid (from the coarse grid's currents). The ohmic and surface drops are a few
#: percent of the voltage, so each iteration gains one to two digits of the current.
COARSE_ITERATIONS = 3
FINE_ITERATIONS = 2


def quasi_steady(
    model: BatteryElectroChemEOD,
    x: NDArray,
    qn_c: NDArray,
    power_w: float,
    current_a: NDArray,
    iterations: int,
) -> tuple[NDArray, NDArray]:
    """Quasi-steady cell voltage and current at each negative-electrode charge ``qn_c``.

    The surface voltage (ProgPy's ``output`` with the drops at 0) depends on the current only
    through the small surface gradient, so it is evaluated with the first guess and, when there
    are more than two iterations, again for the last; the drops come from ``dx`` each time.

    Args:
        model: the cell model.
        x: (8,) present state (its temperature and total charges are used).
        qn_c: (m,) C, negative-electrode charges to evaluate at.
        power_w: W, the constant power drawn from the cell.
        current_a: (m,) A, first guess of the current at each charge.
        iterations: fixed-point iterations, >= 1.

    Returns:
        ``(v, i)``: (m,) V and the (m,) A that voltage was evaluated at; ``v`` is NaN where the
        state is not physical (an electrode emptied, or a load the cell cannot deliver).
    """
    p = model.parameters
    f = p["VolSFraction"]
    qp = x[QPS] + x[QPB] + (negative_charge_c(x) - qn_c)
    # Steady diffusion between bulk and surface carries the current: the surface holds delta C
    # less (negative electrode) or more (positive) than its share by volume.
    gradient = f * (1.0 - f) * p["tDiffusion"] * p["VolB"]
    states = np.repeat(np.asarray(x, dtype=float)[:, None], len(qn_c), axis=1)
    current = np.array(current_a, dtype=float)
    voltage = np.full(len(qn_c), np.nan)
    surface = voltage
    with np.errstate(invalid="ignore", divide="ignore"):
        for k in range(iterations):
            states[[VO, VSN, VSP]] = 0.0
            if k == 0 or (k == iterations - 1 and iterations > 2):
                delta = current * gradient
                states[QNS], states[QNB] = f * qn_c - delta, (1.0 - f) * qn_c + delta
                states[QPS], states[QPB] = f * qp + delta, (1.0 - f) * qp - delta
                surface = np.asarray(model.output(model.StateContainer(states))["v"], dtype=float)
            rates = model.dx(model.StateContainer(states), model.InputContainer(current[None, :]))
            # With the drops at 0, each one's rate is its nominal value over its time constant.
            drops = (
                p["to"] * np.asarray(rates["Vo"])
                + p["tsn"] * np.asarray(rates["Vsn"])
                + p["tsp"] * np.asarray(rates["Vsp"])
            )
            voltage = np.where(surface - drops > 0.0, surface - drops, np.nan)
            if k < iterations - 1:
                following = power_w / voltage
                current = np.where(np.isfinite(following), following, current)
    return voltage, current


def _time_s(charges: NDArray, current: NDArray) -> float:
    """s to move from ``charges[0]`` down to ``charges[-1]`` (trapezoids on 1/i)."""
    if len(charges) < 2:
        return 0.0
    inverse = 1.0 / current
    return float(np.sum(0.5 * (inverse[1:] + inverse[:-1]) * (charges[:-1] - charges[1:])))


def predict_eod(model: BatteryElectroChemEOD, x: NDArray, power_w: float) -> float:
    """s until the cell's voltage falls to ``VEOD`` while it delivers ``power_w`` W.

    Args:
        model: the cell model.
        x: (8,) present state, in the order of :data:`ow_power.battery_model.STATES`.
        power_w: W drawn from the cell (not the pack), constant.

    Returns:
        s, the remaining useful life: ``math.inf`` for no load; 0 when the voltage is already
        below ``VEOD`` or the cell cannot deliver the power even now.

    Raises:
        ValueError: ``x`` is not a state vector of the model.
    """
    if len(x) != len(STATES):
        msg = f"state has {len(x)} values, expected {len(STATES)} ({', '.join(STATES)})"
        raise ValueError(msg)
    if power_w <= 0.0:
        return math.inf
    veod = model.parameters["VEOD"]
    v_now = float(model.output(model.StateContainer(np.asarray(x, dtype=float)[:, None]))["v"])
    qn_now = negative_charge_c(x)
    # Charge cannot go to exactly 0 (the surface fraction's logarithm); 1e-6 of qnMax is a
    # fraction of a second at any load.
    q_min = 1e-6 * model.parameters["qnMax"]
    if v_now < veod or qn_now <= q_min:
        return 0.0
    coarse = np.linspace(qn_now, q_min, COARSE_POINTS)
    first_guess = np.full(COARSE_POINTS, power_w / v_now)
    v, i = quasi_steady(model, x, coarse, power_w, first_guess, COARSE_ITERATIONS)
    ok = v >= veod  # NaN compares False: not deliverable
    if not ok[0]:
        return 0.0
    if ok.all():  # the voltage holds until the charge runs out
        return _time_s(coarse, i)
    k = int(np.argmin(ok))
    fine = np.linspace(coarse[k - 1], coarse[k], FINE_POINTS)
    guess = np.full(FINE_POINTS, i[k - 1])
    v_fine, i_fine = quasi_steady(model, x, fine, power_w, guess, FINE_ITERATIONS)
    ok_fine = v_fine >= veod
    ok_fine[0] = True  # the coarse point above the crossing
    j = int(np.argmin(ok_fine)) if not ok_fine.all() else FINE_POINTS - 1
    q_eod = fine[j - 1]
    if np.isfinite(v_fine[j]) and np.isfinite(v_fine[j - 1]) and v_fine[j] < veod:
        # Linear interpolation of the voltage between the last point above and the first below.
        share = (v_fine[j - 1] - veod) / (v_fine[j - 1] - v_fine[j])
        q_eod = fine[j - 1] + share * (fine[j] - fine[j - 1])
    last = (fine[j - 1] - q_eod) / i_fine[j - 1]
    return _time_s(coarse[:k], i[:k]) + _time_s(fine[:j], i_fine[:j]) + float(last)
