"""Per-frame inputs of the scattering passes: the "OLS Frame Values" image (camera, sun,
cascade rectangles) and the shadow maps, written before each frame is composited.

When (measured in bpy 5.0.1): a still render runs render_pre with the scene's depsgraph up to
date. An animation render runs render_pre of frame f with the previous frame's state, then
frame_change_post of f with the render's depsgraph evaluated at f; images written there are
what the compositor of frame f reads. Both hooks call ``update_frame``; a key of everything the
result depends on skips the repeated work (the shadow maps take about 0.2 s at 1024 texels and
6 cascades on 2 cores for the sample, 0.5 s for a forest of 660 000 triangles). Renders without
compositing skip it all.
"""
from __future__ import annotations

import contextlib

import bpy
import numpy as np

from ....lut_gen.clouds import shafts as cloud_shafts
from ....lut_gen.clouds import veil as cloud_veil
from ....lut_gen.passes import epipolar_grid, frame_values, scattering_pass
from ....lut_gen.model import analytic
from ....lut_gen.tables.process_tuning import blas_on_one_thread
from ...settings import Sanitized, analytic_params
from .. import names
from . import cloud_map
from ..tables import luts, wired_bake
from . import epipolar_tables, frame_state, shadow_maps

_state = {"key": None, "geometry_changed": True, "rendering": False}


def shafts_node(scene):
    tree = scene.compositing_node_group
    node = tree.nodes.get(names.SHAFTS_NODE) if tree is not None else None
    return node if node is not None and node.node_tree is not None else None


def write_frame_values(scene, state=None, cascades=None, extra=None):
    """Camera and sun (and, given, the cascades and ``extra`` rows) into "OLS Frame Values";
    written only when a value changed (this also runs from depsgraph handlers). ``state``: the
    frame's FrameState, read from the scene when not given."""
    image = bpy.data.images.get(names.FRAME_IMAGE)
    if image is None or scene.camera is None:
        return
    if state is None:
        try:
            state = frame_state.read(scene)
        except frame_state.ShadowMapError:
            return              # no sun or an orthographic camera: the operators report it
    values = shadow_maps.camera_values(state.camera)
    values["Sun Direction"], values["Sun Strength"] = state.sun_direction, state.sun_strength
    values.update(cloud_shafts.frame_rows(state.clouds))
    values.update(cloud_veil.frame_rows(state.clouds, _veil_light(scene, state)))
    if cascades is not None:
        values.update(shadow_maps.frame_values(cascades))
    values.update(extra or {})
    rows = len(frame_values.ROWS)
    previous = None
    if tuple(image.size) == (1, rows):
        previous = np.empty(rows * 4, dtype=np.float32)
        image.pixels.foreach_get(previous)
        previous = previous.reshape(rows, 1, 4)
    pixels = frame_values.pack(values, previous)
    if previous is None or not np.array_equal(pixels, previous):
        luts.write_data_image(names.FRAME_IMAGE, pixels)


def _veil_light(scene, state):
    """The light on the cloud layer for the veil (lut_gen.clouds.veil.VeilLight), from the
    tables' images (packed on a farm); None while Clouds is off."""
    info = wired_bake.bake_info(scene) if state.clouds is not None else None
    if info is None:
        return None
    return cloud_veil.VeilLight.of(info.image_luts(), state.clouds, state.sun_direction)


def _frame_key(scene, state: frame_state.FrameState):
    settings = state.settings
    return (scene.frame_current, state.key(),
            settings.shadow_map_resolution, settings.num_cascades, settings.cascade_partitioning_factor,
            settings.enable_light_shafts, settings.enable_light_scattering,
            epipolar_tables.technique(settings), epipolar_grid.settings_from(settings), settings.single_scattering_mode,
            settings.smooth_shadows, settings.best_cascade_search, settings.first_cascade_to_ray_march,
            settings.show_sampling, scene.get(names.WIRED_KEY))


