"""Hoffman & Preetham's analytic atmosphere (2002): constant-density media, closed forms, no bake.

Hoffman & Preetham Eqs. 1-5 (numbered as in their paper), RGB, single scattering of the sun only:

- (1) L = F_ex L0 + L_in.
- (3) F_ex(s) = exp(-beta_ex s).
- (4) L_in(s, theta) = E_sun beta_sc(theta) / beta_ex (1 - exp(-beta_ex s)), beta_sc(theta) the
  Rayleigh and haze scattering coefficients times their phase functions, summed.
- (5) the optical length toward zenith angle theta (degrees) l = l_zenith / (cos theta +
  0.15 (93.885 - theta)^-1.253) (Kasten's air mass), for the sun's extinction and the sky's length.
- The sky as two shells: air and haze for s_haze, air alone for s_air - s_haze beyond.

The media are the scene's own (``AtmosphereParams``), so every aerosol control acts on the preview
as it does on the tables:

- Rayleigh: the project's RGB Rayleigh coefficients (``params.rayleigh``). For the sample-2013
  preset these are the seed's formula, 8 pi^3 (n^2 - 1)^2 / (3 N lambda^4) (6 + 3 p)/(6 - 7 p), at
  680 / 550 / 440 nm (``atmosphere.rayleigh_scattering_from_air``); for the clear sky, the
  white-balanced spectral means of the same formula's power law. Using the seed's own 650 / 570 /
  475 nm triple would give a different blue than the tables, and the preview's point is to look
  like them.
- Haze: ``params.mie`` (aerosol density and Mie colour applied) scatters, ``params.mie_extinction``
  (aerosol absorption added) extinguishes, with a Henyey-Greenstein phase of ``params.mie_g``
  (positive: forward, as the rest of the project counts it; the seed counts the angle the other
  way, hence its negative g). The seed's Table 1 looks are ``HAZE_LOOKS``; the Air Preset control
  sets the aerosol density of each (``lut_gen.model.air_presets``).
- Optical lengths at the zenith: the scale heights of the profiles (an exponential profile's
  integral from the ground up), 7994 m and 1200 m by default, where the seed rounds to 8.4 and
  1.25 km for its profiles. From a camera at height h they shrink by exp(-h / H).

The sky's length for a ray that hits nothing: the seed sizes its sky mesh to the air's optical
length in every direction, so a view ray ends at Hoffman & Preetham Eq. 5's optical length for its
own zenith angle, the length of an equivalent homogeneous atmosphere along it; the haze shell is the
same length times l_haze / l_air. Below the horizon a ray ends at the flat ground (h / -cos) when
that is nearer, and the ground there is lit by the extinguished sun (Lambertian, ``ground_albedo``).

Everything is per unit extraterrestrial sun (E0 = 1), like the tables. The sun is below the
horizon when its zenith angle passes 90 deg (Hoffman & Preetham Eq. 5 is Kasten's fit for
apparent zenith angles up to 90 deg; past 91 deg it falls again and would light the sky from
under the ground): its disc sets over its own angular radius, and the analytic sky has no
twilight.
"""
from __future__ import annotations

import math
import dataclasses
from dataclasses import dataclass

import numpy as np

from .atmosphere import MAX_COEFFICIENT, PARAMETER_RANGES, AtmosphereParams, rayleigh_scattering_from_air

# The seed's sample wavelengths and Rayleigh numbers (their Rayleigh coefficients are
# rayleigh_scattering_from_air(SEED_WAVELENGTHS_NM); the tests hold them to the printed values).
SEED_WAVELENGTHS_NM = (650.0, 570.0, 475.0)
SEED_RAYLEIGH = (6.95e-6, 1.18e-5, 2.44e-5)
SEED_AIR_ZENITH_LENGTH_M = 8400.0
SEED_HAZE_ZENITH_LENGTH_M = 1250.0


@dataclass(frozen=True)
class HazeLook:
    """One row of the seed's Table 1: haze scattering (1/m, R G B at 650 / 570 / 475 nm)."""
    scattering: tuple
    description: str


