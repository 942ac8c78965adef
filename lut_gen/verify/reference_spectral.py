"""The spectral references: a three-channel reference integrator run per wavelength and
converted to RGB, and the check that keeps spectral params out of the three-channel integrators.

The bake of spectral params integrates at a few wavelengths and converts them to RGB. The
reference integrates every 10 nm from 360 to 830 nm (48 wavelengths, as Bruneton 2017's
reference) with the three-channel integrators (lut_gen.verify.reference), three wavelengths at a
time, and converts with the same solar spectrum and colour-matching functions
(lut_gen.model.spectrum.rgb_weights).
"""
from __future__ import annotations

import numpy as np

from ..model import spectrum
from ..model.atmosphere import AtmosphereParams

__all__ = ["per_wavelength", "spectral", "REFERENCE_WAVELENGTHS_NM"]


REFERENCE_WAVELENGTHS_NM = tuple(float(v) for v in range(360, 831, 10))


def per_wavelength(integrator, params: AtmosphereParams, *args, wavelengths_nm=REFERENCE_WAVELENGTHS_NM,
                   **kwargs) -> np.ndarray:
    """(..., len(wavelengths)) ``integrator(params, *args, **kwargs)`` (a three-channel reference
    function) evaluated per wavelength on the spectral media of ``params``."""
    lam = np.asarray(wavelengths_nm, dtype=np.float64)
    padded = np.concatenate([lam, np.full(-len(lam) % 3, lam[-1])])
    parts = [integrator(spectrum.triple_params(params, padded[i:i + 3]), *args, **kwargs)
             for i in range(0, len(padded), 3)]
    return np.concatenate(parts, axis=-1)[..., :len(lam)]


def spectral(integrator, params: AtmosphereParams, *args, wavelengths_nm=REFERENCE_WAVELENGTHS_NM,
             **kwargs) -> np.ndarray:
    """(..., 3) linear Rec.709 per unit extraterrestrial sun of a three-channel reference
    integrator run per wavelength; the integrator itself for Sample 2013 (non-spectral) params."""
    if not params.spectral:
        return integrator(params, *args, **kwargs)
    radiance = per_wavelength(integrator, params, *args, wavelengths_nm=wavelengths_nm, **kwargs)
    return radiance @ spectrum.rgb_weights(wavelengths_nm).T


def _three_channel(params: AtmosphereParams) -> AtmosphereParams:
    """``params`` for a three-channel reference integrator, which takes the media's three channels
    literally: spectral params must go through ``spectral`` / ``per_wavelength`` (their RGB
    coefficients are only an approximation)."""
    if params.spectral:
        raise ValueError("spectral params: call reference.spectral(integrator, params, ...) or "
                         "reference.per_wavelength(...) instead of the three-channel integrator")
    return params
