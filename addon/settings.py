"""The add-on's settings as the render reads them, in plain Python (no bpy): the control sets of
the panel, ``safe_value`` and ``Sanitized`` (every number finite and in range, sizes capped by the
render), and ``atmosphere_params`` (the table parameters of ``lut_gen``).

Everything here takes any object with the PropertyGroup's attributes, so it is tested without
registering the add-on; props.py declares the properties themselves.
"""
import math

import numpy as np

from ..lut_gen.model.air_presets import AIR_PRESETS, air_preset_changes
from ..lut_gen.model.atmosphere import DEFAULT_RAYLEIGH_SCATTERING, AtmosphereParams, preset
from ..lut_gen.passes import render_detail

CONTROL_SETS = ("BASIC", "ADDITIONAL", "TONE_MAPPING", "CLOUDS")

# The controls of each set, in the sample's panel order.
PROPERTIES_BY_SET = {
    "BASIC": [
        "enable_light_scattering",
        "enable_light_shafts",
        "scattering_technique",
        "shadow_map_resolution",
        "num_integration_steps",
        "jitter_steps",
        "epipolar_slices",
        "samples_per_slice",
        "initial_sample_step",
        "epipole_sampling_density",
        "refinement_threshold",
        "scattering_scale",
        "show_sampling",
        "use_min_max_optimization",
        "optimize_sample_locations",
        "correct_depth_breaks",
        "show_depth_breaks",
        "lighting_only",
    ],
    "ADDITIONAL": [
        "single_scattering_mode",
        "multiple_scattering_mode",
        "num_cascades",
        "show_cascades",
        "smooth_shadows",
        "best_cascade_search",
        "cascade_partitioning_factor",
        "first_cascade_to_ray_march",
        "extinction_evaluation_mode",
        "refinement_criterion",
        "use_custom_scattering_coeffs",
        "rayleigh_color",
        "mie_color",
        "air_preset",
        "aerosol_density",
        "aerosol_absorption",
        "atmosphere_model",
        "atmosphere_preset",
        "ground_albedo",
        "ozone_column",
        "fog_visibility",
        "fog_height",
        "animate_sun",
        "day_start_frame",
        "day_end_frame",
    ],
    "TONE_MAPPING": [
        "middle_gray",
        "white_point",
        "luminance_saturation",
        "auto_exposure",
        "tone_mapping_operator",
        "light_adaptation",
        "tone_map_exr",
    ],
    "CLOUDS": [
        "clouds_enabled",
        "cloud_preset",
        "cloud_coverage",
        "cloud_base",
        "cloud_thickness",
        "cloud_density",
        "cloud_scale",
        "cloud_seed",
        "cloud_offset",
    ],
}

# The sample's controls that have no counterpart in this design, and why: the panel greys them
# out and their tooltips end with the reason (lut_gen.passes.epipolar).
WITHOUT_EFFECT = {
    "optimize_sample_locations": "(no effect: samples are spaced by angle from the sun, so short epipolar "
                                 "lines are not oversampled)",
    "correct_depth_breaks": "(not needed: each pixel reads the epipolar tables at its own depth, so no pixel "
                            "is interpolated across a depth break)",
    "show_depth_breaks": "(not needed: each pixel reads the epipolar tables at its own depth, so there are no "
                         "depth breaks to correct)",
    "extinction_evaluation_mode": "(extinction is always evaluated per pixel)",
    "refinement_criterion": "(refinement always compares the lit length of neighbouring samples; depth plays "
                            "no part since each pixel uses its own)",
}

# The largest default Rayleigh coefficient (blue); the Rayleigh colour is relative to it.
RAYLEIGH_SCATTERING_SCALE = max(DEFAULT_RAYLEIGH_SCATTERING)
DEFAULT_RAYLEIGH_COLOR = tuple(c / RAYLEIGH_SCATTERING_SCALE for c in DEFAULT_RAYLEIGH_SCATTERING)
DEFAULT_MIE_COLOR = (1.0, 1.0, 1.0)

# The panel's fog: visibility 100 m (a dense fog) to 50 km (a trace), 0 for none; scale heights
# of 10 m (a shallow radiation fog) to 500 m (a deep valley fog). Below 100 m of visibility
# (or 10 m of height) the tables' height axis stops resolving the layer near the camera.
FOG_VISIBILITY_MIN_M = 100.0
FOG_VISIBILITY_MAX_M = 50_000.0
FOG_HEIGHT_MIN_M = 10.0
FOG_HEIGHT_MAX_M = 500.0



def safe_value(settings, name: str):
    """``settings.<name>`` as the render may use it: a float that is NaN or infinite (set from
    Python) reads as the control's default, and anything past the control's range (an
    ID-property write bypasses it) is clamped into it. One NaN control turned the whole
    composite NaN before."""
    value = getattr(settings, name)
    rna = getattr(settings, "bl_rna", None)         # None: a plain object standing in for scene.ols
    prop = rna.properties.get(name) if rna is not None else None
    if prop is None or prop.type not in {"FLOAT", "INT"} or getattr(prop, "array_length", 0):
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


def analytic_params(settings) -> AtmosphereParams:
    """The media of the analytic model (lut_gen.model.analytic): ``atmosphere_params`` of the
    sanitized controls, so a NaN or out-of-range aerosol control reads as its default or its
    bound instead of failing validation (the model clamps the rest)."""
    return atmosphere_params(Sanitized(settings))