def update_frame(scene, depsgraph) -> bool:
    """Shadow maps and frame values for the frame about to be composited; False when nothing
    changed since the last call. Raises ShadowMapError (a message for the user) when the light
    shafts cannot run. The camera, sun and settings are read once (frame_state) and handed to
    every stage."""
    if not scene.render.use_compositing:
        return False            # nothing reads them
    node = shafts_node(scene)
    shafts = node is not None and not node.mute
    try:
        state = frame_state.read(scene, depsgraph)
    except frame_state.ShadowMapError:
        if shafts:
            raise
        return False            # nothing needs the camera or the sun: no frame values to write
    key = _frame_key(scene, state)
    if key == _state["key"] and not _state["geometry_changed"]:
        return False
    cascades, extra = None, None
    if shafts:
        # OpenBLAS's own threads only slow the frame's thin (n, 3) @ (3, 3) products and compete
        # with the in-scattering worker: one thread (the forest 0.83 -> 0.73 s a frame).
        with blas_on_one_thread():
            casters = shadow_maps.casters(state, depsgraph)
            with _epipolar_tables(scene, node, state, casters.far) as finish_tables:
                cascades = shadow_maps.rasterise(state, casters, getattr(finish_tables, "on_cascade", None))
                if node.node_tree.get(names.READS_SHADOW_MAPS_KEY, True):
                    shadow_maps.write_images(cascades)
                extra = finish_tables(cascades)
    write_frame_values(scene, state, cascades, extra)
    _state.update(key=key, geometry_changed=False)
    return True


def _epipolar_tables(scene, node, state, far: float):
    """A context yielding ``finish(cascades) -> frame value rows or None``, which builds and
    writes the epipolar tables the shafts group's layout reads (none: None). With the baked
    tables the in-scattering tables build on a worker thread while the block rasterises the
    shadow maps (epipolar_tables.building); ``far``: the cascades' last split."""
    if node.node_tree.get(names.LAYOUT_KEY, "").find("EPIPOLAR_SAMPLING") < 0:
        return contextlib.nullcontext(lambda cascades: None)
    if wired_bake.is_analytic(scene):       # no tables: the model's media, no clouds
        media = analytic.media(analytic_params(scene.ols))
        return contextlib.nullcontext(lambda cascades: epipolar_tables.update_analytic(state, cascades, media))
    return epipolar_tables.building(state, far, wired_bake.bake_info(scene).numpy_luts(),
                                    cloud_map.numpy_layer(scene, state.clouds))


def note_depsgraph_update(depsgraph):
    """Edits to geometry, or to an object (its shadow visibility, say), invalidate the shadow
    maps and epipolar tables even when camera and sun stay put."""
    if depsgraph is None or any(_may_move_shadow_casters(update) for update in depsgraph.updates):
        _state["geometry_changed"] = True


def _may_move_shadow_casters(update) -> bool:
    """Objects and collections (visibility, exclusion) and geometry data. Not the Scene: its
    update claims geometry on any change of a scene property, a render setting say, and would
    make every F12 redo the shadow maps and epipolar tables; not images either, which report
    geometry when the frame update itself writes them."""
    if isinstance(update.id, (bpy.types.Object, bpy.types.Collection)):
        return True
    return update.is_updated_geometry and not isinstance(update.id, (bpy.types.Scene, bpy.types.Image))


def set_rendering(active: bool):
    _state["rendering"] = active


def rendering() -> bool:
    return _state["rendering"]


def forget():
    _state.update(key=None, geometry_changed=True)
    epipolar_tables.forget()


def pass_settings(scene, sun_strength: float):
    """scene.ols as the twin's PassSettings (lut_gen.passes.scattering_pass)."""
    fields = scattering_pass.PassSettings.__dataclass_fields__
    settings = Sanitized(scene.ols)
    values = {name: getattr(settings, name) for name in fields if hasattr(scene.ols, name)}
    values["cloud_offset"] = tuple(float(v) for v in values.get("cloud_offset", (0.0, 0.0)))
    return scattering_pass.PassSettings(**values, sun_strength=sun_strength)


def export_pass_inputs(scene, path, depsgraph=None):
    """Save what the numpy twin needs besides the render passes (camera, sun, shadow cascades,
    settings) for ``python -m lut_gen pass``."""
    depsgraph = depsgraph or bpy.context.evaluated_depsgraph_get()
    state = frame_state.read(scene, depsgraph)
    return scattering_pass.save_inputs(path, state.camera, state.sun_direction, shadow_maps.render(state, depsgraph),
                                       pass_settings(scene, state.sun_strength), state.render_size)
