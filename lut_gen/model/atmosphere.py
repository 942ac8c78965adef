"""Atmosphere media: constants, phase functions, validation, presets (the density profiles are
in lut_gen.model.profiles).

Units are metres and 1/m. Colour triples are (red, green, blue) at 680/550/440 nm,
the sample's wavelengths. A spectral bake (the default) reads them as three samples of a
power law over wavelength (lut_gen.model.spectrum); the "Sample 2013" preset uses them directly as
RGB, as the sample did. Everything here is a pure function of AtmosphereParams.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Tuple

import numpy as np

from . import spectrum

Rgb = Tuple[float, float, float]

WAVELENGTHS_NM: Rgb = (680.0, 550.0, 440.0)
# Rayleigh coefficient inputs of the sample (Preetham/Hoffman eq. for beta_R).
AIR_REFRACTIVE_INDEX = 1.0003
AIR_MOLECULES_PER_M3 = 2.545e25
AIR_DEPOLARIZATION = 0.035
# Bruneton's ozone absorption at the same wavelengths (1/m at unit density).
OZONE_ABSORPTION: Rgb = (0.650e-6, 1.881e-6, 0.085e-6)


def rayleigh_scattering_from_air(wavelengths_nm: Rgb = WAVELENGTHS_NM) -> Rgb:
    """8 pi^3 (n^2-1)^2 / (3 N lambda^4) * (6+3p)/(6-7p), the sample's formula."""
    n, big_n, p = AIR_REFRACTIVE_INDEX, AIR_MOLECULES_PER_M3, AIR_DEPOLARIZATION
    king = (6 + 3 * p) / (6 - 7 * p)
    return tuple(
        8 * math.pi**3 * (n * n - 1) ** 2 / (3 * big_n * (lam * 1e-9) ** 4) * king
        for lam in wavelengths_nm
    )


DEFAULT_RAYLEIGH_SCATTERING: Rgb = rayleigh_scattering_from_air()


def aerosol_scattering(optical_depth_550: float, angstrom_exponent: float, scale_height_m: float,
                       wavelengths_nm: Rgb = WAVELENGTHS_NM) -> Rgb:
    """Mie scattering coefficients at sea level (1/m) of an aerosol layer with the given scattering
    optical depth at 550 nm, spectral slope (Angstrom exponent) and scale height."""
    at_550 = optical_depth_550 / scale_height_m
    return tuple(at_550 * (550.0 / lam) ** angstrom_exponent for lam in wavelengths_nm)


# The Clear Sky aerosol: a typical clear day over land. AERONET's continental sites show an
# aerosol optical depth of about 0.1 at 550 nm on clear days, an Angstrom exponent of 1-1.5 and
# an asymmetry parameter near 0.7 (OPAC "continental clean/average": 0.64-0.72). The sample's
# aerosol (2e-5 / m over 1.2 km: optical depth 0.024, grey, g 0.76) is four times cleaner than
# that, so its horizon came out ~2.8x too bright against the zenith at a high sun compared with
# the CIE standard clear sky, which was fitted to measured clear skies (README, "Luminance shape").
CLEAR_DAY_AEROSOL_OPTICAL_DEPTH = 0.1
CLEAR_DAY_ANGSTROM_EXPONENT = 1.3
CLEAR_DAY_MIE_G = 0.7
MIE_SCALE_HEIGHT_M = 1200.0
DEFAULT_MIE_SCATTERING: Rgb = aerosol_scattering(CLEAR_DAY_AEROSOL_OPTICAL_DEPTH, CLEAR_DAY_ANGSTROM_EXPONENT,
                                                 MIE_SCALE_HEIGHT_M)
