"""The bake service: the tables a scene needs, from the cache or baked now, and swapped into a
wired scene. Operators, handlers, batch renders, benches and tests all bake through here.

``BackgroundBake`` runs a bake on a worker thread so that Blender stays responsive; its state is
read by the Bake Tables operator's modal timer on the main thread (bpy is touched only there).

The preview: a default bake takes 17-25 s on two cores, the draft (half every axis) about 1.5 s
and its swap into the scene 2-3 s more. A background bake of tables that are not cached bakes the
draft first; the operator shows the analytic model at once (``analytic_can_stand_in``: it has no
twilight, fog or clouds, so only where the scene has none of those), then the draft (swap_in with
preview=True), which is closer to the tables, and swaps the full tables in when they are done. A scene showing a
preview says so (names.PREVIEW_KEY): the panel, F12 (which waits), the Render operator and a
file opened later (which re-bakes) all read it. A newer bake supersedes an older one: the older
stops at its next progress report and never swaps in (``latest``).
"""
from __future__ import annotations

import math
import threading
import traceback
from pathlib import Path

import bpy

from .. import lut_gen
from .scene import names
from .scene import sun as sun_lamps
from .scene.setup import wiring
from .scene.tables import wired_bake
from .settings import fog_fields


def bake_directory(params, resolution="default") -> Path:
    return lut_gen.store.cache.cache_directory(params, resolution)


def bake_if_needed(params, resolution, progress=None) -> Path:
    """The cache folder of these tables, baked first when it does not hold them (a damaged
    or foreign bake there is replaced: the folder is named by the key)."""
    return lut_gen.store.cache.bake_into(params, resolution=resolution, progress=progress, overwrite=True)[0]


def is_baked(params, resolution) -> bool:
    directory = bake_directory(params, resolution)
    return lut_gen.store.exr_read.is_intact(directory, directory.name)


def swap_in(scene, directory, preview: bool = False):
    """Point an already wired scene at another bake (after a re-bake): rebuild the groups.
    ``preview``: the bake stands in for the tables being baked (draft preview). Not while the
    scene asks for the analytic model: a bake started before the switch ends without a swap."""
    if wiring.wants_analytic(scene):
        return
    mark_preview(scene, preview)
    wiring.use_model(scene, directory)


def needs_settling(scene) -> bool:
    """Whether a render must settle the scene first: it shows a preview (the analytic model or
    the draft) of tables still baking, or it is still on the analytic groups but asks for the
    tables again (a script switched the model back before they were baked)."""
    stand_in = wired_bake.is_analytic(scene) and not wiring.wants_analytic(scene)
    return stand_in or showing_preview(scene)


def settle(scene, params) -> bool:
    """Before a render: a scene that ``needs_settling`` gets the tables of ``params`` (validated,
    its own) now, waiting for the running bake or baking them, so that no frame renders a
    preview. True when it swapped tables in."""
    if not needs_settling(scene):
        return False
    running = latest()
    if running is not None:
        running.wait()
    swap_in(scene, bake_if_needed(params, scene.get(names.RESOLUTION_KEY, "default")))
    return True


def mark_preview(scene, preview: bool):
    if preview:
        scene[names.PREVIEW_KEY] = True
    elif names.PREVIEW_KEY in scene:
        del scene[names.PREVIEW_KEY]


def showing_preview(scene) -> bool:
    """True while a wired scene shows a preview (the analytic model, then the draft) of tables
    still baking."""
    return scene is not None and bool(scene.get(names.WIRED_KEY)) and bool(scene.get(names.PREVIEW_KEY))


def preview_name(scene) -> str:
    return "analytic" if wired_bake.is_analytic(scene) else "draft"


# The analytic sky is black once the sun is below this (Hoffman & Preetham Eq. 5 has no twilight,
# docs/analytic.md).
STAND_IN_MIN_SUN_ELEVATION_DEG = 2.0


def analytic_can_stand_in(scene) -> bool:
    """Whether the analytic model may stand in for tables still baking, before the draft: only
    where it shows what the scene asks for, with the sun up and no fog or clouds (the analytic
    groups have none of those); elsewhere the old look stays until the draft."""
    sun = sun_lamps.find_sun(scene)
    if sun is None or scene.ols.clouds_enabled or fog_fields(scene.ols):
        return False
    try:
        direction = sun_lamps.direction_to_sun(sun)
    except sun_lamps.SunError:
        return False
    return float(direction[2]) > math.sin(math.radians(STAND_IN_MIN_SUN_ELEVATION_DEG))


