"""The terrain's surface texture: procedural ice regolith, seamless, the same for a seed (no ROS).

A stereo matcher needs texture: TinyRenderer draws a plain height field as one flat colour, on
which no block matches another any better than its neighbours. This albedo map has grain at three
scales (about 3, 10 and 40 mm) so that the ground seen from the mast (1 to 2 mm per pixel at 2-3 m)
carries detail at every distance the matcher works at; it repeats every :data:`TILE_M` metres,
far beyond any disparity search range.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

#: texels per side.
TEXELS = 1024
#: m, side of the square of ground one copy of the texture covers.
TILE_M = 2.0
#: Mean albedo and the grain's standard deviation at each scale (sigma in texels).
MEAN_ALBEDO = 0.72
GRAIN = ((1.2, 0.10), (4.0, 0.07), (16.0, 0.05))
#: Tint of the ice (multiplies the grey albedo per channel: a faintly blue white).
TINT = (0.94, 0.96, 1.0)


def _periodic_noise(rng: np.random.Generator, sigma_texels: float) -> npt.NDArray[np.float64]:
    """Gaussian noise low-passed with a Gaussian of ``sigma_texels``, wrapped at the edges, unit
    standard deviation."""
    noise = rng.standard_normal((TEXELS, TEXELS))
    k = np.fft.fftfreq(TEXELS)
    kernel = np.exp(-2.0 * (np.pi * sigma_texels) ** 2 * (k[:, None] ** 2 + k[None, :] ** 2))
    smooth = np.real(np.fft.ifft2(np.fft.fft2(noise) * kernel))
    return smooth / smooth.std()


def regolith_albedo(seed: int = 0) -> npt.NDArray[np.uint8]:
    """(TEXELS, TEXELS, 3) RGB albedo map (255 = albedo 1), seamless in both directions."""
    rng = np.random.default_rng(seed)
    grey = MEAN_ALBEDO + sum(std * _periodic_noise(rng, sigma) for sigma, std in GRAIN)
    grey = np.clip(grey, 0.05, 1.0)
    rgb = grey[:, :, None] * np.asarray(TINT)[None, None, :]
    return np.round(rgb * 255.0).astype(np.uint8)


def write_texture(path: Path, seed: int = 0) -> Path:
    """Write :func:`regolith_albedo` as a PNG at ``path`` (for ``pybullet.loadTexture``)."""
    if not cv2.imwrite(str(path), regolith_albedo(seed)[:, :, ::-1]):
        msg = f"cannot write the terrain texture to {path}"
        raise OSError(msg)
    return path