# The sample's own aerosol (Yusov 2013), kept by the "sample-2013" preset.
SAMPLE_MIE_SCATTERING: Rgb = (2e-5, 2e-5, 2e-5)
SAMPLE_MIE_G = 0.76
# Lambertian albedo of the ground under the atmosphere: vegetation reflects 0.15-0.25 of the
# visible, bare soil and rock 0.2-0.35, water under 0.1. 0.2 sits in the middle of the land
# a terrain scene shows (Bruneton 2017 uses 0.1, Hosek-Wilkie's default is 0.3).
DEFAULT_GROUND_ALBEDO = 0.2


# An optical depth of 10 per kilometre: far hazier than any haze the tables are meant for (fog
# has its own limit, FOG_VISIBILITY_RANGE).
MAX_COEFFICIENT = 1e-2

# Fog: a second aerosol layer of water droplets, hugging the ground. Its extinction at the
# ground comes from the meteorological visibility by Koschmieder's law (the distance at which a
# black object's contrast against the horizon sky falls to 2%: beta = -ln 0.02 / V = 3.912 / V),
# counted for the fog alone. Droplets of 5-20 um are far larger than the wavelength: their
# scattering is grey, they absorb almost nothing in the visible (single-scattering albedo
# > 0.999), and their phase function is strongly forward (asymmetry 0.85 for fog and cloud
# droplets at 550 nm; Hess et al. 1998, OPAC "fog").
KOSCHMIEDER_CONSTANT = -math.log(0.02)
FOG_G = 0.85
# Visibility from 100 m (a dense fog; below it, or under 10 m of scale height, the tables'
# height axis stops resolving the layer near a camera on the ground) to 50 km (a trace); 0 means
# no fog. Scale heights from 10 m (a shallow radiation fog) to 500 m (a deep valley fog). The
# panel's Fog controls take these limits (addon/control_sets/additional.py).
FOG_VISIBILITY_RANGE = (100.0, 50_000.0)
FOG_HEIGHT_RANGE = (10.0, 500.0)


def fog_extinction(visibility_m: float) -> float:
    """Fog extinction at the ground (1/m) for a visibility in metres (0: no fog)."""
    return KOSCHMIEDER_CONSTANT / visibility_m if visibility_m > 0.0 else 0.0


TRIPLES = ("rayleigh_scattering", "mie_scattering", "ozone_absorption")
# Physical ranges (units of the fields): a planet from a small moon to a gas giant, an
# atmosphere from 1 km to 1000 km, coefficients up to MAX_COEFFICIENT.
PARAMETER_RANGES = {
    "earth_radius": (1e5, 1e8),
    "atmosphere_height": (1e3, 1e6),
    "rayleigh_scale_height": (1.0, 1e6),
    "mie_scale_height": (1.0, 1e6),
    "rayleigh_scattering": (0.0, MAX_COEFFICIENT),
    "mie_scattering": (0.0, MAX_COEFFICIENT),
    "ozone_absorption": (0.0, MAX_COEFFICIENT),
    "aerosol_density": (0.0, 1e3),
    "aerosol_absorption": (0.0, 1e3),
    "mie_g": (-0.999, 0.999),
    "ozone_column": (0.0, 2000.0),
    "ground_albedo": (0.0, 1.0),
    "fog_height": FOG_HEIGHT_RANGE,
    "fog_g": (-0.999, 0.999),
}


