"""The bake service: the tables a scene needs, from the cache or baked now, and swapped into a
wired scene. Operators, handlers, batch renders, benches and tests all bake through here.

``BackgroundBake`` runs a bake on a worker thread so that Blender stays responsive; its state is
read by the Bake Tables operator's modal timer on the main thread (bpy is touched only there).
"""
from __future__ import annotations

import threading
import traceback
from pathlib import Path

import bpy

from .. import lut_gen
from .scene import names
from .scene.setup import wiring
from .scene.tables import luts


def bake_directory(params, resolution="default") -> Path:
    return lut_gen.store.cache.cache_directory(params, resolution)


def bake_if_needed(params, resolution, progress=None) -> Path:
    """The cache folder of these tables, baked first when it does not hold them (a damaged
    or foreign bake there is replaced: the folder is named by the key)."""
    return lut_gen.store.cache.bake_into(params, resolution=resolution, progress=progress, overwrite=True)[0]


def is_baked(params, resolution) -> bool:
    directory = bake_directory(params, resolution)
    return lut_gen.store.exr_io.is_intact(directory, directory.name)


def swap_in(scene, directory):
    """Point an already wired scene at another bake (after a re-bake): rebuild the groups."""
    wiring.build_groups(directory, scene.render.engine)
    scene[names.WIRED_KEY] = lut_gen.store.exr_io.verify_bake(directory)   # verified by build_groups: cached
    wiring.refresh(scene, force=True)
    luts.release_unused_images()


class BackgroundBake:
    """One bake on a worker thread: ``stage`` and ``fraction`` follow its progress, ``done``
    turns true at the end, ``error`` then says why it failed (None when it did not)."""

    def __init__(self, params, resolution):
        self.params, self.resolution = params, resolution
        self.stage, self.fraction, self.error, self.done = "starting", 0.0, None, False
        self._thread = threading.Thread(target=self._work, daemon=True)
        self._thread.start()

    def _progress(self, stage, fraction):
        self.stage, self.fraction = stage, fraction

    def _work(self):
        try:
            bake_if_needed(self.params, self.resolution, progress=self._progress)
        except Exception as exc:        # reported on the main thread by whoever polls
            self.error = f"{exc}"
            traceback.print_exc()
        self.done = True

    @property
    def directory(self) -> Path:
        return bake_directory(self.params, self.resolution)


def invoke_bake_in_window(resolution="default"):
    """Start the background bake from a timer (no operator context there): borrow a window."""
    window = next(iter(bpy.context.window_manager.windows), None)
    if window is not None:
        with bpy.context.temp_override(window=window):
            bpy.ops.ols.bake_luts("INVOKE_DEFAULT", resolution=resolution)
