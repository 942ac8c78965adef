"""The add-on's settings as the render reads them, in plain Python (no bpy): ``safe_value`` and
``Sanitized`` (every number finite and in range, sizes capped by the render), and
``atmosphere_params`` (the table parameters of ``lut_gen``).

Everything here takes any object with the PropertyGroup's attributes, so it is tested without
registering the add-on. The controls, their defaults and ranges are declared in the registry
(addon/controls.py); props.py makes the properties from it.
"""
import math

import numpy as np

from ..lut_gen.model.air_presets import AIR_PRESETS, air_preset_changes
from ..lut_gen.model.atmosphere import DEFAULT_RAYLEIGH_SCATTERING, FOG_VISIBILITY_RANGE, AtmosphereParams, preset
from ..lut_gen.passes import render_detail
from .controls import (BY_NAME, CONTROL_SETS, DEFAULT_MIE_COLOR, DEFAULT_RAYLEIGH_COLOR,  # noqa: F401 (the panel's views)
                       PROPERTIES_BY_SET, RAYLEIGH_SCATTERING_SCALE, WITHOUT_EFFECT)

# The fog's lowest visibility the tables resolve: a value between 0 (no fog) and it reads as it.
FOG_VISIBILITY_MIN_M = FOG_VISIBILITY_RANGE[0]


def safe_value(settings, name: str):
    """``settings.<name>`` as the render may use it: a float that is NaN or infinite (set from
    Python) reads as the control's default, and anything past the control's range (an
    ID-property write bypasses it) is clamped into it. One NaN control turned the whole
    composite NaN before."""
    value = getattr(settings, name)
    rna = getattr(settings, "bl_rna", None)         # None: a plain object standing in for scene.ols
    prop = rna.properties.get(name) if rna is not None else None
    if prop is None:
        control = BY_NAME.get(name)
        return value if control is None else control.clamp(value)
    # The property's own range and default: the registry's, as Blender stores them (float32),
    # so a clamped value equals what the panel's slider gives at its end.
    if prop.type not in {"FLOAT", "INT"} or getattr(prop, "array_length", 0):
        return value
    if prop.type == "FLOAT" and not math.isfinite(value):
        value = prop.default
    return type(value)(min(max(value, prop.hard_min), prop.hard_max))


class Sanitized:
    """scene.ols as the render reads it: every number through safe_value, and the shadow-map
    resolution, epipolar slices and samples capped at what the scene's render size can resolve
    (lut_gen.passes.render_detail)."""

    def __init__(self, settings):
        self._settings = settings
        scene = settings.id_data
        render = getattr(scene, "render", None)
        self._capped = {} if render is None else render_detail.capped_fields(
            *render_detail.render_size(render.resolution_x, render.resolution_y, render.resolution_percentage))

    def __getattr__(self, name):
        value = safe_value(self._settings, name)
        cap = self._capped.get(name)
        return value if cap is None else cap(value)


def _f32_value(value):
    """The shortest decimal that round-trips a float32-stored value (what the user typed).

    Blender stores float properties as float32: 0.1 reads back as 0.10000000149. Table
    parameters (and so the bake cache key) use the decimal instead, so the panel's defaults
    equal ``AtmosphereParams()`` and a value typed in the panel equals the same value given to
    ``python -m lut_gen bake``.
    """
    return float(str(np.float32(value)))


def _f32_color(color):
    return tuple(_f32_value(c) for c in color)


def fog_fields(settings) -> dict:
    """The fog's AtmosphereParams fields for the panel's controls: no fog at visibility 0; a
    visibility between 0 and the lowest the tables resolve reads as that lowest one (the
    property's range cannot say "0 or at least 100 m")."""
    visibility = _f32_value(safe_value(settings, "fog_visibility"))
    if visibility <= 0.0:
        return {}
    return {"fog_visibility": max(visibility, FOG_VISIBILITY_MIN_M),
            "fog_height": _f32_value(safe_value(settings, "fog_height"))}


def apply_air_preset(settings, name: str) -> None:
    """Set the controls of air preset ``name`` (lut_gen.model.air_presets: "hazy-summer-day",
    "morning-fog", ...) on ``settings``: a haze sets the aerosol density and clears any fog (the
    preset is that day's air), a fog sets its visibility and height and keeps the haze.
    ValueError naming the presets for an unknown one, before anything changes."""
    changes = air_preset_changes(name, atmosphere_params(settings))
    if name in AIR_PRESETS:
        changes["fog_visibility"] = 0.0
    for field, value in changes.items():
        setattr(settings, field, value)


def atmosphere_params(settings) -> AtmosphereParams:
    """Table parameters (``lut_gen.AtmosphereParams``) for an ``OLSSettings``.

    The Atmosphere preset picks the starting point (lut_gen.model.atmosphere.PRESETS); aerosol density
    and absorption map one to one; ground albedo and ozone column apply to the Clear Sky preset
    (Sample 2013 has neither). With custom scattering coefficients on, the Rayleigh coefficients
    are ``max(default Rayleigh) * rayleigh_color`` (so the default colour gives the default
    coefficients) and the Mie coefficients the preset's times ``mie_color``; off, both are the
    preset's.
    """
    preset_name = "sample-2013" if settings.atmosphere_preset == "SAMPLE_2013" else "clear-sky"
    rayleigh = DEFAULT_RAYLEIGH_SCATTERING
    mie = preset(preset_name).mie_scattering
    if settings.use_custom_scattering_coeffs:
        color = _f32_color(settings.rayleigh_color)
        if color != _f32_color(DEFAULT_RAYLEIGH_COLOR):
            rayleigh = tuple(RAYLEIGH_SCATTERING_SCALE * c for c in color)
        color = _f32_color(settings.mie_color)
        if color != _f32_color(DEFAULT_MIE_COLOR):
            mie = tuple(m * c for m, c in zip(mie, color))
    if preset_name == "sample-2013":
        return preset("sample-2013", rayleigh_scattering=rayleigh, mie_scattering=mie,
                      aerosol_density=_f32_value(settings.aerosol_density),
                      aerosol_absorption=_f32_value(settings.aerosol_absorption), **fog_fields(settings))
    return preset(
        "clear-sky",
        rayleigh_scattering=rayleigh,
        mie_scattering=mie,
        aerosol_density=_f32_value(settings.aerosol_density),
        aerosol_absorption=_f32_value(settings.aerosol_absorption),
        ground_albedo=_f32_value(settings.ground_albedo),
        ozone=_f32_value(settings.ozone_column) > 0.0,
        ozone_column=_f32_value(settings.ozone_column),
        **fog_fields(settings),
    )


def validated_params(settings) -> AtmosphereParams:
    """``atmosphere_params`` validated: the one place the scene's controls become parameters a
    bake accepts. Called where a request enters (an operator, a render or load handler, the
    batch CLI, a control's update) and handed down as it is. ValueError names the bad field."""
    return atmosphere_params(settings).validate()


def analytic_params(settings) -> AtmosphereParams:
    """The media of the analytic model (lut_gen.model.analytic): ``atmosphere_params`` of the
    sanitized controls, so a NaN or out-of-range aerosol control reads as its default or its
    bound instead of failing validation (the model clamps the rest)."""
    return atmosphere_params(Sanitized(settings))
