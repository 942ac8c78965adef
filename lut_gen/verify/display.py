"""Comparing renders in display values, as the light-shaft tests and benches do: one fixed
exposure from the reference's log-average luminance (middle grey 0.18), a Reinhard curve, and
the PSNR between the two displayed images (the techniques' bar is 40 dB)."""
from __future__ import annotations

import numpy as np

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def exposure_of(reference) -> float:
    """The exposure that puts the log-average luminance of ``reference`` (..., 3) at 0.18."""
    luminance = np.asarray(reference) @ LUMINANCE
    return float(0.18 / np.exp(np.mean(np.log(np.maximum(luminance, 0) + 1e-6))))


def display(radiance, exposure):
    x = np.asarray(radiance) * exposure
    return np.clip(x / (1.0 + x), 0.0, 1.0)


def psnr(a, b) -> float:
    return float(10.0 * np.log10(1.0 / max(np.mean((np.asarray(a) - np.asarray(b)) ** 2), 1e-20)))


def display_psnr(image, reference) -> float:
    """PSNR (dB) of ``image`` against ``reference``, both shown through the reference's exposure."""
    exposure = exposure_of(reference)
    return psnr(display(image, exposure), display(reference, exposure))