@dataclass(frozen=True)
class AtmosphereParams:
    """Air, a clear day's aerosol, Bruneton's ozone layer and a lit ground, baked spectrally
    (the "clear-sky" preset); "sample-2013" gives the sample's (Yusov 2013) own media.

    ``mie_scattering`` is the coefficient at aerosol density 1; the effective Mie
    scattering is ``mie_scattering * aerosol_density`` and Mie extinction adds
    ``aerosol_absorption`` times that. ``spectral``: integrate at many wavelengths and convert
    with the CIE observer (False: the sample's three wavelengths as RGB). ``ozone_column`` (Dobson
    units) sets the spectral ozone layer; ``ozone_absorption`` only the three-wavelength one.
    ``ground_albedo``: Lambertian ground, lit by the sun and the sky; its light enters the
    higher scattering orders and the ground a camera sees below the horizon.
    ``fog_visibility`` (m, 0 = no fog), ``fog_height`` (m, the fog's exponential scale height)
    and ``fog_g`` (its Cornette-Shanks asymmetry): a grey, non-absorbing fog layer at the
    ground, a medium of its own beside the haze aerosol (fog_extinction).
    """

    earth_radius: float = 6_360_000.0
    atmosphere_height: float = 80_000.0
    rayleigh_scattering: Rgb = DEFAULT_RAYLEIGH_SCATTERING
    rayleigh_scale_height: float = 7994.0
    mie_scattering: Rgb = DEFAULT_MIE_SCATTERING
    mie_scale_height: float = MIE_SCALE_HEIGHT_M
    aerosol_density: float = 1.0
    aerosol_absorption: float = 0.1
    mie_g: float = CLEAR_DAY_MIE_G
    ozone: bool = True
    ozone_absorption: Rgb = field(default=OZONE_ABSORPTION)
    ozone_column: float = 300.0
    spectral: bool = True
    ground_albedo: float = DEFAULT_GROUND_ALBEDO
    fog_visibility: float = 0.0
    fog_height: float = 50.0
    fog_g: float = FOG_G

    def __post_init__(self):
        # Triples given as lists (JSON, argparse) become tuples: params must stay hashable
        # (spectrum.rgb_coefficients caches per params) and compare equal either way.
        for name in ("rayleigh_scattering", "mie_scattering", "ozone_absorption"):
            value = getattr(self, name)
            if isinstance(value, list):
                object.__setattr__(self, name, tuple(value))

    # -- validation -------------------------------------------------------
    def validate(self) -> "AtmosphereParams":
        """Raise ValueError naming the first bad field and its range; return self when valid.
        The ranges (PARAMETER_RANGES) keep every result finite: far past them the float
        arithmetic of the bake overflows into NaN or negative optical depths."""
        for name, (lower, upper) in PARAMETER_RANGES.items():
            value = getattr(self, name)
            if name in TRIPLES:
                if not isinstance(value, (tuple, list)) or len(value) != 3:
                    raise ValueError(f"{name} must be three numbers (red, green, blue), got {value!r}")
                for channel, v in zip("rgb", value):
                    _check_number(f"{name}.{channel}", v, lower=lower, upper=upper)
            else:
                _check_number(name, value, lower=lower, upper=upper)
        for name in ("ozone", "spectral"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if self.atmosphere_height >= self.earth_radius:
            raise ValueError("atmosphere_height must be smaller than earth_radius")
        _check_number("fog_visibility", self.fog_visibility, lower=0.0, upper=FOG_VISIBILITY_RANGE[1])
        if 0.0 < self.fog_visibility < FOG_VISIBILITY_RANGE[0]:
            raise ValueError(f"fog_visibility must be 0 (no fog) or at least {FOG_VISIBILITY_RANGE[0]:g} m, "
                             f"got {self.fog_visibility!r}")
        if self.fog_height >= self.atmosphere_height:
            raise ValueError(f"fog_height ({self.fog_height:g} m) must lie inside the atmosphere "
                             f"(atmosphere_height {self.atmosphere_height:g} m)")
        aerosol = max(self.mie_scattering) * self.aerosol_density * (1.0 + self.aerosol_absorption)
        if aerosol > MAX_COEFFICIENT:
            raise ValueError(f"the aerosol extinction (mie_scattering x aerosol_density x (1 + aerosol_absorption)) "
                             f"must be <= {MAX_COEFFICIENT:g} per metre, got {aerosol:g}")
        return self

    # -- derived quantities ----------------------------------------------
    @property
    def top_radius(self) -> float:
        return self.earth_radius + self.atmosphere_height

    # RGB coefficients for code that works in RGB (node groups, the pass twins): the triples
    # themselves for Sample 2013 params, white-balanced spectral means and fitted extinction
    # for spectral ones (lut_gen.model.spectrum.rgb_coefficients). The bake uses spectrum.bake_media.
    @property
    def rayleigh(self) -> np.ndarray:
        """Rayleigh scattering coefficient at sea level, RGB."""
        if self.spectral:
            return np.array(spectrum.rgb_coefficients(self)[0])
        return np.asarray(self.rayleigh_scattering, dtype=np.float64)

    @property
    def mie(self) -> np.ndarray:
        """Mie scattering coefficient at sea level, aerosol density applied, RGB."""
        if self.spectral:
            return np.array(spectrum.rgb_coefficients(self)[1])
        return np.asarray(self.mie_scattering, dtype=np.float64) * self.aerosol_density

    @property
    def has_fog(self) -> bool:
        return self.fog_visibility > 0.0

    @property
    def fog(self) -> float:
        """Fog scattering = extinction at the ground (1/m), grey."""
        return fog_extinction(self.fog_visibility)

    @property
    def mie_extinction(self) -> np.ndarray:
        return self.extinction_matrix()[1]

    @property
    def ozone_extinction(self) -> np.ndarray:
        return self.extinction_matrix()[2]

    def extinction_matrix(self) -> np.ndarray:
        """(4 media, 3 channels): RGB optical depth = net densities (R, M, O, F) @ this."""
        fog = np.full((1, 3), self.fog)
        if self.spectral:
            return np.concatenate([spectrum.rgb_coefficients(self)[2], fog])
        ozone = np.asarray(self.ozone_absorption, dtype=np.float64) * (1.0 if self.ozone else 0.0)
        mie = np.asarray(self.mie_scattering, dtype=np.float64) * self.aerosol_density
        return np.concatenate([np.stack([np.asarray(self.rayleigh_scattering, dtype=np.float64),
                                         mie * (1.0 + self.aerosol_absorption), ozone]), fog])

    def to_dict(self) -> dict:
        d = asdict(self)
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = [float(x) for x in v]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "AtmosphereParams":
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"unknown atmosphere parameter(s): {', '.join(sorted(unknown))}")
        kwargs = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        return cls(**kwargs)