# The seed's Table 1 (its fog rows are the project's fog layer's job, not a haze look). The g
# column is printed as -1 and -3, outside Henyey-Greenstein's domain (|g| < 1): the looks keep the
# scene's aerosol asymmetry instead (params.mie_g).
HAZE_LOOKS = {
    "light-haze": HazeLook((2e-5, 3e-5, 4e-5), "Light haze: the seed's low haze, Rayleigh dominates"),
    "heavy-haze": HazeLook((8e-5, 1e-4, 1.2e-4), "Heavy haze: the seed's high haze, nearly grey"),
}

# Kasten's fit is for zenith angles up to 90 deg: the sun and the view ray both clamp there.
HORIZON_DEG = 90.0
# The sun's angular radius (the lamp's default angle 0.545 deg, halved): the disc sets over it.
SUN_RADIUS_RAD = math.radians(0.545) / 2
# Guards a medium with no extinction (all coefficients 0): (1 - exp(-b s)) / b -> s.
MIN_EXTINCTION = 1e-12


def _finite_clamped(value, low, high, default):
    value = float(value)
    if not math.isfinite(value):
        value = default
    return min(max(value, low), high)


def _rgb(value, low, high):
    array = np.nan_to_num(np.asarray(value, dtype=np.float64), nan=0.0, posinf=high, neginf=low)
    return np.clip(array, low, high)


@dataclass(frozen=True)
class AnalyticMedia:
    """The coefficients of the analytic model (1/m, RGB) and the zenith optical lengths (m)."""
    rayleigh: np.ndarray            # scattering = extinction: air does not absorb
    haze_scattering: np.ndarray
    haze_extinction: np.ndarray
    g: float                        # Henyey-Greenstein asymmetry of the haze, forward > 0
    air_length: float               # optical length at the zenith from the ground
    haze_length: float
    ground_albedo: float

    @property
    def length_ratio(self) -> float:
        """s_haze / s_air for the same ray (the seed's constant ratio)."""
        return self.haze_length / self.air_length


def media(params: AtmosphereParams) -> AnalyticMedia:
    """The analytic media of ``params`` (see the module docstring). NaN or out-of-range numbers
    clamp into the ranges the tables accept (atmosphere.PARAMETER_RANGES) instead of raising:
    the preview must show something for any panel state, like the clamped controls."""
    rayleigh = _rgb(params.rayleigh, 0.0, MAX_COEFFICIENT)
    haze = _rgb(params.mie, 0.0, MAX_COEFFICIENT)
    haze_extinction = np.maximum(_rgb(params.mie_extinction, 0.0, MAX_COEFFICIENT * 2), haze)
    return AnalyticMedia(
        rayleigh=rayleigh, haze_scattering=haze, haze_extinction=haze_extinction,
        g=_finite_clamped(params.mie_g, *PARAMETER_RANGES["mie_g"], 0.7),
        air_length=_finite_clamped(params.rayleigh_scale_height, *PARAMETER_RANGES["rayleigh_scale_height"], 7994.0),
        haze_length=_finite_clamped(params.mie_scale_height, *PARAMETER_RANGES["mie_scale_height"], 1200.0),
        ground_albedo=_finite_clamped(params.ground_albedo, 0.0, 1.0, 0.2),
    )


def seed_rayleigh() -> tuple:
    """The seed's Rayleigh coefficients from its formula at its wavelengths."""
    return rayleigh_scattering_from_air(SEED_WAVELENGTHS_NM)


# -- phase functions ----------------------------------------------------------------------------

def rayleigh_phase(cos_theta):
    c = np.asarray(cos_theta, dtype=np.float64)
    return 3.0 / (16.0 * math.pi) * (1.0 + c * c)


def hg_phase(cos_theta, g: float):
    """Henyey-Greenstein, normalised over the sphere, forward peak at cos = 1 for g > 0."""
    c = np.asarray(cos_theta, dtype=np.float64)
    return (1.0 - g * g) / (4.0 * math.pi * np.power(1.0 + g * g - 2.0 * g * c, 1.5))


# -- Hoffman & Preetham Eq. 5 -------------------------------------------------------------------