def show_analytic_stand_in(scene):
    """The analytic model's groups on a wired scene at once, marked as a preview: the running
    bake's draft and then its full tables replace them (swap_in)."""
    wiring.use_model(scene, None, shafts=False)        # the tables' shafts wait, muted, for the draft
    mark_preview(scene, True)


PREVIEW_RESOLUTION = "draft"


def wants_preview(params, resolution, preview: bool = True) -> bool:
    """Whether a bake of these tables shows previews: they are not cached, and not the draft."""
    return preview and resolution != PREVIEW_RESOLUTION and not is_baked(params, resolution)


class BakeSuperseded(Exception):
    """Raised inside a bake's progress report once a newer bake has started."""


# Share of a previewed bake's progress bar that the draft takes (its share of the time).
PREVIEW_SHARE = 0.1


class BackgroundBake:
    """One bake on a worker thread: ``stage`` and ``fraction`` follow its progress, ``done``
    turns true at the end, ``error`` then says why it failed (None when it did not).

    ``preview``: when these tables are not cached yet, bake the draft first; ``preview_ready``
    turns true when it is (``preview_directory``). The newest BackgroundBake is ``latest()``;
    an older one stops (``superseded``) at its next progress report."""

    def __init__(self, params, resolution, preview: bool = False):
        global _latest
        self.params, self.resolution = params, resolution
        self.stage, self.fraction, self.error, self.done = "starting", 0.0, None, False
        self.superseded = False
        self.preview_resolution = PREVIEW_RESOLUTION if wants_preview(params, resolution, preview) else None
        self.preview_ready = False
        self.render_after = None        # "STILL" or "ANIMATION": F12 pressed while baking
        if _latest is not None and not _latest.done:
            _latest.superseded = True
            self.render_after = _latest.render_after
        _latest = self
        self._thread = threading.Thread(target=self._work, daemon=True)
        self._thread.start()

    def _report(self, stage, fraction, start, share):
        if self.superseded:
            raise BakeSuperseded()
        self.stage, self.fraction = stage, start + share * fraction

    def _work(self):
        try:
            full_start = 0.0
            if self.preview_resolution:
                bake_if_needed(self.params, self.preview_resolution,
                               progress=lambda stage, f: self._report(f"draft preview, {stage}", f, 0.0, PREVIEW_SHARE))
                self.preview_ready = True
                full_start = PREVIEW_SHARE
            bake_if_needed(self.params, self.resolution,
                           progress=lambda stage, f: self._report(stage, f, full_start, 1.0 - full_start))
        except BakeSuperseded:
            self.superseded = True
        except Exception as exc:        # reported on the main thread by whoever polls
            self.error = f"{exc}"
            traceback.print_exc()
        self.done = True

    def wait(self, timeout=None) -> bool:
        """Block until the worker ends (True) or ``timeout`` seconds pass (False)."""
        self._thread.join(timeout)
        return self.done

    @property
    def directory(self) -> Path:
        return bake_directory(self.params, self.resolution)

    @property
    def preview_directory(self) -> Path:
        return bake_directory(self.params, self.preview_resolution)


_latest = None


def latest():
    """The newest BackgroundBake still running, or None."""
    return _latest if _latest is not None and not _latest.done else None


def progress_line(bake, scene=None) -> str:
    """The status bar's and the panel's line for a running bake."""
    line = f"Baking atmosphere tables {bake.fraction * 100:.0f}%: {bake.stage}"
    if showing_preview(scene):
        line += f" (showing the {preview_name(scene)} preview)"
    if bake.render_after:
        line += "; the render starts when they are done"
    return line


def invoke_bake_in_window(resolution="default"):
    """Start the background bake from a timer (no operator context there): borrow a window."""
    window = next(iter(bpy.context.window_manager.windows), None)
    if window is not None:
        with bpy.context.temp_override(window=window):
            bpy.ops.ols.bake_luts("INVOKE_DEFAULT", resolution=resolution)
