"""Operators (bake tables, set up the scene, render) and the app handlers that keep the Sun
lamp's colour and animation current. The bpy layer only: the work lives in scene/ and lut_gen."""
from __future__ import annotations

import os
import sys
import threading
import traceback
from pathlib import Path

import bpy
from bpy.app.handlers import persistent
from bpy.props import BoolProperty, EnumProperty, StringProperty

from .. import lut_gen
from . import props
from .scene import (adaptation, adaptation_plan, animation, checks, compositor, frame_update, luts,
                    packed_tables, wiring)
from .scene import sun as sun_lamps

RESOLUTION_ITEMS = [("default", "Default", "The sample's 32 x 128 x 64 x 16 tables (~10-20 s)"),
                    ("draft", "Draft", "Half every dimension (~2 s)")]


def bake_directory(params, resolution="default") -> Path:
    return lut_gen.store.cache.cache_directory(params, resolution)


def bake_if_needed(params, resolution, progress=None) -> Path:
    """The cache folder of these tables, baked first when it does not hold them (a damaged
    or foreign bake there is replaced: the folder is named by the key)."""
    return lut_gen.store.cache.bake_into(params, resolution=resolution, progress=progress, overwrite=True)[0]


def terrain_candidates(context):
    return [o for o in context.selected_objects if o.type == "MESH"]


def swap_in(scene, directory):
    """Point an already wired scene at another bake (after a re-bake): rebuild the groups."""
    wiring.build_groups(directory, scene.render.engine)
    scene[wiring.WIRED_KEY] = lut_gen.store.exr_io.verify_bake(directory)   # verified by build_groups: cached
    wiring.refresh(scene, force=True)
    luts.release_unused_images()


