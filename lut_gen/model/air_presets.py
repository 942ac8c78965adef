"""Air presets: a day's haze as its aerosol optical depth at 550 nm (AIR_PRESETS), shared by the
panel's Air Preset control and `scripts/render.py --preset NAME`, and fog as its visibility and
depth (FOG_PRESETS); ``air_preset_changes`` turns either into AtmosphereParams fields
(`python -m lut_gen bake --preset NAME`).

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
from .analytic import HAZE_LOOKS, SEED_HAZE_ZENITH_LENGTH_M
from .atmosphere import AtmosphereParams

REFERENCE_NM = 550.0
AIR_PRESETS = {
    "hazy-summer-day": 0.3,
    "clean-mountain-air": 0.03,
    # Hoffman & Preetham's haze looks (their Table 1): the green coefficient over their haze
    # optical length, 0.0375 and 0.125. Their colour and phase are not carried over: the
    # aerosol keeps the clear sky's (see lut_gen.model.analytic).
    **{name: look.scattering[1] * SEED_HAZE_ZENITH_LENGTH_M for name, look in HAZE_LOOKS.items()},
}
# Fog presets: (visibility m, scale height m). Morning fog in a valley: a radiation fog a few
# tens of metres deep, a few hundred metres' visibility at the ground.
FOG_PRESETS = {
    "morning-fog": (300.0, 50.0),
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


def air_preset_changes(name: str, params: AtmosphereParams | None = None) -> dict:
    """The AtmosphereParams fields that air preset ``name`` sets on ``params`` (default: the clear
    sky): the aerosol density of a haze (AIR_PRESETS), the fog's visibility and height of a fog
    (FOG_PRESETS). ValueError naming every air preset for an unknown one."""
    if name in AIR_PRESETS:
        return {"aerosol_density": preset_density(name, params)}
    if name in FOG_PRESETS:
        visibility, height = FOG_PRESETS[name]
        return {"fog_visibility": visibility, "fog_height": height}
    raise ValueError(f"unknown air preset {name!r}; choose one of {', '.join([*AIR_PRESETS, *FOG_PRESETS])}")
