"""Precomputed atmospheric scattering tables (Yusov 2013, "Outdoor Light Scattering Sample
Update"): pure numpy + OpenEXR, no Blender needed.

    import lut_gen
    luts = lut_gen.bake()                       # default 32 x 128 x 64 x 16 tables
    lut_gen.save(luts, "luts/")
    luts = lut_gen.load("luts/")
    luts.sky_radiance(height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view)
"""
from . import aerial, atomic, monte_carlo, reference, scattering_pass, shadow_map, spectrum
from .atmosphere import AtmosphereParams, preset
from .bake import RESOLUTIONS, bake
from .cache import cached_bake, default_cache_root
from .exr_io import LutError, load, save
from .sampling import Luts

__all__ = ["AtmosphereParams", "Luts", "LutError", "RESOLUTIONS", "bake", "cached_bake", "preset",
           "default_cache_root", "load", "save"]