class OLS_OT_bake_luts(bpy.types.Operator):
    """Bake the scattering tables for the current atmosphere settings (cached by parameters)"""
    bl_idname = "ols.bake_luts"
    bl_label = "Bake Tables"
    bl_options = {"REGISTER", "UNDO"}

    resolution: EnumProperty(name="Resolution", items=RESOLUTION_ITEMS, default="default")
    setup_after: BoolProperty(name="Set Up Scene After", default=False, options={"HIDDEN", "SKIP_SAVE"})

    def _finish(self, context, directory):
        scene = context.scene
        try:
            if self.setup_after:
                wiring.wire_scene(scene, directory, terrain_candidates(context), resolution=self.resolution)
            elif scene.get(wiring.WIRED_KEY):
                swap_in(scene, directory)
        except (wiring.SetupError, lut_gen.LutError, OSError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Tables ready: {directory}")
        return {"FINISHED"}

    def execute(self, context):
        """Blocking bake (scripts and background mode) with the window manager's progress."""
        try:
            params = props.atmosphere_params(context.scene.ols).validate()
        except ValueError as exc:
            self.report({"ERROR"}, f"Invalid atmosphere setting: {exc}")
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            directory = bake_if_needed(params, self.resolution,
                                       progress=lambda stage, f: wm.progress_update(int(f * 100)))
        except (lut_gen.LutError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        return self._finish(context, directory)

    def invoke(self, context, event):
        """In the UI: bake on a worker thread, keep Blender responsive, swap in when done."""
        try:
            self._params = props.atmosphere_params(context.scene.ols).validate()
        except ValueError as exc:
            self.report({"ERROR"}, f"Invalid atmosphere setting: {exc}")
            return {"CANCELLED"}
        directory = bake_directory(self._params, self.resolution)
        if lut_gen.store.exr_io.is_intact(directory, directory.name):
            return self._finish(context, directory)
        self._state = {"stage": "starting", "fraction": 0.0, "error": None, "done": False}

        def work():
            try:
                bake_if_needed(self._params, self.resolution,
                               progress=lambda stage, f: self._state.update(stage=stage, fraction=f))
            except Exception as exc:   # reported on the main thread
                self._state["error"] = f"{exc}"
                traceback.print_exc()
            self._state["done"] = True

        self._thread = threading.Thread(target=work, daemon=True)
        self._thread.start()
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.2, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        wm = context.window_manager
        wm.progress_update(int(self._state["fraction"] * 100))
        context.workspace.status_text_set(f"Baking atmosphere tables: {self._state['stage']} "
                                          f"{self._state['fraction'] * 100:.0f}%")
        if not self._state["done"]:
            return {"RUNNING_MODAL"}
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)
        if self._state["error"]:
            self.report({"ERROR"}, f"Baking failed: {self._state['error']}")
            return {"CANCELLED"}
        return self._finish(context, bake_directory(self._params, self.resolution))


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
            params = props.atmosphere_params(scene.ols).validate()
            directory = bake_if_needed(params, self.resolution)
            wiring.wire_scene(scene, directory, terrain_candidates(context), resolution=self.resolution)
        except (wiring.SetupError, lut_gen.LutError, OSError, ValueError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, "Scene wired to the atmosphere tables")
        return {"FINISHED"}

    def invoke(self, context, event):
        try:
            wiring.check_scene(context.scene)
            params = props.atmosphere_params(context.scene.ols).validate()
        except (wiring.SetupError, ValueError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        directory = bake_directory(params, self.resolution)
        if not lut_gen.store.exr_io.is_intact(directory, directory.name):
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
        import tempfile
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
        problem = wiring.table_problem(scene)
        if problem is not None:
            self.report({"ERROR"}, f"Not rendering: {problem}")
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
        return context.scene is not None and bool(context.scene.get(wiring.WIRED_KEY))


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
        problem = wiring.table_problem(scene)
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

    def execute(self, context):
        try:
            size = packed_tables.pack(context.scene[wiring.WIRED_KEY])
        except lut_gen.LutError as exc:
            self.report({"ERROR"}, f"Cannot pack the tables: {exc}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Packed {size / 2**20:.0f} MiB of tables; save the file to keep them")
        return {"FINISHED"}


# -- handlers ---------------------------------------------------------------------------------

def _update_scene(scene):
    sun = sun_lamps.find_sun(scene)
    if sun is None or not scene.get(wiring.WIRED_KEY):
        return
    try:
        wiring.match_engine(scene)
        wiring.match_light_shaft_layout(scene)
        if scene.ols.animate_sun:
            elevation, azimuth = animation.sun_angles_for_frame(scene.frame_current, scene.ols.day_start_frame,
                                                                scene.ols.day_end_frame)
            sun_lamps.set_sun_angles(sun, elevation, azimuth)
        wiring.refresh(scene)
    except (lut_gen.LutError, OSError, ValueError) as exc:
        # Once per problem: depsgraph updates come many times a second while a user works.
        if str(exc) != _reported.get("problem"):
            _reported["problem"] = str(exc)
            print(f"Outdoor Light Scattering: cannot update the sky: {exc}")


_reported = {}


@persistent
def on_frame_change(scene, depsgraph=None):
    _update_scene(scene)


@persistent
def on_depsgraph_update(scene, depsgraph=None):
    frame_update.note_depsgraph_update(depsgraph)
    _update_scene(scene)


def _match_layout(scene):
    """wiring.match_light_shaft_layout; the problem that stopped it, or None."""
    try:
        wiring.match_light_shaft_layout(scene)
    except (ValueError, lut_gen.LutError, OSError, KeyError) as exc:
        return exc
    return None


def _update_frame(scene, depsgraph):
    """Shadow maps and frame values before the frame is composited. Where they cannot be made,
    the light-shaft pass is off for this render and the reason printed (the render completes)."""
    if not scene.get(wiring.WIRED_KEY):
        return
    # First: the settings may have changed the layout since the last depsgraph update (scripts
    # set controls without one), and sync_settings feeds the groups it builds.
    problem = _match_layout(scene)
    compositor.sync_settings(scene)     # e.g. the output format: OpenEXR saves scene-linear
    compositor.sync_layers_output(scene, rendering=True)
    if problem is None:
        try:
            if frame_update.update_frame(scene, depsgraph):
                for message in checks.render_problems(scene, depsgraph):
                    print(f"Outdoor Light Scattering: {message}")
        except ValueError as exc:       # a ShadowMapError (a ValueError) says what to change
            problem = exc
    if problem is not None:
        compositor.disable_light_shafts(scene)
        print(f"Outdoor Light Scattering: light shafts are off for this render: {problem}")


@persistent
def on_render_pre(scene, *_args):
    _update_frame(scene, bpy.context.evaluated_depsgraph_get())


@persistent
def on_frame_change_post(scene, depsgraph=None):
    """In an animation render this runs after render_pre, with the frame's evaluated state."""
    if frame_update.rendering() and depsgraph is not None:
        _update_frame(scene, depsgraph)


@persistent
def on_render_init(scene=None, *_args):
    frame_update.set_rendering(True)
    problem = wiring.table_problem(scene)
    if problem is None:
        return
    if bpy.app.background:
        # A farm's `blender -b shot.blend -a` (no script of ours runs before it): a handler cannot
        # cancel the render, so the process ends here, with one line and status 1, before any
        # frame is written with a wrong sky. scripts/render.py refuses such tables before this.
        print(f"error: Outdoor Light Scattering: scene {scene.name!r}: {problem}; nothing was rendered",
              file=sys.stderr, flush=True)
        sys.stdout.flush()
        os._exit(1)
    # In the UI the render cannot be stopped from here; the file load started a re-bake.
    print(f"Outdoor Light Scattering: scene {scene.name!r}: this render uses damaged tables: {problem}")


@persistent
def on_render_end(*_args):
    frame_update.set_rendering(False)
    for scene in bpy.data.scenes:
        if scene.get(wiring.WIRED_KEY):
            compositor.sync_layers_output(scene, rendering=False)


@persistent
def on_data_replaced(*_args):
    """Undo, redo and file loads replace Blender's data: cached image references go stale."""
    wiring.forget_caches()


@persistent
def on_file_loaded(*_args):
    """A wired file opened where its tables are not baked, or are damaged (another machine, a
    cleared cache, a truncated file): bake them again for the scene's settings and swap them in."""
    wiring.forget_caches()
    for scene in bpy.data.scenes:
        key = scene.get(wiring.WIRED_KEY)
        problem = wiring.table_problem(scene)
        if problem is None:             # not wired, or its tables verify
            continue
        if packed_tables.is_packed(key):
            try:
                directory = packed_tables.restore(key)
                print(f"Outdoor Light Scattering: scene {scene.name!r}: using the tables packed in the file "
                      f"(written to {directory})")
                continue
            except (lut_gen.LutError, OSError) as exc:
                problem = exc
        print(f"Outdoor Light Scattering: scene {scene.name!r}: {problem}; baking them again")
        resolution = scene.get(wiring.RESOLUTION_KEY, "default")
        try:
            if bpy.app.background:
                swap_in(scene, bake_if_needed(props.atmosphere_params(scene.ols).validate(), resolution))
            else:
                bpy.app.timers.register(lambda: invoke_bake_in_window(resolution), first_interval=0.1)
        except (lut_gen.LutError, OSError, ValueError) as exc:
            print(f"Outdoor Light Scattering: cannot bake the tables of scene {scene.name!r}: {exc}")


def invoke_bake_in_window(resolution="default"):
    """Start the background bake from a timer (no operator context there): borrow a window."""
    window = next(iter(bpy.context.window_manager.windows), None)
    if window is not None:
        with bpy.context.temp_override(window=window):
            bpy.ops.ols.bake_luts("INVOKE_DEFAULT", resolution=resolution)


HANDLERS = ((bpy.app.handlers.frame_change_pre, on_frame_change),
            (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
            (bpy.app.handlers.render_pre, on_render_pre),
            (bpy.app.handlers.frame_change_post, on_frame_change_post),
            (bpy.app.handlers.render_init, on_render_init),
            (bpy.app.handlers.render_complete, on_render_end),
            (bpy.app.handlers.render_cancel, on_render_end),
            (bpy.app.handlers.undo_post, on_data_replaced),
            (bpy.app.handlers.redo_post, on_data_replaced),
            (bpy.app.handlers.load_post, on_file_loaded)) + adaptation.HANDLERS


def register_handlers():
    for handlers, function in HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister_handlers():
    for handlers, function in HANDLERS:
        while function in handlers:
            handlers.remove(function)
    wiring.forget_caches()


CLASSES = (OLS_OT_bake_luts, OLS_OT_setup_scene, OLS_OT_render, OLS_OT_measure_adaptation, OLS_OT_pack_tables)
