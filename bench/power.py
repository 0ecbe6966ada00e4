"""ow_power benchmarks: one JSON line per metric (power update, bag writing, analysis).

Also writes bench/out/power_demo.png, a synthetic run with a ground contact, to look at.
"""

import json
import tempfile
import time
from pathlib import Path

import numpy as np

from ow_description.description import ALL_JOINTS, DEFAULT_GROUND_Z
from ow_power.analysis import analyze, plot_power
from ow_power.bagwriter import SplitBagWriter
from ow_power.config import PowerConfig
from ow_power.model import PowerIntegrator
from ow_power.synthetic import BagMessages, Segment, write_run

OUT = Path(__file__).resolve().parent / "out"


def emit(metric: str, value: float, unit: str, **extra: object) -> None:
    print(
        json.dumps(
            {"bench": "power", "metric": metric, "value": round(value, 4), "unit": unit, **extra}
        )
    )


def bench_update() -> None:
    integrator = PowerIntegrator(PowerConfig())
    velocity, effort = np.full(9, 0.1), np.full(9, 20.0)
    n = 20000
    start = time.perf_counter()
    for k in range(n):
        integrator.update(k * 0.01, ALL_JOINTS, velocity, effort)
    emit("power_update", (time.perf_counter() - start) / n * 1e6, "us", joints=9)


def bench_write_and_analyze(directory: Path) -> None:
    messages = BagMessages()
    ros1_type, md5, msgdef, data = messages.serialize(
        "sensor_msgs/msg/JointState",
        header=messages.header(0),
        name=list(ALL_JOINTS),
        position=np.zeros(9),
        velocity=np.zeros(9),
        effort=np.zeros(9),
    )
    writer = SplitBagWriter(directory / "write", split_duration_s=60.0)
    n = 60000  # 10 min at 100 Hz
    start = time.perf_counter()
    for k in range(n):
        writer.write("/joint_states", ros1_type, md5, msgdef, (k + 1) * 10**7, data)
    writer.close()
    emit("bag_write", n / (time.perf_counter() - start), "msg/s", bytes_per_msg=len(data))

    segment_s = 60.0  # 10 operations of 1 min: 60k joint states and 60k power messages
    segments = [
        Segment(f"op{i}", segment_s, {"j_shou_pitch": 0.1}, {"j_shou_pitch": 10.0 * i})
        for i in range(10)
    ]
    run = SplitBagWriter(directory / "run", split_duration_s=60.0)
    write_run(run, segments, ALL_JOINTS)
    run.close()
    start = time.perf_counter()
    result = analyze([directory / "run"])
    elapsed = time.perf_counter() - start
    emit("analyze_10_min_run", elapsed, "s", samples=len(result.power), bags=len(result.bags))
    error = abs(
        result.total["mechanical_energy_j"] - sum(s.power_w() * segment_s for s in segments)
    )
    emit("analyze_energy_error", error, "J")


def demo_plot(directory: Path) -> None:
    """A Figure-18-like trace: approach, contact (power rises), hold."""
    writer = SplitBagWriter(directory / "demo")
    segments = [
        Segment(
            "unstow",
            4.0,
            {"j_shou_pitch": 0.1, "j_prox_pitch": -0.1},
            {"j_shou_pitch": 60.0, "j_prox_pitch": -20.0},
        ),
        Segment("guarded_move", 3.0, {"j_shou_pitch": -0.05}, {"j_shou_pitch": 30.0}),
        Segment("guarded_move", 1.0, {"j_shou_pitch": -0.02}, {"j_shou_pitch": 400.0}),
        Segment(
            "grind",
            5.0,
            {"j_grinder": 0.1, "j_hand_yaw": 0.05},
            {"j_grinder": 1.0, "j_hand_yaw": 40.0},
        ),
    ]
    end_s = write_run(writer, segments, ALL_JOINTS)
    contact_ns = round((10.0 + 7.0) * 1e9)
    ros1_type, md5, msgdef, data = messages_for_contact(contact_ns)
    writer.write("/guarded_move_result", ros1_type, md5, msgdef, contact_ns, data)
    writer.close()
    OUT.mkdir(exist_ok=True)
    plot_power(analyze([directory / "demo"]), OUT / "power_demo.png")
    emit("demo_plot_written", end_s, "s_sim_end", path=str(OUT / "power_demo.png"))


def messages_for_contact(stamp_ns: int) -> tuple[str, str, str, bytes]:
    messages = BagMessages()
    point = messages.store.types["geometry_msgs/msg/Point"](x=2.0, y=0.0, z=DEFAULT_GROUND_Z)
    return messages.serialize(
        "ow_msgs/msg/GuardedMoveResult",
        header=messages.header(stamp_ns),
        success=True,
        position=point,
        frame="base_link",
    )


if __name__ == "__main__":
    bench_update()
    with tempfile.TemporaryDirectory() as tmp:
        bench_write_and_analyze(Path(tmp))
        demo_plot(Path(tmp))
