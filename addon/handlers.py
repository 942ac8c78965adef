"""Every app handler of the add-on and its registration: the sky follows the sun and the
camera as a user works (depsgraph and frame changes), each render gets its shadow maps, frame
values and light adaptation (render_init/pre/post/complete), undo and file loads drop stale
caches and re-bake tables a file's machine does not have.

When Blender calls them (measured in bpy 5.0.1): see scene/frame/frame_update.py for the
render_pre / frame_change_post order and scene/frame/adaptation.py for when the tone-mapping
inputs must be set.
"""
from __future__ import annotations

import os
import sys

import bpy
from bpy.app.handlers import persistent

from .. import lut_gen
from . import baking
from .scene import names
from .scene import sun as sun_lamps
from .scene.frame import adaptation, adaptation_plan, animation, frame_update
from .scene.setup import checks, compositor, wiring
from .scene.tables import packed_tables, wired_bake
from .settings import validated_params


def _update_scene(scene):
    sun = sun_lamps.find_sun(scene)
    if sun is None or not scene.get(names.WIRED_KEY):
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
    if not scene.get(names.WIRED_KEY):
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
    adaptation.push_inputs(scene, scene.frame_current)


@persistent
def on_render_post(scene, *_args):
    adaptation.record_frame(scene, scene.frame_current)
    adaptation.push_inputs(scene, scene.frame_current + max(scene.frame_step, 1))


@persistent
def on_frame_change_post(scene, depsgraph=None):
    """In an animation render this runs after render_pre, with the frame's evaluated state."""
    if frame_update.rendering() and depsgraph is not None:
        _update_frame(scene, depsgraph)


@persistent
def on_render_init(scene=None, *_args):
    frame_update.set_rendering(True)
    if scene is None:
        return
    problem = wired_bake.table_problem(scene)
    if problem is not None:
        _refuse_damaged_tables(scene, problem)
    if baking.showing_preview(scene):
        # F12 waits for the bake (the Bake Tables operator holds it back) and the Render
        # operator settles first; a render started from the menu meanwhile cannot be stopped.
        print(f"Outdoor Light Scattering: scene {scene.name!r}: this render uses the draft preview tables; "
              "the full ones are still baking (F12 or Render wait for them)")
    adaptation.begin_render(scene, adaptation_plan.for_render(scene))


def _refuse_damaged_tables(scene, problem):
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
def on_render_end(scene=None, *_args):
    frame_update.set_rendering(False)
    for each in bpy.data.scenes:
        if each.get(names.WIRED_KEY):
            compositor.sync_layers_output(each, rendering=False)
    if scene is not None:
        adaptation.end_render(scene)


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
        key = scene.get(names.WIRED_KEY)
        problem = wired_bake.table_problem(scene)
        saved_in_preview = problem is None and baking.showing_preview(scene)
        if saved_in_preview:
            problem = "it was saved showing the draft preview of tables that were still baking"
        elif problem is None:           # not wired, or its tables verify
            continue
        if packed_tables.is_packed(key) and not saved_in_preview:
            try:
                directory = packed_tables.restore(key)
                print(f"Outdoor Light Scattering: scene {scene.name!r}: using the tables packed in the file "
                      f"(written to {directory})")
                continue
            except (lut_gen.LutError, OSError) as exc:
                problem = exc
        print(f"Outdoor Light Scattering: scene {scene.name!r}: {problem}; baking them again")
        resolution = scene.get(names.RESOLUTION_KEY, "default")
        try:
            if bpy.app.background:
                baking.swap_in(scene, baking.bake_if_needed(validated_params(scene.ols), resolution))
            else:
                bpy.app.timers.register(lambda: baking.invoke_bake_in_window(resolution), first_interval=0.1)
        except (lut_gen.LutError, OSError, ValueError) as exc:
            print(f"Outdoor Light Scattering: cannot bake the tables of scene {scene.name!r}: {exc}")


HANDLERS = ((bpy.app.handlers.frame_change_pre, on_frame_change),
            (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
            (bpy.app.handlers.render_init, on_render_init),
            (bpy.app.handlers.render_pre, on_render_pre),
            (bpy.app.handlers.render_post, on_render_post),
            (bpy.app.handlers.frame_change_post, on_frame_change_post),
            (bpy.app.handlers.render_complete, on_render_end),
            (bpy.app.handlers.render_cancel, on_render_end),
            (bpy.app.handlers.undo_post, on_data_replaced),
            (bpy.app.handlers.redo_post, on_data_replaced),
            (bpy.app.handlers.load_post, on_file_loaded))


def register():
    for handlers, function in HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister():
    for handlers, function in HANDLERS:
        while function in handlers:
            handlers.remove(function)
    wiring.forget_caches()
