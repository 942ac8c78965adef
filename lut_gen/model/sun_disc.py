"""The sun's disc as the world shows it: limb-darkened, sized by the Sun lamp's angle.

Limb darkening follows Hestroffer & Magnan (1998, A&A 333, 338): I(mu) / I(1) = mu^alpha with
alpha(lambda) = -0.023 + 0.292 / lambda[um], mu the cosine of the angle between the line of
sight and the solar surface normal (mu = sqrt(1 - rho^2) at rho = the fraction of the disc's
radius). Evaluated at the sample's 680/550/440 nm for red, green and blue: the limb is darker
and redder than the centre, as photographs of the sun show. The profile is normalised so that
it averages to 1 over the disc: the disc still integrates to the lamp's irradiance.
"""
from __future__ import annotations

import math

import numpy as np

WAVELENGTHS_UM = (0.680, 0.550, 0.440)
LIMB_DARKENING_ALPHA = tuple(-0.023 + 0.292 / lam for lam in WAVELENGTHS_UM)


def limb_profile(cos_sun_view, angular_diameter_rad: float) -> np.ndarray:
    """(..., 3) disc radiance relative to a uniform disc of the same irradiance; 0 outside."""
    radius = 0.5 * angular_diameter_rad
    angle = np.arccos(np.clip(np.asarray(cos_sun_view, dtype=np.float64), -1.0, 1.0))
    mu = np.sqrt(np.clip(1.0 - (angle / radius) ** 2, 0.0, 1.0))
    alpha = np.asarray(LIMB_DARKENING_ALPHA)
    profile = mu[..., None] ** alpha * (alpha + 2.0) / 2.0
    return np.where((angle < radius)[..., None], profile, 0.0)


def disc_solid_angle(angular_diameter_rad: float) -> float:
    return 2.0 * math.pi * (1.0 - math.cos(0.5 * angular_diameter_rad))
