"""Terrain specifications: ``flat:<z>``, ``europa:<seed>`` and ``file:<path>`` -> HeightMap.

All heights are z in ``base_link`` (m). The generated grids cover x in [-1.5, 3.5] m and
y in [-2.4, 2.6] m at 4 cm, everything the arm can reach (the shoulder is at x 0.79, y 0.175 and
the arm reaches about 2.3 m from it). The 4 cm cells are a compromise: Bullet's contact cost grows
with the number of heightfield triangles under a tool (about 4x slower at 2 cm).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ow_description.description import DEFAULT_GROUND_Z
from ow_description.errors import TerrainError
from ow_description.terrain import HeightMap
from ow_sim_bullet.errors import TerrainSpecError

FloatArray = npt.NDArray[np.float64]

#: m, grid of the generated terrains.
GRID_RESOLUTION = 0.04
GRID_X = (-1.5, 3.5)
GRID_Y = (-2.4, 2.6)
#: m, centre and half-axes of the smooth digging workspace in front of the arm.
WORKSPACE_CENTRE = (1.75, 0.05)
WORKSPACE_HALF_AXES = (0.75, 0.95)
#: m, half extent of the lander's footprint (footpads at |x|, |y| = 1.1 +- 0.09).
LANDER_HALF_EXTENT = 1.25
#: m, largest |z| in base_link a terrain may have anywhere. The arm reaches about 2.3 m from a
#: shoulder 0.27 m above base_link; heights far beyond are a mistake (a unit, a sign, 1e308) and
#: would overflow Bullet's heightfield and the carving arithmetic.
MAX_TERRAIN_HEIGHT_M = 10.0


def _grid() -> tuple[FloatArray, FloatArray]:
    cols = round((GRID_X[1] - GRID_X[0]) / GRID_RESOLUTION) + 1
    rows = round((GRID_Y[1] - GRID_Y[0]) / GRID_RESOLUTION) + 1
    xs = GRID_X[0] + GRID_RESOLUTION * np.arange(cols)
    ys = GRID_Y[0] + GRID_RESOLUTION * np.arange(rows)
    return np.meshgrid(xs, ys)


def flat(z: float) -> HeightMap:
    """A plane at height ``z`` (m, base_link) on the standard grid."""
    gx, _ = _grid()
    return HeightMap(np.full(gx.shape, float(z)), GRID_RESOLUTION, GRID_X[0], GRID_Y[0])


def _smooth_noise(
    rng: np.random.Generator, shape: tuple[int, int], sigma_cells: float
) -> FloatArray:
    """Gaussian-filtered white noise with unit standard deviation (periodic FFT filter)."""
    noise = rng.standard_normal(shape)
    ky = np.fft.fftfreq(shape[0])[:, None]
    kx = np.fft.fftfreq(shape[1])[None, :]
    kernel = np.exp(-2.0 * (math.pi * sigma_cells) ** 2 * (kx**2 + ky**2))
    smooth = np.real(np.fft.ifft2(np.fft.fft2(noise) * kernel))
    return smooth / smooth.std()


def _smoothstep(edge0: float, edge1: float, x: FloatArray) -> FloatArray:
    t = np.clip((x - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def europa(seed: int) -> HeightMap:
    """Procedural ice: a smooth workspace at about -0.155 m, rough ice with penitentes beyond.

    The workspace in front of the arm (an ellipse around x 1.75, y 0.05 with half-axes 0.75 and
    0.95 m) and the ground under the lander undulate by a few millimetres around the reference
    ground height. Away from them the ice is rough (centimetres) and carries penitente-like spikes:
    blades 0.15 to 0.45 m tall, elongated along y. The same seed gives the same terrain.

    Args:
        seed: seed of the random generator (>= 0).
    """
    rng = np.random.default_rng(seed)
    gx, gy = _grid()
    shape = gx.shape
    undulation = _smooth_noise(rng, shape, sigma_cells=7.5)
    roughness = _smooth_noise(rng, shape, sigma_cells=1.25)
    ellipse = np.hypot(
        (gx - WORKSPACE_CENTRE[0]) / WORKSPACE_HALF_AXES[0],
        (gy - WORKSPACE_CENTRE[1]) / WORKSPACE_HALF_AXES[1],
    )
    under_lander = (np.abs(gx) < LANDER_HALF_EXTENT) & (np.abs(gy) < LANDER_HALF_EXTENT)
    rough_weight = _smoothstep(1.0, 1.5, ellipse) * ~under_lander
    heights = (
        DEFAULT_GROUND_Z
        + 0.004 * undulation
        + rough_weight * (0.04 * undulation + 0.012 * roughness)
    )

    # Penitentes only where the ice is fully rough.
    res = GRID_RESOLUTION
    candidates = np.argwhere(rough_weight > 0.99)
    count = len(candidates) // 150
    for r, c in candidates[rng.choice(len(candidates), size=count, replace=False)]:
        height = rng.uniform(0.15, 0.45)
        half_x = rng.uniform(0.04, 0.09)
        half_y = half_x * rng.uniform(1.5, 3.0)
        dr, dc = math.ceil(half_y / res), math.ceil(half_x / res)
        r0, r1 = max(r - dr, 0), min(r + dr + 1, shape[0])
        c0, c1 = max(c - dc, 0), min(c + dc + 1, shape[1])
        local = np.hypot(
            (gx[r0:r1, c0:c1] - gx[r, c]) / half_x, (gy[r0:r1, c0:c1] - gy[r, c]) / half_y
        )
        spike = height * np.clip(1.0 - local, 0.0, None) ** 1.5
        heights[r0:r1, c0:c1] = np.maximum(heights[r0:r1, c0:c1], heights[r, c] + spike)
    return HeightMap(heights, GRID_RESOLUTION, GRID_X[0], GRID_Y[0])


def load_file(
    path: Path,
    resolution: float,
    centre: tuple[float, float],
    png_height_range: tuple[float, float],
) -> HeightMap:
    """Read a height map from ``.npy``, ``.npz`` or a 16-bit (or 8-bit) grayscale ``.png``.

    Grid layout: row index along +y, column index along +x, heights in m (base_link z).
    ``.npy``: a 2-D float array of heights; the grid has ``resolution`` m cells and is centred on
    ``centre``. ``.npz``: key ``heights`` as for ``.npy``, optional scalar keys ``resolution``,
    ``origin_x``, ``origin_y`` (centre of cell (0, 0)) override the parameters. ``.png``: seen from
    above with +x to the right and +y up (the top image row is the largest y); pixel value v maps
    to ``z_low + v / v_max * (z_high - z_low)`` with ``(z_low, z_high) = png_height_range`` and
    v_max 65535 (16-bit) or 255 (8-bit); cells and centre as for ``.npy``.

    Raises:
        TerrainSpecError: the file is missing, unreadable, of an unknown type or not a valid grid,
            or holds a height that is not finite or beyond +-:data:`MAX_TERRAIN_HEIGHT_M` m.
    """
    if not path.is_file():
        msg = f"terrain file {path} does not exist"
        raise TerrainSpecError(msg)
    suffix = path.suffix.lower()
    origin: tuple[float, float] | None = None
    try:
        if suffix == ".npy":
            heights = np.load(path, allow_pickle=False)
        elif suffix == ".npz":
            with np.load(path, allow_pickle=False) as data:
                if "heights" not in data:
                    msg = f"terrain file {path} has no 'heights' array (keys: {sorted(data)})"
                    raise TerrainSpecError(msg)
                heights = data["heights"]
                resolution = float(data["resolution"]) if "resolution" in data else resolution
                if "origin_x" in data and "origin_y" in data:
                    origin = (float(data["origin_x"]), float(data["origin_y"]))
        elif suffix == ".png":
            heights = _read_png(path, png_height_range)
        else:
            msg = f"terrain file {path} has unknown type {suffix!r}; use .npy, .npz or .png"
            raise TerrainSpecError(msg)
    except (OSError, ValueError) as error:
        msg = f"cannot read terrain file {path}: {error}"
        raise TerrainSpecError(msg) from error
    heights = np.asarray(heights)
    if heights.ndim != 2 or not np.issubdtype(heights.dtype, np.number):
        msg = f"terrain file {path} must hold a 2-D numeric grid, got shape {heights.shape}"
        raise TerrainSpecError(msg)
    if origin is None:
        rows, cols = heights.shape
        origin = (centre[0] - (cols - 1) * resolution / 2, centre[1] - (rows - 1) * resolution / 2)
    heights = heights.astype(np.float64)
    check_heights(heights, f"terrain file {path}")
    try:
        return HeightMap(heights, resolution, origin[0], origin[1])
    except TerrainError as error:
        msg = f"terrain file {path}: {error}"
        raise TerrainSpecError(msg) from error


def check_heights(heights: FloatArray, what: str) -> None:
    """Refuse finite heights beyond :data:`MAX_TERRAIN_HEIGHT_M` (non-finite ones are refused
    where they are parsed: ``float`` for flat, :class:`HeightMap` for files).

    Args:
        heights: m, base_link z, any shape.
        what: the source, named in the message.

    Raises:
        TerrainSpecError: naming the first bad value and the limit.
    """
    bad = np.isfinite(heights) & (np.abs(heights) > MAX_TERRAIN_HEIGHT_M)
    if np.count_nonzero(bad):
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        value = float(heights[index])
        where = f" at cell {index}" if heights.ndim else ""
        msg = (
            f"{what}: height {value:g} m{where} is outside the sane range "
            f"[-{MAX_TERRAIN_HEIGHT_M:g}, {MAX_TERRAIN_HEIGHT_M:g}] m (base_link z)"
        )
        raise TerrainSpecError(msg)


def _read_png(path: Path, height_range: tuple[float, float]) -> FloatArray:
    from PIL import Image

    with Image.open(path) as image:
        if image.mode in ("I;16", "I;16B", "I;16L", "I"):
            pixels = np.asarray(image, dtype=np.float64)
            full_scale = 65535.0
        elif image.mode == "L":
            pixels = np.asarray(image, dtype=np.float64)
            full_scale = 255.0
        else:
            msg = f"terrain image {path} must be 8- or 16-bit grayscale, got mode {image.mode}"
            raise TerrainSpecError(msg)
    low, high = height_range
    return np.flipud(low + pixels / full_scale * (high - low))


def parse_terrain_spec(
    spec: str,
    file_resolution: float = GRID_RESOLUTION,
    file_centre: tuple[float, float] = (1.5, 0.0),
    png_height_range: tuple[float, float] = (-1.0, 1.0),
) -> HeightMap:
    """Build the height map a terrain spec names.

    Args:
        spec: ``flat:<z>`` (z in m, base_link), ``europa:<seed>`` (integer >= 0) or
            ``file:<path>`` (see :func:`load_file`).
        file_resolution: m per cell for ``.npy`` and ``.png`` files.
        file_centre: (x, y) m in base_link of the centre of a file's grid.
        png_height_range: (z at pixel 0, z at full scale) m for PNG files.

    Raises:
        TerrainSpecError: unknown form, bad number, unreadable file, or a height that is not
            finite or beyond +-:data:`MAX_TERRAIN_HEIGHT_M`, with the reason.
    """
    kind, sep, arg = spec.partition(":")
    kind = kind.strip().lower()
    arg = arg.strip()
    if not sep or not arg:
        msg = f"terrain spec {spec!r} must be flat:<z>, europa:<seed> or file:<path>"
        raise TerrainSpecError(msg)
    if kind == "flat":
        try:
            z = float(arg)
        except ValueError:
            z = math.nan
        if not math.isfinite(z):
            msg = f"terrain spec {spec!r}: flat height {arg!r} is not a finite number (m)"
            raise TerrainSpecError(msg)
        check_heights(np.array(z), f"terrain spec {spec!r}")
        return flat(z)
    if kind == "europa":
        if not arg.isdigit():
            msg = f"terrain spec {spec!r}: europa seed {arg!r} must be an integer >= 0"
            raise TerrainSpecError(msg)
        return europa(int(arg))
    if kind == "file":
        return load_file(Path(arg).expanduser(), file_resolution, file_centre, png_height_range)
    msg = (
        f"terrain spec {spec!r} has unknown form {kind!r}; "
        "use flat:<z>, europa:<seed> or file:<path>"
    )
    raise TerrainSpecError(msg)