def air_mass(cos_zenith):
    """Hoffman & Preetham Eq. 5 without l_zenith: 1 / (cos theta + 0.15 (93.885 - theta)^-1.253),
    theta in degrees, clamped at the horizon (36.5 there)."""
    c = np.clip(np.asarray(cos_zenith, dtype=np.float64), 0.0, 1.0)
    theta = np.degrees(np.arccos(c))
    return 1.0 / (c + 0.15 * np.power(93.885 - theta, -1.253))


def optical_length(cos_zenith, zenith_length, height=0.0, scale_height=None):
    """Hoffman & Preetham Eq. 5's optical length toward ``cos_zenith`` from ``height`` (the density
    there, relative to the ground, scales it: the optical length is the integrated density over the
    ground's)."""
    scale = 1.0 if scale_height is None else np.exp(-np.maximum(height, 0.0) / scale_height)
    return zenith_length * air_mass(cos_zenith) * scale


def sun_visibility(cos_sun):
    """The fraction of the disc above the horizon (linear in the angle across the disc)."""
    elevation = np.arcsin(np.clip(np.asarray(cos_sun, dtype=np.float64), -1.0, 1.0))
    return np.clip((elevation + SUN_RADIUS_RAD) / (2 * SUN_RADIUS_RAD), 0.0, 1.0)


def extinction(m: AnalyticMedia, s_air, s_haze):
    """F_ex(s_air, s_haze) = exp(-(beta_air s_air + beta_haze s_haze)), RGB on the last axis."""
    s_air = np.asarray(s_air, dtype=np.float64)[..., None]
    s_haze = np.asarray(s_haze, dtype=np.float64)[..., None]
    return np.exp(-(m.rayleigh * s_air + m.haze_extinction * s_haze))


def sun_transmittance(m: AnalyticMedia, cos_sun, height=0.0):
    """E_sun / E0 at ``height``: Hoffman & Preetham Eq. 5's optical lengths in Eq. 3, times
    the visible part of the disc."""
    s_air = optical_length(cos_sun, m.air_length, height, m.air_length)
    s_haze = optical_length(cos_sun, m.haze_length, height, m.haze_length)
    return extinction(m, s_air, s_haze) * sun_visibility(cos_sun)[..., None]


# -- Hoffman & Preetham Eq. 4 -------------------------------------------------------------------

def angular_scattering(m: AnalyticMedia, cos_sun_view, air_density=1.0, haze_density=1.0):
    """beta_sc(theta) of air and haze at the given relative densities, RGB."""
    c = np.asarray(cos_sun_view, dtype=np.float64)[..., None]
    air = np.asarray(air_density, dtype=np.float64)[..., None]
    haze = np.asarray(haze_density, dtype=np.float64)[..., None]
    return m.rayleigh * air * rayleigh_phase(c) + m.haze_scattering * haze * hg_phase(c, m.g)


def segment(m: AnalyticMedia, cos_sun_view, length, e_sun, air_density=1.0, haze_density=1.0):
    """(F_ex, L_in) of a constant-density segment of ``length`` m: Hoffman & Preetham Eqs. 3 and 4
    with both media at the given densities relative to the ground. ``e_sun``: E_sun / E0, RGB."""
    length = np.asarray(length, dtype=np.float64)[..., None]
    air = np.asarray(air_density, dtype=np.float64)[..., None]
    haze = np.asarray(haze_density, dtype=np.float64)[..., None]
    beta = m.rayleigh * air + m.haze_extinction * haze
    transmittance = np.exp(-beta * length)
    # (1 - exp(-b s)) / b, exact at b = 0 (-expm1 keeps small b s accurate).
    reach = np.where(beta > MIN_EXTINCTION, -np.expm1(-beta * length) / np.maximum(beta, MIN_EXTINCTION), length)
    return transmittance, e_sun * angular_scattering(m, cos_sun_view, air_density, haze_density) * reach


def sky_lengths(m: AnalyticMedia, cos_view, height=0.0):
    """(s_air, s_haze) of a view ray that ends in the sky, from ``height``."""
    s_air = optical_length(cos_view, m.air_length, height, m.air_length)
    s_haze = optical_length(cos_view, m.haze_length, height, m.haze_length)
    return s_air, np.minimum(s_haze, s_air)


