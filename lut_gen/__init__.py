"""Precomputed atmospheric scattering (Yusov 2013, "Outdoor Light Scattering Sample Update";
Bruneton 2017's spectral media and ozone) and the per-frame passes that read it: pure numpy and
OpenEXR, no Blender.

    import lut_gen
    luts = lut_gen.bake()                       # default 32 x 128 x 64 x 16 tables
    lut_gen.save(luts, "luts/")
    luts = lut_gen.load("luts/")
    luts.sky_radiance(height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view)

The package by concern (docs/design.md has the picture):
    model/    the media: AtmosphereParams, density profiles, spectra, geometry, the sun's disc
    tables/   the baked tables: parameterization, interpolation, the bake, look-ups (Luts)
    store/    files: EXR tables, manifests, atomic writes, locks, the bake cache
    passes/   per-frame work and the numpy twins of the node groups: aerial perspective, light
              shafts (brute force and epipolar), shadow maps, panoramas, tone mapping
    verify/   brute-force and Monte Carlo references (imported only by whoever checks the tables)
"""
from . import model, passes, store, tables
from .model.atmosphere import PRESETS, AtmosphereParams, preset
from .store.cache import cached_bake, default_cache_root
from .store.exr_header import LutError
from .store.exr_read import load
from .store.exr_write import save
from .tables.bake import RESOLUTIONS, bake
from .tables.lookup import Luts

__all__ = ["AtmosphereParams", "Luts", "LutError", "PRESETS", "RESOLUTIONS", "bake", "cached_bake", "preset",
           "default_cache_root", "load", "save", "model", "passes", "store", "tables"]
