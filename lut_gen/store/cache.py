"""Bakes cached on disk by their bake key: equal inputs are baked once."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Optional

from ..model.atmosphere import AtmosphereParams
from ..tables.bake import bake_validated, resolve_orders, resolve_resolution
from ..tables.bake_parallel import Progress
from .exr_header import bake_key
from .exr_read import is_intact, load
from .exr_write import removed_if_left_empty, save


def default_cache_root() -> Path:
    """$OLS_CACHE_DIR, else $XDG_CACHE_HOME/outdoor_light_scattering, else ~/.cache/..."""
    if os.environ.get("OLS_CACHE_DIR"):
        return Path(os.environ["OLS_CACHE_DIR"])
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "outdoor_light_scattering"


def key_for(params: AtmosphereParams, resolution="default", orders=None) -> str:
    """The bake key of validated ``params`` (bake_into validates what enters the store)."""
    res = resolve_resolution(resolution)
    return bake_key(params, res.scattering, res.optical_depth, res.ambient, resolve_orders(params, orders))


def cache_directory(params: AtmosphereParams, resolution="default", orders=None) -> Path:
    """The folder of the cache root that holds (or will hold) the bake for these inputs."""
    return default_cache_root() / key_for(params, resolution, orders)


def bake_into(params: AtmosphereParams, *, resolution="default", orders=None, directory=None,
              progress: Optional[Progress] = None, overwrite: bool = False):
    """(directory, luts): bake and save unless ``directory`` (default: cache_directory) already
    holds this bake whole and undamaged (exr_read.is_intact: the bake manifest and the files' hashes),
    in which case luts is None. A damaged, incomplete or mixed copy of this bake is baked again."""
    params = params.validate()          # where parameters enter the store; handed down as they are
    key = key_for(params, resolution, orders)
    directory = Path(directory) if directory else default_cache_root() / key
    if is_intact(directory, key):
        return directory, None
    with removed_if_left_empty(directory):
        luts = bake_validated(params, resolution=resolution, orders=orders, progress=progress)
        save(luts, directory, overwrite=overwrite)
    return directory, luts


def cached_bake(params: Optional[AtmosphereParams] = None, *, resolution="default", orders=None,
                directory=None, progress: Optional[Progress] = None):
    """(luts, directory, hit): load the bake for these inputs from ``directory`` (default: a
    folder named by the bake key under the cache root) or bake and save it there."""
    directory, luts = bake_into(params or AtmosphereParams(), resolution=resolution, orders=orders,
                                directory=directory, progress=progress)
    if luts is None:
        return load(directory), directory, True
    return luts, directory, False
