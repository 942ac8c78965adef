"""Operators: bake tables, set up the scene, render, measure the light adaptation, pack the
tables. The bpy layer only: the work lives in baking.py, scene/ and lut_gen; the app handlers
are in handlers.py."""
from __future__ import annotations

import tempfile
from pathlib import Path

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from .. import lut_gen
from . import baking
from .scene import names
from .scene import sun as sun_lamps
from .scene.frame import adaptation_plan
from .scene.setup import checks, wiring
from .scene.tables import packed_tables, wired_bake
from .settings import validated_params

RESOLUTION_ITEMS = [("default", "Default", "The sample's 32 x 128 x 64 x 16 tables (~10-20 s)"),
                    ("draft", "Draft", "Half every dimension (about 2 s)")]


def terrain_candidates(context):
    return [o for o in context.selected_objects if o.type == "MESH"]


class OLS_OT_bake_luts(bpy.types.Operator):
    """Bake the scattering tables for the current atmosphere settings (cached by parameters)"""
    bl_idname = "ols.bake_luts"
    bl_label = "Bake Tables"
    bl_options = {"REGISTER", "UNDO"}

    resolution: EnumProperty(name="Resolution", items=RESOLUTION_ITEMS, default="default")
    setup_after: BoolProperty(name="Set Up Scene After", default=False, options={"HIDDEN", "SKIP_SAVE"})
    preview: BoolProperty(name="Preview While Baking", default=True, options={"SKIP_SAVE"},
                          description="In the UI, show the draft tables (a few seconds) while the full ones bake")

    def _show(self, context, directory, preview=False):
        """Wire the scene to ``directory`` (Set Up Scene after a bake) or swap it in."""
        scene = context.scene
        if not preview and scene.get(names.WIRED_KEY) == directory.name and not baking.showing_preview(scene):
            return                      # already there (a render settled it while the bake ran)
        if self.setup_after and not scene.get(names.WIRED_KEY):
            wiring.wire_scene(scene, directory, terrain_candidates(context), resolution=self.resolution)
            baking.mark_preview(scene, preview)
        elif scene.get(names.WIRED_KEY):
            baking.swap_in(scene, directory, preview=preview)

    def _show_stand_in(self, context):
        """While the draft bakes: the analytic model at once, where it can stand in for the
        tables (baking.analytic_can_stand_in); the draft replaces it when ready."""
        scene = context.scene
        if not baking.analytic_can_stand_in(scene):
            return
        try:
            if self.setup_after and not scene.get(names.WIRED_KEY):
                wiring.wire_scene(scene, None, terrain_candidates(context), resolution=self.resolution)
                baking.mark_preview(scene, True)
            elif scene.get(names.WIRED_KEY) and not wiring.wants_analytic(scene):
                baking.show_analytic_stand_in(scene)
        except (wiring.SetupError, lut_gen.LutError, OSError, RuntimeError) as exc:
            self.report({"WARNING"}, f"The analytic preview cannot be shown ({exc}); the tables are still baking")

    def _finish(self, context, directory):
        try:
            self._show(context, directory)
        except (wiring.SetupError, lut_gen.LutError, OSError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Tables ready: {directory}")
        return {"FINISHED"}

    def execute(self, context):
        """Blocking bake (scripts and background mode) with the window manager's progress."""
        try:
            params = validated_params(context.scene.ols)
        except ValueError as exc:
            self.report({"ERROR"}, f"Invalid atmosphere setting: {exc}")
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            directory = baking.bake_if_needed(params, self.resolution,
                                       progress=lambda stage, f: wm.progress_update(int(f * 100)))
        except (lut_gen.LutError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        return self._finish(context, directory)

    def invoke(self, context, event):
        """In the UI: bake on a worker thread, keep Blender responsive, show the analytic model
        at once where it can stand in, the draft preview when it is ready and swap the full
        tables in when done."""
        try:
            self._params = validated_params(context.scene.ols)
        except ValueError as exc:
            self.report({"ERROR"}, f"Invalid atmosphere setting: {exc}")
            return {"CANCELLED"}
        if baking.is_baked(self._params, self.resolution):
            return self._finish(context, baking.bake_directory(self._params, self.resolution))
        # The stand-in first: built while the bake's thread runs, it took 1.6-2x as long.
        if baking.wants_preview(self._params, self.resolution, self.preview):
            self._show_stand_in(context)
        self._bake = baking.BackgroundBake(self._params, self.resolution, preview=self.preview)
        self._preview_shown = False
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.2, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        bake = self._bake
        if event.type == "F12" and event.value == "PRESS" and not bake.done:
            # F12 renders the tables asked for, never the preview or the old ones: it waits.
            bake.render_after = "ANIMATION" if event.ctrl else "STILL"
            self.report({"INFO"}, "The render starts when the atmosphere tables are baked")
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        wm = context.window_manager
        shown_now = False
        if bake.preview_ready and not self._preview_shown and not bake.superseded:
            self._preview_shown = shown_now = True
            try:
                self._show(context, bake.preview_directory, preview=True)
            except (wiring.SetupError, lut_gen.LutError, OSError, RuntimeError) as exc:
                self.report({"WARNING"}, f"The draft preview cannot be shown ({exc}); the full tables are still baking")
        wm.progress_update(int(bake.fraction * 100))
        context.workspace.status_text_set(baking.progress_line(bake, context.scene))
        _redraw_sidebars(context)
        # A preview shown in this step stays for one redraw at least, even when the full tables
        # finished while it was being wired (the per-frame images take a moment).
        if not bake.done or shown_now:
            return {"RUNNING_MODAL"}
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)
        _redraw_sidebars(context)
        if bake.superseded:             # a newer bake (a later slider change) swaps in instead
            return {"CANCELLED"}
        if bake.error:
            self.report({"ERROR"}, f"Baking failed: {bake.error}")
            return {"CANCELLED"}
        result = self._finish(context, bake.directory)
        if result == {"FINISHED"} and bake.render_after:
            start_render(animation=bake.render_after == "ANIMATION")
        return result


def start_render(animation: bool):
    """The render F12 (Ctrl+F12: the animation) asked for while the tables baked."""
    bpy.ops.render.render("INVOKE_DEFAULT", animation=animation)


def _redraw_sidebars(context):
    screen = getattr(context, "screen", None)
    for area in (screen.areas if screen is not None else ()):
        if area.type == "VIEW_3D":
            area.tag_redraw()


class OLS_OT_setup_scene(bpy.types.Operator):
    """Add (or adopt) a Sun lamp, bake or load the tables, set the OLS Sky world and give the
    selected meshes the OLS Terrain material"""
    bl_idname = "ols.setup_scene"
    bl_label = "Set Up Scene"
    bl_options = {"REGISTER", "UNDO"}

    resolution: EnumProperty(name="Resolution", items=RESOLUTION_ITEMS, default="default")

    def execute(self, context):
        scene = context.scene
        try:
            wiring.check_scene(scene)
            directory = None            # the analytic model: no tables
            if not wiring.wants_analytic(scene):
                directory = baking.bake_if_needed(validated_params(scene.ols), self.resolution)
            wiring.wire_scene(scene, directory, terrain_candidates(context), resolution=self.resolution)
        except (wiring.SetupError, lut_gen.LutError, OSError, ValueError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, "Scene wired to the analytic atmosphere model" if directory is None
                    else "Scene wired to the atmosphere tables")
        return {"FINISHED"}

    def invoke(self, context, event):
        try:
            wiring.check_scene(context.scene)
            params = validated_params(context.scene.ols)
        except (wiring.SetupError, ValueError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        if not wiring.wants_analytic(context.scene) and not baking.is_baked(params, self.resolution):
            # Not baked yet (or damaged): bake in the background, then set up.
            return bpy.ops.ols.bake_luts("INVOKE_DEFAULT", resolution=self.resolution, setup_after=True)
        return self.execute(context)


def render_path(filepath: str) -> Path:
    """Where the Render operator writes ``filepath``: a path relative to the .blend ("//...") of
    an unsaved file goes to the system's temporary folder (it has no folder to resolve to); a
    folder is refused."""
    if not filepath.strip():
        raise ValueError("The file path is empty: give a file name such as //render.png")
    if filepath.endswith(("/", "\\")) or Path(bpy.path.abspath(filepath)).is_dir():
        raise ValueError(f"{filepath} is a folder: give a file name in it, such as {filepath.rstrip('/')}/render.png")
    if filepath.startswith("//") and not bpy.data.filepath:
        return Path(tempfile.gettempdir()) / filepath[2:]
    return Path(bpy.path.abspath(filepath))


class OLS_OT_render(bpy.types.Operator):
    """Render the scene camera to an image file"""
    bl_idname = "ols.render"
    bl_label = "Render"

    filepath: StringProperty(name="File Path", subtype="FILE_PATH", default="//ols_render.png")

    def execute(self, context):
        scene = context.scene
        if scene.camera is None:
            self.report({"ERROR"}, "The scene has no camera: add one and make it the scene camera")
            return {"CANCELLED"}
        if sun_lamps.find_sun(scene) is None:
            self.report({"ERROR"}, "The scene has no Sun lamp: run Set Up Scene")
            return {"CANCELLED"}
        problem = wired_bake.table_problem(scene)
        if problem is not None:
            self.report({"ERROR"}, f"Not rendering: {problem}")
            return {"CANCELLED"}
        try:
            if baking.needs_settling(scene):    # the tables asked for, not the draft preview
                baking.settle(scene, validated_params(scene.ols))
        except (lut_gen.LutError, OSError, ValueError, RuntimeError) as exc:
            self.report({"ERROR"}, f"Not rendering: the atmosphere tables cannot be baked: {exc}")
            return {"CANCELLED"}
        try:
            path = render_path(self.filepath)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        try:
            lut_gen.store.atomic.probe_writable(path)
        except OSError as exc:
            self.report({"ERROR"}, f"Cannot write {path}: {exc.strerror or exc}")
            return {"CANCELLED"}
        for problem in checks.ensure_passes(scene) + checks.camera_problems(scene, context.evaluated_depsgraph_get()):
            self.report({"WARNING"}, problem[0].upper() + problem[1:])
        previous = scene.render.filepath
        scene.render.filepath = str(path)
        try:
            bpy.ops.render.render(write_still=True)
        finally:
            scene.render.filepath = previous
        self.report({"INFO"}, f"Rendered {path}")
        return {"FINISHED"}


class _OnWiredScene:
    """Operators that act on a scene Set Up Scene has wired."""

    @classmethod
    def poll(cls, context):
        return context.scene is not None and bool(context.scene.get(names.WIRED_KEY))


class OLS_OT_measure_adaptation(_OnWiredScene, bpy.types.Operator):
    """Measure the light adaptation of every frame in a quick low-resolution pre-pass and store it
    in the scene, so that frames rendered in separate processes (a render farm's chunks) adapt as
    in one job"""
    bl_idname = "ols.measure_adaptation"
    bl_label = "Measure Light Adaptation"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        scene = context.scene
        if not scene.ols.light_adaptation:
            self.report({"ERROR"}, "Light Adaptation is off: nothing to measure")
            return {"CANCELLED"}
        if not scene.render.use_compositing:
            self.report({"ERROR"}, "Compositing is off (Output Properties > Post Processing): the tone "
                                   "mapping does not run, so there is no adaptation to measure")
            return {"CANCELLED"}
        problem = wired_bake.table_problem(scene)
        if problem is not None:             # its pre-pass renders: refuse as the Render operator does
            self.report({"ERROR"}, f"Cannot measure the light adaptation: {problem}")
            return {"CANCELLED"}
        try:
            plan = adaptation_plan.build(scene, progress=print)
        except adaptation_plan.PlanError as exc:
            self.report({"ERROR"}, f"Cannot measure the light adaptation: {exc}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Light adaptation measured for frames {plan['start']}-{plan['end']}; "
                              "save the file before sending it to a farm")
        return {"FINISHED"}


class OLS_OT_pack_tables(_OnWiredScene, bpy.types.Operator):
    """Store the scene's baked tables in the .blend (about 150 MB at the default resolution), so
    that a render-farm worker renders it without baking"""
    bl_idname = "ols.pack_tables"
    bl_label = "Pack Tables"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        # the analytic model has no tables: a farm renders it as it is
        return super().poll(context) and not wired_bake.is_analytic(context.scene)

    def execute(self, context):
        try:
            size = packed_tables.pack(context.scene[names.WIRED_KEY])
        except lut_gen.LutError as exc:
            self.report({"ERROR"}, f"Cannot pack the tables: {exc}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Packed {size / 2**20:.0f} MiB of tables; save the file to keep them")
        return {"FINISHED"}


CLASSES = (OLS_OT_bake_luts, OLS_OT_setup_scene, OLS_OT_render, OLS_OT_measure_adaptation, OLS_OT_pack_tables)