def sky_inscattering(m: AnalyticMedia, cos_sun_view, s_air, s_haze, e_sun):
    """The seed's two-shell sky: air and haze over s_haze, then air alone to s_air."""
    inner_t, inner = segment(m, cos_sun_view, s_haze, e_sun)
    _, outer = segment(m, cos_sun_view, np.asarray(s_air) - np.asarray(s_haze), e_sun, 1.0, 0.0)
    return inner + inner_t * outer


def ground_distance(cos_view, height):
    """Distance to the flat ground below the horizon, inf above it."""
    c = np.asarray(cos_view, dtype=np.float64)
    h = np.maximum(np.asarray(height, dtype=np.float64), 0.0)
    with np.errstate(divide="ignore"):
        return np.where(c < 0.0, np.maximum(h, 1e-3) / np.maximum(-c, 1e-9), np.inf)


def sky_parts(m: AnalyticMedia, height, view, sun):
    """(air light, ground light) per unit E0 for view directions ``view`` (..., 3, unit, +Z up)
    from a camera ``height`` m up, the sun toward ``sun`` (3,): the sky's two shells, or below the
    horizon the air to the ground and the lit ground seen through it, whichever the ray meets
    first. Kept apart because the groups scale the air's light by the Scattering Scale and the
    ground's not, as the precomputed sky does. No sun disc (the groups add it)."""
    view = np.asarray(view, dtype=np.float64)
    sun = np.asarray(sun, dtype=np.float64)
    cos_view = view[..., 2]
    cos_sun_view = view @ sun
    e_sun = sun_transmittance(m, sun[2], height)
    s_air, s_haze = sky_lengths(m, cos_view, height)
    sky = sky_inscattering(m, cos_sun_view, s_air, s_haze, e_sun)
    distance = ground_distance(cos_view, height)
    hits = distance < s_air
    air = math.exp(-max(height, 0.0) / m.air_length)
    haze = math.exp(-max(height, 0.0) / m.haze_length)
    t, inscatter = segment(m, cos_sun_view, np.where(hits, distance, 0.0), e_sun, air, haze)
    ground = m.ground_albedo / math.pi * max(float(sun[2]), 0.0) * e_sun * t
    return np.where(hits[..., None], inscatter, sky), ground * hits[..., None]


def sky_radiance(m: AnalyticMedia, height, view, sun):
    """The analytic sky per unit E0: sky_parts' air and ground light together."""
    air, ground = sky_parts(m, height, view, sun)
    return air + ground


def segment_densities(m: AnalyticMedia, start, end):
    """The relative air and haze densities the aerial perspective holds constant along a segment:
    those at its middle's height (z up, flat ground at 0)."""
    middle = np.maximum((np.asarray(start, dtype=np.float64)[..., 2] + np.asarray(end, dtype=np.float64)[..., 2]) / 2, 0.0)
    return np.exp(-middle / m.air_length), np.exp(-middle / m.haze_length)


