"""The medium and the geometry of the atmosphere's Monte Carlo path tracer
(lut_gen.verify.monte_carlo): the media's three-channel coefficients and densities, rays in the
spherical shell, and directions about an axis. Also the cloud tracer's air
(lut_gen.verify.cloud_monte_carlo).

Only the media definitions of lut_gen.model (densities, phase functions) are shared with the
baker. Fog (``params.has_fog``): a fourth medium, grey, that only scatters (scattering =
extinction = params.fog x exp(-h / fog_height)).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.profiles import fog_density, mie_density, ozone_density, rayleigh_density
from ..model.atmosphere import AtmosphereParams


@dataclass(frozen=True)
class _Media:
    """Three-channel coefficients of the media (1/m at unit density)."""

    params: AtmosphereParams
    rayleigh: np.ndarray     # (3,) scattering = extinction
    mie: np.ndarray          # (3,) scattering
    extinction: np.ndarray   # (media: Rayleigh, Mie, ozone and, with fog only, fog; 3 channels)
    fog: np.ndarray          # (3,) fog scattering = extinction (grey; 0 without fog)

    @classmethod
    def of(cls, params: AtmosphereParams) -> "_Media":
        rayleigh = np.asarray(params.rayleigh_scattering, dtype=np.float64)
        mie = np.asarray(params.mie_scattering, dtype=np.float64) * params.aerosol_density
        ozone = np.asarray(params.ozone_absorption, dtype=np.float64) * (1.0 if params.ozone else 0.0)
        fog = np.full(3, params.fog if params.has_fog else 0.0)
        rows = [rayleigh, mie * (1.0 + params.aerosol_absorption), ozone] + ([fog] if params.has_fog else [])
        return cls(params, rayleigh, mie, np.stack(rows), fog)

    @property
    def has_fog(self) -> bool:
        return bool(self.params.has_fog)

    @property
    def earth_radius(self) -> float:
        return self.params.earth_radius

    @property
    def top_radius(self) -> float:
        return self.params.top_radius

    def densities(self, radius: np.ndarray):
        """Rayleigh, Mie, ozone and (with fog only) fog densities at the given radii, one per row
        of ``extinction`` (ozone None without ozone)."""
        h = np.maximum(radius - self.earth_radius, 0.0)
        ozone = ozone_density(self.params, h) if self.params.ozone else None
        out = (rayleigh_density(self.params, h), mie_density(self.params, h), ozone)
        return out + (fog_density(self.params, h),) if self.has_fog else out

    def scattering(self, radius: np.ndarray):
        """(N, 3) Rayleigh, (N, 3) Mie and (N, 3) fog scattering coefficients per channel at the
        radii (the fog's None without fog)."""
        h = np.maximum(radius - self.earth_radius, 0.0)
        fog = fog_density(self.params, h)[:, None] * self.fog if self.has_fog else None
        return (rayleigh_density(self.params, h)[:, None] * self.rayleigh,
                mie_density(self.params, h)[:, None] * self.mie, fog)


# -- geometry ----------------------------------------------------------------------------------

def _norm(x: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ni,ni->n", x, x))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ni,ni->n", a, b)


def _distance_to_top(media: _Media, r, mu):
    disc = r * r * (mu * mu - 1.0) + media.top_radius ** 2
    return np.maximum(-r * mu + np.sqrt(np.maximum(disc, 0.0)), 0.0)


def _ground_hit(media: _Media, r, mu):
    """(hits, distance): whether the ray meets the Earth in front (tangent rays do not), and
    the distance to it, in a form without cancellation for grazing rays near the ground."""
    big_r = media.earth_radius
    rise = np.maximum(r * r - big_r * big_r, 0.0)
    hits = mu < -np.sqrt(rise) / r
    root = np.sqrt(np.maximum(r * r * mu * mu - rise, 0.0))
    denominator = -r * mu + root
    distance = np.divide(rise, denominator, out=np.zeros_like(r), where=denominator > 0.0)
    return hits, distance


def _onb(z: np.ndarray):
    """Two unit vectors completing the unit vectors z (N, 3) to orthonormal frames
    (Duff et al. 2017, branchless)."""
    sign = np.where(z[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z[:, 2])
    b = z[:, 0] * z[:, 1] * a
    e1 = np.stack([1.0 + sign * z[:, 0] ** 2 * a, sign * b, -sign * z[:, 0]], axis=-1)
    e2 = np.stack([b, sign + z[:, 1] ** 2 * a, -z[:, 1]], axis=-1)
    return e1, e2


def _around(axis: np.ndarray, cos_theta: np.ndarray, rng) -> np.ndarray:
    """Unit vectors at the given angle to ``axis`` (N, 3), uniform in azimuth."""
    e1, e2 = _onb(axis)
    phi = 2.0 * math.pi * rng.random(axis.shape[0])
    sin_theta = np.sqrt(np.maximum(1.0 - cos_theta * cos_theta, 0.0))
    return (cos_theta[:, None] * axis
            + (sin_theta * np.cos(phi))[:, None] * e1 + (sin_theta * np.sin(phi))[:, None] * e2)
