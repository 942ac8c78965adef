"""How a march of few steps errs against a fine one, split into banding and noise (for the
jittered steps, lut_gen.passes.jitter): the error image relative to the shaft's own size (the
largest |unshadowed - shadowed| luminance of the reference), over sky pixels away from any
surface's silhouette (where the depth jump, not the march, makes the error).

- ``banding``: the largest error after a Gaussian blur of ``sigma`` pixels, what the eye sees
  of structured error at a few pixels' distance (noise averages out there, bands do not);
- ``banding_step``: the largest step between horizontal neighbours of that blurred error;
- ``pixel_step``: the largest step between horizontal neighbours of the raw error (bands'
  edges without jitter, noise with it);
- ``mean_abs`` and ``bias``: the raw error's mean absolute and mean signed value.
"""
from __future__ import annotations

import numpy as np

from .display import LUMINANCE



def _blur(image, sigma):
    radius = max(int(3 * sigma), 1)
    kernel = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    kernel /= kernel.sum()
    padded = np.pad(image, radius, mode="edge")
    rows = np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="valid"), 1, padded)
    return np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="valid"), 0, rows)


def measure(image, reference, unshadowed, sky, sigma: float = 1.5, margin: int = 4) -> dict:
    """The error of ``image`` (H, W, 3) against ``reference`` (both with shafts), as fractions
    of the shafts' size (``unshadowed``: the reference without shafts); ``sky``: (H, W) bool."""
    signal = np.abs((unshadowed - reference) @ LUMINANCE).max()
    error = (image - reference) @ LUMINANCE / max(signal, 1e-20)
    inner = np.asarray(sky, dtype=bool).copy()
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            inner &= np.roll(np.roll(sky, dy, axis=0), dx, axis=1)
    pairs = inner[:, 1:] & inner[:, :-1]
    blurred = _blur(error, sigma)
    return {"banding": float(np.abs(blurred[inner]).max()),
            "banding_step": float(np.abs(np.diff(blurred, axis=1))[pairs].max()),
            "pixel_step": float(np.abs(np.diff(error, axis=1))[pairs].max()),
            "mean_abs": float(np.abs(error[inner]).mean()),
            "bias": float(error[inner].mean())}
