"""Air presets: a day's haze as its aerosol optical depth at 550 nm, shared by the panel's Air
Preset control and `scripts/render.py --preset NAME`.

Aerosol optical depths at 550 nm: a hazy summer day over land about 0.3 (AERONET's continental
summer means are 0.2-0.4), clean mountain air about 0.03 (high-altitude stations, 0.02-0.05).
The clear-sky preset's aerosol is 0.11. A preset sets the aerosol density, which scales the
aerosol's profile as a whole, so its colour (the Angstrom exponent), its phase function and its
absorption stay the clear sky's.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from . import spectrum
from .atmosphere import AtmosphereParams

REFERENCE_NM = 550.0
AIR_PRESETS = {
    "hazy-summer-day": 0.3,
    "clean-mountain-air": 0.03,
}


def aerosol_optical_depth(params: AtmosphereParams, wavelength_nm: float = REFERENCE_NM) -> float:
    """The aerosol's vertical extinction optical depth from the ground at ``wavelength_nm``: an
    exponential profile's scale height times its extinction at the ground."""
    scattering = float(spectrum.power_law(params.mie_scattering, np.array([wavelength_nm]))[0])
    return scattering * params.aerosol_density * (1.0 + params.aerosol_absorption) * params.mie_scale_height


def aerosol_density_for(optical_depth: float, params: AtmosphereParams | None = None) -> float:
    """The aerosol density that gives ``params`` (default: the clear sky) this optical depth at
    550 nm."""
    params = params or AtmosphereParams()
    unit = aerosol_optical_depth(dataclasses.replace(params, aerosol_density=1.0))
    return float(optical_depth) / unit


def preset_density(name: str, params: AtmosphereParams | None = None) -> float:
    """The aerosol density of the air preset ``name`` (AIR_PRESETS); ValueError naming the
    presets for an unknown one."""
    if name not in AIR_PRESETS:
        raise ValueError(f"unknown air preset {name!r}; choose one of {', '.join(AIR_PRESETS)}")
    return aerosol_density_for(AIR_PRESETS[name], params)
