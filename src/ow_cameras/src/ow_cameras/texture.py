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


def _periodic_noise(rng: np.random.Generator, sigma_texels: float) -> npt.NDArray[np.float32]:
    """Gaussian noise low-passed with a Gaussian of ``sigma_texels``, wrapped at the edges, unit
    standard deviation. In single precision and through the real FFT: the texture ends as 8-bit
    values, and the double-precision complex transforms made the camera node's set-up 70 MB
    larger for nothing."""
    noise = rng.standard_normal((TEXELS, TEXELS), dtype=np.float32)
    ky = np.fft.fftfreq(TEXELS).astype(np.float32)
    kx = np.fft.rfftfreq(TEXELS).astype(np.float32)
    gain = np.float32(-2.0 * (np.pi * sigma_texels) ** 2)
    kernel = np.exp(gain * (ky[:, None] ** 2 + kx[None, :] ** 2))
    spectrum = np.fft.rfft2(noise)
    del noise
    spectrum *= kernel
    smooth = np.fft.irfft2(spectrum, s=(TEXELS, TEXELS)).astype(np.float32, copy=False)
    smooth /= smooth.std()
    return smooth


def regolith_albedo(seed: int = 0) -> npt.NDArray[np.uint8]:
    """(TEXELS, TEXELS, 3) RGB albedo map (255 = albedo 1), seamless in both directions."""
    rng = np.random.default_rng(seed)
    grey = np.full((TEXELS, TEXELS), MEAN_ALBEDO, dtype=np.float32)
    for sigma, std in GRAIN:
        grey += np.float32(std) * _periodic_noise(rng, sigma)
    np.clip(grey, 0.05, 1.0, out=grey)
    rgb = np.empty((TEXELS, TEXELS, 3), dtype=np.uint8)
    for channel, tint in enumerate(TINT):
        rgb[:, :, channel] = np.round(grey * np.float32(tint * 255.0))
    return rgb


def write_texture(path: Path, seed: int = 0) -> Path:
    """Write :func:`regolith_albedo` as a PNG at ``path`` (for ``pybullet.loadTexture``)."""
    if not cv2.imwrite(str(path), regolith_albedo(seed)[:, :, ::-1]):
        msg = f"cannot write the terrain texture to {path}"
        raise OSError(msg)
    return path