def aerial_perspective(m: AnalyticMedia, camera, points, surface_radiance, sun, sun_strength=1.0,
                       scattering_scale=1.0):
    """Hoffman & Preetham Eq. 1 between the camera and ``points`` (..., 3): (image, transmittance,
    in-scattering), the air light times ``sun_strength * scattering_scale`` like the precomputed
    pass. E_sun is the sun's extinction at the camera's height, once a frame (the seed's choice)."""
    camera = np.asarray(camera, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    sun = np.asarray(sun, dtype=np.float64)
    offset = points - camera
    length = np.linalg.norm(offset, axis=-1)
    cos_sun_view = (offset @ sun) / np.maximum(length, 1e-9)
    e_sun = sun_transmittance(m, sun[2], camera[2])
    air, haze = segment_densities(m, camera, points)
    transmittance, inscatter = segment(m, cos_sun_view, length, e_sun, air, haze)
    inscatter = inscatter * sun_strength * scattering_scale
    return np.asarray(surface_radiance)[..., :3] * transmittance + inscatter, transmittance, inscatter


# -- the terrain's light ------------------------------------------------------------------------

# The ambient skylight: the analytic sky's irradiance on a horizontal plane AMBIENT_HEIGHT_M up (the
# precomputed tables' Yusov 2013 eq. (3) height), at AMBIENT_NODES suns evenly spaced in cos from
# the horizon to the zenith, linear between. The groups hold the same nodes as constants: no image.
AMBIENT_NODES = 17
AMBIENT_HEIGHT_M = 20.0


def _hemisphere(zeniths: int = 48, azimuths: int = 64):
    """Directions and weights (solid angle x cos) of the upper hemisphere: Gauss-Legendre in
    cos zenith, even in azimuth."""
    x, w = np.polynomial.legendre.leggauss(zeniths)
    mu, w_mu = (x + 1) / 2, w / 2
    phi = (np.arange(azimuths) + 0.5) * 2 * math.pi / azimuths
    sin = np.sqrt(1 - mu ** 2)
    directions = np.stack(np.broadcast_arrays(sin[:, None] * np.cos(phi), sin[:, None] * np.sin(phi),
                                              mu[:, None]), axis=-1)
    weights = (w_mu * mu)[:, None] * np.full(azimuths, 2 * math.pi / azimuths)
    return directions.reshape(-1, 3), weights.reshape(-1)


# The last table and the media it is of: building the analytic groups asks for it twice (the sky's
# and the terrain's media group), and it is 0.07 s of the stand-in's second.
_last_ambient = {"key": None, "table": None}


def ambient_table(m: AnalyticMedia):
    """(cos sun nodes, irradiance per unit E0 (nodes, RGB) without the sun's visibility factor):
    E = int L_air(w) cos dw over the sky, from sky_parts' air light."""
    key = tuple(np.asarray(getattr(m, field.name), dtype=np.float64).tobytes() for field in dataclasses.fields(m))
    if _last_ambient["key"] != key:
        _last_ambient.update(key=key, table=_ambient_table(m))
    nodes, values = _last_ambient["table"]
    return nodes.copy(), values.copy()


def _ambient_table(m: AnalyticMedia):
    cos_nodes = np.linspace(0.0, 1.0, AMBIENT_NODES)
    directions, weights = _hemisphere()
    values = []
    for c in cos_nodes:
        sun = np.array([math.sqrt(1 - c * c), 0.0, c])
        air, _ = sky_parts(m, AMBIENT_HEIGHT_M, directions, sun)
        values.append((air * weights[:, None]).sum(axis=0) / sun_visibility(c))
    return cos_nodes, np.array(values)


def ambient_irradiance(m: AnalyticMedia, cos_sun, table=None):
    """The ambient skylight per unit E0 for suns at ``cos_sun``: the table, linear, times the
    visible part of the disc."""
    nodes, values = table if table is not None else ambient_table(m)
    c = np.asarray(cos_sun, dtype=np.float64)
    clamped = np.clip(c, 0.0, 1.0)
    rgb = np.stack([np.interp(clamped, nodes, values[:, i]) for i in range(3)], axis=-1)
    return rgb * sun_visibility(c)[..., None]


def terrain_radiance(m: AnalyticMedia, position, normal, sun, sun_strength: float, albedo, table=None):
    """(..., 3) radiance leaving a Lambertian point (lut_gen.passes.terrain's formula with the
    analytic model's sun extinction at the point's height and its ambient skylight): albedo / pi
    E0 (F_ex(point) max(N . L, 0) + E_sky(cos sun) occlusion(N)). +Z is up; shadows are the
    renderer's."""
    position = np.asarray(position, dtype=np.float64)
    normal = np.asarray(normal, dtype=np.float64)
    sun = np.asarray(sun, dtype=np.float64)
    direct = sun_transmittance(m, sun[2], position[..., 2]) * np.maximum(normal @ sun, 0.0)[..., None]
    occlusion = np.clip((1.0 + normal[..., 2]) / 2.0, 0.0, 1.0)[..., None]
    ambient = ambient_irradiance(m, sun[2], table) * occlusion
    return np.asarray(albedo, dtype=np.float64) / math.pi * sun_strength * (direct + ambient)
