"""The lander's battery cell: ProgPy's electrochemistry model scaled to the pack's figures.

OceanWATERS' GSAP prognoser runs the ``Battery`` model of Daigle and Kulkarni (2013) with 6S1P
pack parameters. ProgPy's :class:`~progpy.models.BatteryElectroChemEOD` is the same model, fitted
to one 18650 Li-ion cell. The pack here is ``n`` such cells in series, all in the same state, so
one cell model serves for every cell:

* **in series** the charge is the string's (``qMobile`` is the pack's, 80387 C), while voltages
  and resistance add up: the cell's ``Ro`` and ``VEOD`` are the pack's divided by ``n``
  (0.0232 ohm / 6, 18 V / 6 = 3.0 V, ProgPy's own cell figure), and the pack voltage is ``n``
  times the cell's;
* the cell is ``qMobile / 7600`` (10.6) times ProgPy's 18650, i.e. that many 18650s in
  parallel: the electrode surface areas ``Sn`` and ``Sp`` scale with it, so at the same C-rate
  the current density, and with it the surface overpotentials, are those of the fitted cell.
  Every other parameter (Redlich-Kister coefficients, time constants, diffusion) is ProgPy's.

Units: charge C, current A, voltage V, temperature K inside the model (its output ``t`` is
degrees C), time s. The state-of-charge convention is ProgPy's event state of ``EOD``: the
negative electrode's charge over its maximum, overridden near the end by the margin of the
voltage above ``VEOD`` (over ``VDropoff``, 0.1 V per cell).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from progpy.models import BatteryElectroChemEOD

from ow_power.config import BatteryConfig

#: ProgPy's 18650 cell, the cell every parameter not given by the pack is taken from.
CELL_PARAMETERS = BatteryElectroChemEOD.default_parameters

#: The model's state names, in the order of every state vector here.
STATES: tuple[str, ...] = tuple(BatteryElectroChemEOD.states)

#: 0 degrees C in K.
ZERO_C_K = 273.15


def index(state: str) -> int:
    """Position of ``state`` (``"qnS"``, ``"tb"``, ...) in a state vector."""
    return STATES.index(state)


TB, VO, VSN, VSP = index("tb"), index("Vo"), index("Vsn"), index("Vsp")
QNB, QNS, QPB, QPS = index("qnB"), index("qnS"), index("qpB"), index("qpS")


def make_cell_model(config: BatteryConfig) -> BatteryElectroChemEOD:
    """One cell of the pack, with ProgPy's own noise switched off (runs stay deterministic).

    Args:
        config: the pack figures (``mobile_charge_c``, ``internal_resistance_ohm``,
            ``eod_voltage_v``, ``cells_in_series``) and the ambient temperature.

    Returns:
        The cell model; its ambient temperature (``parameters["x0"]["tb"]``, K) is the
        configured one.
    """
    n = config.cells_in_series
    scale = config.mobile_charge_c / CELL_PARAMETERS["qMobile"]
    model = BatteryElectroChemEOD(
        qMobile=config.mobile_charge_c,
        Ro=config.internal_resistance_ohm / n,
        VEOD=config.eod_voltage_v / n,
        Sn=CELL_PARAMETERS["Sn"] * scale,
        Sp=CELL_PARAMETERS["Sp"] * scale,
        process_noise=0.0,
        measurement_noise=0.0,
    )
    set_ambient_k(model, config.temperature_c + ZERO_C_K)
    return model


def set_ambient_k(model: BatteryElectroChemEOD, temperature_k: float) -> None:
    """Set the temperature (K) the cell relaxes to: the model's ``x0["tb"]``, constant 100 s."""
    model.parameters["x0"] = {**model.parameters["x0"], "tb": float(temperature_k)}


def state_at_soc(model: BatteryElectroChemEOD, soc: float, temperature_k: float) -> NDArray:
    """A cell at rest with a state of charge ``soc`` (0-1) and temperature ``temperature_k``.

    The negative electrode holds ``soc`` of its maximum charge and the positive electrode the
    rest of the mobile charge; each splits between surface and bulk by volume, as at rest.

    Returns:
        (8,) state vector in the order of :data:`STATES`.
    """
    p = model.parameters
    f = p["VolSFraction"]
    qn = soc * p["qnMax"]
    qp = p["qMax"] - qn
    x = np.zeros(len(STATES))
    x[TB] = temperature_k
    x[QNS], x[QNB] = f * qn, (1.0 - f) * qn
    x[QPS], x[QPB] = f * qp, (1.0 - f) * qp
    return x


def discharge_to(model: BatteryElectroChemEOD, x: NDArray, qn_c: float) -> NDArray:
    """``x`` with its negative electrode discharged to ``qn_c`` C, at once.

    The charge taken from the negative electrode (its surface and bulk in proportion) goes to
    the positive electrode (split by volume), as a discharge moves it.

    Args:
        model: the cell model (its surface volume fraction).
        x: (8,) state vector.
        qn_c: C, the negative electrode's new charge, between 0 and its present charge.

    Returns:
        A new (8,) state vector.
    """
    f = model.parameters["VolSFraction"]
    qn = negative_charge_c(x)
    moved = qn - qn_c
    y = np.array(x, dtype=float)
    ratio = qn_c / qn if qn > 0.0 else 0.0
    y[QNS], y[QNB] = x[QNS] * ratio, x[QNB] * ratio
    y[QPS], y[QPB] = x[QPS] + f * moved, x[QPB] + (1.0 - f) * moved
    return y


def lose_charge(x: NDArray, fraction: float) -> NDArray:
    """``x`` with ``fraction`` (0-1) of the negative electrode's charge lost, not moved.

    Lost lithium leaves the cycle: the mobile charge, and so the charge still to deliver,
    shrinks, and the positive electrode is untouched.

    Returns:
        A new (8,) state vector.
    """
    y = np.array(x, dtype=float)
    y[QNS], y[QNB] = x[QNS] * (1.0 - fraction), x[QNB] * (1.0 - fraction)
    return y


def negative_charge_c(x: NDArray) -> float:
    """C, the negative electrode's charge (surface plus bulk) of an (8,) state."""
    return float(x[QNS] + x[QNB])
