"""The bake a wired scene uses, as the per-frame code needs it: its images, parameters and
table sizes, the transmittance at the origin, and the tables as numpy (read once per bake key
and dropped when undo or a file load replaces the images). ``table_problem`` says whether the
tables may render at all.
"""
from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np

from .... import lut_gen
from ....lut_gen.tables import atlas
from ....lut_gen.tables.lookup import Luts
from .. import names
from ..sun import OriginTransmittance
from . import luts


def _pixels(image) -> np.ndarray:
    """(height, width, 3) of a loaded table image (rows bottom to top, as the arrays lut_gen
    writes)."""
    width, height = image.size
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(height, width, 4)[..., :3]


class BakeInfo:
    """What the scene handlers need of the wired bake, read once per bake key."""

    def __init__(self, key: str):
        self.key = key
        luts.verify_wired(key)          # never read damaged tables (hashes cached: cheap)
        self.multiple = bpy.data.images.get(luts.image_name("multiple", key))
        self.single = bpy.data.images.get(luts.image_name("single", key))
        self.higher = bpy.data.images.get(luts.image_name("higher", key))
        self.single_mie = bpy.data.images.get(luts.image_name("single_mie", key))
        self.ambient = bpy.data.images.get(luts.image_name("ambient", key))
        self.optical_depth = optical_depth = bpy.data.images.get(luts.image_name("optical_depth", key))
        if None in (self.multiple, self.single, self.higher, self.single_mie, self.ambient, optical_depth):
            raise FileNotFoundError(f"the images of bake {key} are not loaded; run Set Up Scene")
        directory = Path(bpy.path.abspath(self.multiple.filepath)).parent
        self.params, self.dims = lut_gen.store.exr_header.read_header_params(directory)
        self.single_fog = bpy.data.images.get(luts.image_name("single_fog", key)) if self.params.has_fog else None
        self.fog_depth = luts.fog_depth_image(optical_depth, self.params)
        if self.params.has_fog and self.single_fog is None:
            raise FileNotFoundError(f"the fog images of bake {key} are not loaded; run Set Up Scene")
        self.origin_transmittance = OriginTransmittance(optical_depth, self.params, self.fog_depth)
        self._luts = None
        self._image_luts = None

    def numpy_luts(self):
        """The bake as lut_gen.Luts (read on first use: the epipolar tables need it)."""
        if self._luts is None:
            self._luts = lut_gen.load(Path(bpy.path.abspath(self.multiple.filepath)).parent,
                                      params=self.params).keep_packed()
        return self._luts

    def image_luts(self):
        """Luts of the tables the per-frame images need (the lighting panoramas, the twilight
        correction, the cloud air map), read back from their images: the multiple, single,
        higher-order and single Mie atlases, the optical depth (stored height along x) and the
        ambient skylight (and the fog's single atlas and column). Kept packed: the ground
        look-ups otherwise copied the optical-depth table three times a sun move (10 ms each)."""
        if self._image_luts is None:
            table = atlas.unpack(_pixels(self.multiple), self.dims)
            optical_depth = _pixels(self.optical_depth)
            if self.fog_depth is not None:
                optical_depth = np.concatenate([optical_depth, _pixels(self.fog_depth)[..., :1]], axis=-1)
            self._image_luts = Luts(
                self.params, single=atlas.unpack(_pixels(self.single), self.dims),
                higher=atlas.unpack(_pixels(self.higher), self.dims),
                optical_depth=np.ascontiguousarray(optical_depth.transpose(1, 0, 2)),
                ambient=np.ascontiguousarray(_pixels(self.ambient)[0]), multiple=table,
                single_mie=atlas.unpack(_pixels(self.single_mie), self.dims),
                single_fog=None if self.single_fog is None else atlas.unpack(_pixels(self.single_fog), self.dims),
            ).keep_packed()
        return self._image_luts


_bake_info = {}


def is_analytic(scene) -> bool:
    """Wired to the analytic model: no bake behind the scene."""
    return scene is not None and scene.get(names.WIRED_KEY) == names.ANALYTIC_WIRED


def bake_info(scene):
    key = scene.get(names.WIRED_KEY)
    if not key or key == names.ANALYTIC_WIRED:
        return None
    info = _bake_info.get(key)
    if info is not None:
        try:
            info.multiple.name          # still the live image (not replaced by undo or a load)?
        except ReferenceError:
            info = None
    if info is None:
        _bake_info.clear()
        info = _bake_info[key] = BakeInfo(key)
    return info


def table_problem(scene):
    """Why the wired ``scene``'s tables must not render (LutError text naming the file and the
    fix), or None: they verify (cached hashes, so this costs only stats)."""
    key = scene.get(names.WIRED_KEY) if scene is not None else None
    if not key or key == names.ANALYTIC_WIRED:
        return None
    try:
        luts.verify_wired(key)
    except (lut_gen.LutError, OSError) as exc:
        return str(exc)
    return None


def forget():
    _bake_info.clear()
