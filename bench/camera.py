"""ow_cameras benchmarks: one JSON line per metric. What a capture costs (render, stereo, the
messages), at the default 800 x 600 and at OceanWATERS' 1600 x 1200, and the point cloud's
accuracy on flat ground.

    python bench/camera.py                 # the metrics; bench/out/camera_left.png to look at
    python bench/camera.py --docs          # also docs/images/camera_left.png (the docs' picture)
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from dataclasses import replace
from pathlib import Path

import cv2
import genpy
import numpy as np

from ow_cameras.capture import Capture, Shot, StereoCamera
from ow_cameras.config import CameraConfig, StereoConfig
from ow_cameras.conversions import cloud_msg, image_msg
from ow_description.description import STOWED, UNSTOWED
from ow_description.terrain import HeightMap
from ow_sim_bullet.terrains import parse_terrain_spec

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "bench" / "out"
DOCS_PICTURE = ROOT / "docs" / "images" / "camera_left.png"
#: bytes, the largest picture the docs take.
DOCS_PICTURE_LIMIT = 150_000
#: The arm unstowed, the mast pointing the cameras at its scoop over the workspace.
WORKSPACE = {**UNSTOWED, "j_ant_pan": 1.32, "j_ant_tilt": 0.5}
#: Bare flat ground 1.6 to 2.3 m away (the unit test's view).
GROUND = {**STOWED, "j_ant_pan": 3.1, "j_ant_tilt": 0.9}
GROUND_Z = -0.155


def emit(metric: str, value: float, unit: str, **extra: object) -> None:
    print(
        json.dumps(
            {"bench": "camera", "metric": metric, "value": round(value, 4), "unit": unit, **extra}
        ),
        flush=True,
    )


def shot(joints: dict[str, float], terrain: HeightMap) -> Shot:
    return Shot(joints, 0, terrain, 0.001, {"left": 1.0, "right": 1.0})


def bench_capture(config: CameraConfig, repeats: int, label: str) -> Capture:
    """Median wall and CPU time of a capture of the workspace (the first one, which builds the
    terrain mesh, left out)."""
    camera = StereoCamera(config)
    terrain = parse_terrain_spec("europa:7")
    try:
        capture = camera.capture(shot(WORKSPACE, terrain))
        walls, cpus, renders, stereos, messages = [], [], [], [], []
        for _ in range(repeats):
            wall, cpu = time.perf_counter(), time.process_time()
            capture = camera.capture(shot(WORKSPACE, terrain))
            walls.append(time.perf_counter() - wall)
            cpus.append(time.process_time() - cpu)
            renders.append(capture.timings_s["render"])
            stereos.append(capture.timings_s["stereo"])
            start = time.perf_counter()
            assert capture.left is not None and capture.cloud is not None
            for msg in (
                image_msg(capture.left, genpy.Time(), "f"),
                image_msg(capture.right, genpy.Time(), "f"),
                cloud_msg(capture.cloud.points, capture.left, genpy.Time(), "f"),
            ):
                msg.serialize(_Sink())
            messages.append(time.perf_counter() - start)
    finally:
        camera.close()
    size = f"{config.width}x{config.height}"
    extra = {"size": size, "disparities": config.stereo.num_disparities, "repeats": repeats}
    emit(f"capture_{label}", statistics.median(walls) * 1e3, "ms", **extra)
    emit(f"capture_cpu_{label}", statistics.median(cpus) * 1e3, "ms", **extra)
    emit(f"render_{label}", statistics.median(renders) * 1e3, "ms", **extra)
    emit(f"stereo_{label}", statistics.median(stereos) * 1e3, "ms", **extra)
    emit(f"messages_{label}", statistics.median(messages) * 1e3, "ms", **extra)
    return capture


class _Sink:
    """A write-only buffer: serialisation cost without keeping the bytes."""

    def write(self, data: bytes) -> None:
        pass


def bench_accuracy(config: CameraConfig, label: str) -> None:
    """The cloud of flat ground against the true plane (the unit test's scene)."""
    camera = StereoCamera(config)
    try:
        capture = camera.capture(shot(GROUND, HeightMap.flat(GROUND_Z, 4.0, 0.1)))
    finally:
        camera.close()
    assert capture.cloud is not None
    cloud, X = capture.cloud, capture.X_base_left
    points = cloud.points[cloud.valid] @ X[:3, :3].T + X[:3, 3]
    error = points[:, 2] - GROUND_Z
    band = config.stereo.min_disparity + config.stereo.num_disparities
    extra = {"size": f"{config.width}x{config.height}", "range_m": "1.6-2.3"}
    emit(f"cloud_median_abs_dz_{label}", float(np.median(np.abs(error))) * 1e3, "mm", **extra)
    emit(f"cloud_median_dz_{label}", float(np.median(error)) * 1e3, "mm", **extra)
    emit(f"cloud_p95_abs_dz_{label}", float(np.percentile(np.abs(error), 95)) * 1e3, "mm", **extra)
    emit(f"cloud_valid_{label}", float(cloud.valid[:, band:].mean()), "fraction", **extra)
    emit(f"cloud_valid_all_{label}", float(cloud.valid.mean()), "fraction", **extra)


def write_picture(capture: Capture, path: Path, limit: int | None = None) -> None:
    assert capture.left is not None
    path.parent.mkdir(parents=True, exist_ok=True)
    ok, png = cv2.imencode(".png", capture.left[:, :, ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
    assert ok
    if limit is not None and len(png) > limit:
        msg = f"{path}: {len(png)} bytes is more than the docs take ({limit})"
        raise SystemExit(msg)
    path.write_bytes(png.tobytes())
    emit("picture", len(png) / 1e3, "kB", path=str(path.relative_to(ROOT)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--docs", action="store_true", help=f"also write {DOCS_PICTURE}")
    args = parser.parse_args()
    emit("load_average", os.getloadavg()[0], "1", cores=os.cpu_count())
    default = CameraConfig()
    capture = bench_capture(default, repeats=5, label="default")
    write_picture(capture, OUT / "camera_left.png")
    if args.docs:
        small = replace(default, width=400, height=300, stereo=StereoConfig(num_disparities=96))
        camera = StereoCamera(small)
        try:
            picture = camera.capture(shot(WORKSPACE, parse_terrain_spec("europa:7")))
        finally:
            camera.close()
        write_picture(picture, DOCS_PICTURE, DOCS_PICTURE_LIMIT)
    bench_accuracy(default, "default")
    oceanwaters = replace(
        default, width=1600, height=1200, stereo=replace(default.stereo, num_disparities=672)
    )
    bench_capture(oceanwaters, repeats=2, label="oceanwaters")
    bench_accuracy(oceanwaters, "oceanwaters")


if __name__ == "__main__":
    main()
