"""ow_power battery benchmarks: one JSON line per metric.

The battery node updates once per second of simulated time while the simulation runs 40-70x
real time, so one update has 14-25 ms of wall time; it must cost far less. Measured: a whole
update (cell step, UKF estimate, end-of-discharge prediction) at 1 Hz under an arm-like load,
its two expensive parts alone, the prediction against ProgPy's full simulation to the end of
discharge (cost and agreement), and the import cost of a node start.
"""

import json
import math
import subprocess
import sys
import time

import numpy as np
from progpy.state_estimators import UnscentedKalmanFilter
from progpy.uncertain_data import MultivariateNormalDist

from ow_power.battery import PROCESS_NOISE, Battery, SteppedUKF
from ow_power.battery_model import STATES, make_cell_model, state_at_soc
from ow_power.battery_prediction import predict_eod
from ow_power.config import BatteryConfig


def emit(metric: str, value: float, unit: str, **extra: object) -> None:
    print(
        json.dumps(
            {"bench": "battery", "metric": metric, "value": round(value, 4), "unit": unit, **extra}
        )
    )


def arm_load_w(k: int) -> float:
    """W: P0 plus a motor load that changes every second (an arm moving)."""
    return 43.0 + 40.0 * math.sin(k / 9.0) ** 2 + 15.0 * (k % 7 == 0)


def bench_update() -> None:
    battery = Battery(BatteryConfig())
    for k in range(20):  # warm-up (first calls allocate)
        battery.update(arm_load_w(k), 1.0)
    n = 1000
    wall = np.empty(n)
    cpu_start = time.process_time()
    for k in range(n):
        start = time.perf_counter()
        battery.update(arm_load_w(k), 1.0)
        wall[k] = time.perf_counter() - start
    cpu_ms = (time.process_time() - cpu_start) / n * 1e3
    emit("update_wall_median", float(np.median(wall)) * 1e3, "ms", updates=n, rate_hz=1.0)
    emit("update_wall_p90", float(np.percentile(wall, 90)) * 1e3, "ms")
    emit("update_wall_min", float(wall.min()) * 1e3, "ms")
    emit("update_cpu_mean", cpu_ms, "ms")
    emit("simulated_per_cpu_second", 1e3 / cpu_ms, "s/s", note="1 Hz updates")


def _median_ms(call, n: int = 300) -> float:
    times = np.empty(n)
    for k in range(n):
        start = time.perf_counter()
        call()
        times[k] = time.perf_counter() - start
    return float(np.median(times)) * 1e3


def bench_parts() -> None:
    """The UKF estimate (ours and ProgPy's stock one) and the prediction, each alone."""
    model = make_cell_model(BatteryConfig())
    x = state_at_soc(model, 0.5, 293.15)
    q = np.diag([PROCESS_NOISE[s] for s in STATES])
    r = np.diag([1e-4, 1e-8])
    u = model.InputContainer(np.array([[1.8]]))
    z = model.OutputContainer(model.output(model.StateContainer(x[:, None])).matrix)
    ours = SteppedUKF(model, MultivariateNormalDist(STATES, x, q), Q=q, R=r, t0=0.0)
    stock = UnscentedKalmanFilter(model, MultivariateNormalDist(STATES, x, q), Q=q, R=r, t0=0.0)
    emit(
        "ukf_estimate_median",
        _median_ms(lambda: ours.estimate(ours.t + 1.0, u, z)),
        "ms",
        sigma_points=2 * len(STATES) + 1,
    )
    stock_z = {"t": float(z["t"]), "v": float(z["v"])}
    emit(
        "progpy_stock_ukf_estimate_median",
        _median_ms(lambda: stock.estimate(stock.t + 1.0, u, stock_z), n=100),
        "ms",
    )
    emit("eod_prediction_median", _median_ms(lambda: predict_eod(model, x, 10.0)), "ms")


def bench_prediction_vs_full_simulation() -> None:
    """The quasi-steady prediction against ProgPy's simulate_to_threshold (1 s Euler steps)."""
    config = BatteryConfig()
    model = make_cell_model(config)
    for soc, pack_w in ((0.3, 43.0), (0.3, 240.0)):
        x = state_at_soc(model, soc, 293.15)
        cell_w = pack_w / config.cells_in_series

        def load(_t, state=None, cell_w=cell_w):
            if state is None:
                return model.InputContainer({"i": cell_w / 4.0})
            return model.InputContainer({"i": cell_w / float(model.output(state)["v"])})

        start = time.perf_counter()
        result = model.simulate_to_threshold(
            load, x=model.StateContainer(x[:, None]), dt=1.0, save_freq=1e9, events="EOD"
        )
        full_s = time.perf_counter() - start
        predicted = predict_eod(model, x, cell_w)
        fast_ms = _median_ms(lambda x=x, cell_w=cell_w: predict_eod(model, x, cell_w), n=20)
        eod = float(result.times[-1])
        tag = {"soc": soc, "load_w": pack_w}
        emit("full_simulation_to_eod", full_s * 1e3, "ms", simulated_s=round(eod), **tag)
        emit("quasi_steady_prediction", fast_ms, "ms", **tag)
        emit("prediction_error", (predicted - eod) / eod * 100.0, "%", **tag)


def bench_import() -> None:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import ow_power.battery"], check=True)
    emit("import_battery_module", time.perf_counter() - start, "s", note="progpy, scipy, pandas")


if __name__ == "__main__":
    bench_update()
    bench_parts()
    bench_prediction_vs_full_simulation()
    bench_import()
