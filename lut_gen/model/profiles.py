"""Density profiles of the media, relative to sea level (dimensionless): the one place that says
how each medium thins with height. Every integrator (the bake, the spectral fit, the references)
reads the media through ``densities``."""
from __future__ import annotations

import numpy as np

OZONE_PEAK_HEIGHT_M = 25_000.0
OZONE_HALF_WIDTH_M = 15_000.0


def rayleigh_density(params, height_m):
    return np.exp(-np.maximum(height_m, 0.0) / params.rayleigh_scale_height)


def mie_density(params, height_m):
    return np.exp(-np.maximum(height_m, 0.0) / params.mie_scale_height)


def ozone_density(params, height_m):
    """Bruneton's tent profile: 0 below 10 km and above 40 km, 1 at 25 km."""
    tent = 1.0 - np.abs(np.asarray(height_m) - OZONE_PEAK_HEIGHT_M) / OZONE_HALF_WIDTH_M
    return np.clip(tent, 0.0, 1.0)


def fog_density(params, height_m):
    """The fog layer: exponential with its own scale height (params.fog_height); its extinction
    at the ground is params.fog (0 without fog)."""
    return np.exp(-np.maximum(height_m, 0.0) / params.fog_height)


MEDIA = ("rayleigh", "mie", "ozone", "fog")


def densities(params, height_m) -> np.ndarray:
    """(..., 4) Rayleigh, Mie, ozone and fog densities at the given heights (MEDIA's order, the
    rows of AtmosphereParams.extinction_matrix)."""
    h = np.asarray(height_m)
    return np.stack([rayleigh_density(params, h), mie_density(params, h), ozone_density(params, h),
                     fog_density(params, h)], axis=-1)