PRESETS = {
    # Spectral bake, ozone, ground, a clear day's aerosol: the colours and the luminance shape of
    # a real clear sky (the default).
    "clear-sky": {},
    # The sample's own media: its aerosol, three wavelengths used as RGB, no ozone, black ground.
    "sample-2013": {"spectral": False, "ozone": False, "ground_albedo": 0.0,
                    "mie_scattering": SAMPLE_MIE_SCATTERING, "mie_g": SAMPLE_MIE_G},
}


def preset(name: str, **changes) -> AtmosphereParams:
    """AtmosphereParams of a named preset (PRESETS), with ``changes`` on top."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}")
    return AtmosphereParams(**{**PRESETS[name], **changes})


def _check_number(name, value, *, lower, upper):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value) or not lower <= value <= upper:
        raise ValueError(f"{name} must be between {lower:g} and {upper:g}, got {value!r}")


# -- phase functions (normalised to 1 over the sphere) ----------------------

RAYLEIGH_PHASE_NORM = 3.0 / (16.0 * math.pi)


def rayleigh_phase(cos_theta):
    c = np.asarray(cos_theta)
    return RAYLEIGH_PHASE_NORM * (1.0 + c * c)


def mie_phase(cos_theta, g: float):
    """Cornette-Shanks phase function, forward peak at cos_theta = 1 for g > 0."""
    c = np.asarray(cos_theta)
    g2 = g * g
    norm = 3.0 / (8.0 * math.pi) * (1.0 - g2) / (2.0 + g2)
    return norm * (1.0 + c * c) / np.power(1.0 + g2 - 2.0 * g * c, 1.5)
