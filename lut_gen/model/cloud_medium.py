"""The cloud medium: droplet scattering as both the cloud layer (lut_gen/clouds) and its Monte
Carlo reference (lut_gen/verify/slab_monte_carlo.py) define it.

Water-droplet clouds scatter strongly forward (asymmetry ~0.85) with a weak backward glory; two
Henyey-Greenstein lobes (weight, g) keep the silver lining and a little back-glow. Absorption is
negligible in the visible (single-scattering albedo > 0.999), so the medium is conservative.
"""
from __future__ import annotations

import numpy as np

PHASE_LOBES = ((0.9, 0.8), (0.1, -0.3))
ASYMMETRY = sum(w * g for w, g in PHASE_LOBES)


def henyey_greenstein(cos_theta, g):
    return (1.0 - g * g) / (4.0 * np.pi * np.power(1.0 + g * g - 2.0 * g * cos_theta, 1.5))


def phase(cos_theta):
    """The cloud phase function (per steradian, integrates to 1) of the scattering angle's cosine."""
    cos_theta = np.asarray(cos_theta, dtype=np.float64)
    return sum(w * henyey_greenstein(cos_theta, g) for w, g in PHASE_LOBES)
