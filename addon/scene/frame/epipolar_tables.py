"""The epipolar technique's per-frame tables (lut_gen.passes.epipolar) in the images the "OLS Light
Shafts" group reads, and the choice of technique for the scene's settings."""
from __future__ import annotations

import contextlib
import dataclasses
import functools
import weakref
from concurrent.futures import ThreadPoolExecutor

import bpy
import numpy as np

from ....lut_gen.passes import analytic_shafts, epipolar, epipolar_air, epipolar_grid, min_max, render_detail
from ... import nodes
from ..tables import luts
from .. import names

ALL_IMAGES = (names.EPIPOLAR_LIT_IMAGE, names.EPIPOLAR_INTEGRAL_IMAGE, names.EPIPOLAR_SAMPLING_IMAGE, *names.EPIPOLAR_AIR_IMAGES.values())


def render_size(scene):
    """(width, height) in pixels of the scene's render."""
    render = scene.render
    return render_detail.render_size(render.resolution_x, render.resolution_y, render.resolution_percentage)


def table_texels(settings) -> int:
    return (settings.epipolar_slices + 1) * settings.samples_per_slice * settings.num_integration_steps


def technique(settings) -> str:
    """The technique the pass runs: the setting, except that epipolar tables larger than
    lut_gen.passes.epipolar.MAX_TABLE_TEXELS fall back to brute force (too_large says so)."""
    if settings.scattering_technique == "EPIPOLAR_SAMPLING" and table_texels(settings) <= epipolar.MAX_TABLE_TEXELS:
        return "EPIPOLAR_SAMPLING"
    return "BRUTE_FORCE"


def too_large(settings) -> str | None:
    """Why the epipolar technique falls back to brute force, or None."""
    if settings.scattering_technique != "EPIPOLAR_SAMPLING" or technique(settings) == "EPIPOLAR_SAMPLING":
        return None
    return (f"the epipolar tables of {settings.epipolar_slices} slices x {settings.samples_per_slice} samples x "
            f"{settings.num_integration_steps} steps exceed {epipolar.MAX_TABLE_TEXELS:,} values; brute force ray "
            "marching runs instead (lower the slices, samples or steps to use epipolar sampling)")


def _sized_images(layout, settings) -> dict:
    """{name: (width, height)} of the per-frame table images the layout reads, at the sizes
    of the settings' slices, samples and steps. The group reads those sizes from the frame
    values, so a change of them resizes images and rebuilds no group."""
    sizes = {names.EPIPOLAR_LIT_IMAGE: nodes.epipolar.image_size(settings.epipolar_slices, settings.samples_per_slice,
                                                  settings.num_integration_steps)}
    if layout.single_mode == "INTEGRATION":
        sizes[names.EPIPOLAR_INTEGRAL_IMAGE] = sizes[names.EPIPOLAR_LIT_IMAGE]
    if not layout.analytic:     # the analytic model's air needs no in-scattering tables
        air = epipolar_air.air_dims(settings.epipolar_slices, settings.samples_per_slice)
        for name in names.EPIPOLAR_AIR_IMAGES.values():
            sizes[name] = nodes.epipolar.image_size(*air)
    return sizes


def ensure_images(layout, settings):
    """(lit image, integral image or None, sampling overlay, {name: in-scattering image}) at
    the sizes ``settings`` need (scene.ols, sanitized); None and {} for brute force. Sized
    here, before a render: an image made anew while an animation renders would be freed under
    the render's copy of the compositor (a crash)."""
    if not layout.epipolar:
        return None, None, None, {}
    images = {}
    for name, (width, height) in _sized_images(layout, settings).items():
        image = bpy.data.images.get(name)
        if image is None or tuple(image.size) != (width, height):
            image = luts.write_data_image(name, np.zeros((height, width, 4), dtype=np.float32))
        images[name] = image
    sampling = bpy.data.images.get(names.EPIPOLAR_SAMPLING_IMAGE)      # any size: written at the render's each frame
    sampling = sampling or luts.write_data_image(names.EPIPOLAR_SAMPLING_IMAGE, np.zeros((1, 1, 4), dtype=np.float32))
    air = {name: images[name] for name in names.EPIPOLAR_AIR_IMAGES.values() if name in images}
    return images[names.EPIPOLAR_LIT_IMAGE], images.get(names.EPIPOLAR_INTEGRAL_IMAGE), sampling, air


def resize_images(layout, settings) -> bool:
    """Bring existing table images to the sizes ``settings`` need (the group's image nodes
    follow, see luts.write_data_image); False when one is missing (the group must be rebuilt)."""
    if not all(bpy.data.images.get(name) is not None for name in (*_sized_images(layout, settings), names.EPIPOLAR_SAMPLING_IMAGE)):
        return False
    ensure_images(layout, settings)
    return True


def images_intact(layout, settings) -> bool:
    if not layout.epipolar:
        return True
    return (bpy.data.images.get(names.EPIPOLAR_SAMPLING_IMAGE) is not None
            and all(bpy.data.images.get(name) is not None and tuple(bpy.data.images[name].size) == size
                    for name, size in _sized_images(layout, settings).items()))


# The in-scattering tables depend on the camera's position, the sun and the grid's angles, not
# on the scene's geometry or the camera's turn within the grid: a frame where an object moved,
# the clouds drifted or the shadow maps changed reuses them (0.2-0.3 s a frame at 960 x 540).
_air_cache = {"luts": None, "key": None, "tables": None}


def _air_key(grid, camera_position):
    air, needed = grid
    return (np.asarray(camera_position, dtype=np.float64).tobytes(), needed.tobytes(),
            tuple(np.asarray(v).tobytes() if isinstance(v, np.ndarray) else v for v in dataclasses.astuple(air)))


def _air_tables_started(worker, luts_object, grid, camera_position):
    """A function returning the in-scattering tables of ``grid`` ((air frame, nodes needed)): the
    cached ones, or those ``worker`` builds from now on (cached here, on the calling thread, when
    the function fetches them)."""
    # The bake is compared by identity through a weak reference: a new bake never matches a
    # freed one's reused id, and a replaced bake's tables are not kept alive by this cache.
    key = _air_key(grid, camera_position)
    cached = _air_cache["luts"]
    if cached is not None and cached() is luts_object and _air_cache["key"] == key:
        tables = _air_cache["tables"]
        return lambda: tables
    air, needed = grid
    future = worker.submit(epipolar_air.build, luts_object, air, camera_position, needed)

    def fetched():
        tables = future.result()            # the worker's error, if any, raises here
        _air_cache.update(luts=weakref.ref(luts_object), key=key, tables=tables)
        return tables
    return fetched


def forget():
    """Drop the cached in-scattering tables (the next frame builds them anew)."""
    _air_cache.update(luts=None, key=None, tables=None)


def grids(state, far: float, luts_object, clouds=None):
    """((lit-length grid, its nodes the screen reads), (in-scattering grid, its nodes)) of the
    frame (lut_gen.passes.epipolar_grid.EpipolarFrame, screen_nodes): ``far`` is the shadow cascades'
    last split (shadow_maps.Casters.far). Only the nodes the screen reads are built."""
    camera = state.camera
    width, height = state.render_size
    reach = epipolar_grid.cloud_reach(clouds, camera, width, height, luts_object.params.earth_radius)
    frame = epipolar_grid.frame_for(camera, state.sun_direction, width, height, far,
                                    epipolar_grid.settings_from(state.settings), reach)
    air = epipolar_air.air_frame(frame, camera)
    return ((frame, epipolar_grid.screen_nodes(frame, camera, width, height)),
            (air, epipolar_grid.screen_nodes(air, camera, width, height)))


@contextlib.contextmanager
def building(state, far: float, luts_object, clouds=None):
    """The frame's tables, built while the block runs; yields ``finish(cascades) -> rows``.
    ``state``: the frame's FrameState; ``far``: the cascades' last split; ``luts_object``: the
    bake as lut_gen.Luts; ``clouds``: (layer, map) while the cloud layer shadows the air.

    The in-scattering tables need no shadow maps, but they wait for them: ``finish`` starts
    them on a worker thread and builds the lit-length tables beside them on this one (numpy
    releases the GIL in its loops), while the block's rasterising has every core (started
    with the block, the worker slowed the rasterising it ran beside, which the lit-length
    tables wait for: the forest's frame 0.57 -> 0.46 s). ``finish`` then writes both and
    returns the "OLS Frame Values" rows; the worker's error raises there. The worker never
    outlives the block (leaving it waits for the tables), and its tables are those the serial
    build makes: the same call on the same inputs."""
    (frame, needed), air_grid = grids(state, far, luts_object, clouds)
    settings = state.settings
    maps = None
    if epipolar_grid.settings_from(settings).use_min_max:
        # Filled by the rasterising threads, each cascade as soon as its map is done (built
        # after the rasterising, they held up the lit-length tables: 0.016 s of the forest's frame).
        maps = min_max.allocate(settings.num_cascades, int(settings.shadow_map_resolution), settings.smooth_shadows)
    with ThreadPoolExecutor(1, thread_name_prefix="OLS in-scattering") as worker:
        finish = functools.partial(_finish, state, far, frame, needed, air_grid,
                                   functools.partial(_air_tables_started, worker, luts_object, air_grid,
                                                     state.camera.position), luts_object, clouds, maps=maps)
        yield TableBuild(finish, None if maps is None else functools.partial(min_max.fill_cascade, maps))


@dataclasses.dataclass
class TableBuild:
    """What the frame's table builds yield: ``finish(cascades) -> frame value rows or None``,
    called as the object, and ``on_cascade`` for shadow_map.render_cascades (None: nothing to
    do per cascade)."""
    finish: object
    on_cascade: object = None

    def __call__(self, cascades):
        return self.finish(cascades)


def _finish(state, far, frame, needed, air_grid, start_air_tables, luts_object, clouds, cascades,
            maps=None) -> dict:
    """The lit-length tables of ``cascades`` (the nodes ``needed``) and the in-scattering
    tables (``start_air_tables()()``, built meanwhile) into their images; the "OLS Frame
    Values" rows (see building)."""
    if float(cascades.far_depths[-1]) != far:
        raise ValueError(f"the epipolar grid was laid out for cascades to {far} m, these end at "
                         f"{float(cascades.far_depths[-1])} m")
    air_tables, air = start_air_tables(), air_grid[0]
    settings, camera = state.settings, state.camera
    width, height = state.render_size
    tables = epipolar.build_tables(frame, cascades, camera, epipolar_grid.settings_from(settings),
                                   settings.smooth_shadows, settings.best_cascade_search,
                                   settings.first_cascade_to_ray_march, luts_object,
                                   settings.single_scattering_mode == "INTEGRATION", clouds,
                                   needed=needed, maps=maps if _maps_fit(maps, cascades) else None)
    _write_lit_tables(frame, tables, settings, camera, width, height)
    for name, pixels in nodes.epipolar.pack_air(air_tables()).items():
        luts.write_data_image(name, pixels)
    values = frame.as_values()
    values["Epipolar Depth"] = (frame.t_max, frame.growth, air.t_max)
    values["Epipolar Air Grid"] = (air.slices, air.samples, air.steps)
    return values


def _maps_fit(maps, cascades) -> bool:
    return maps is not None and maps.high.shape[0] == cascades.count and maps.high.shape[-1] == -(
        -cascades.resolution // min_max.BLOCK)


def update_analytic(state, cascades, media) -> dict:
    """``update`` under the analytic model (``media``: lut_gen.model.analytic.media of the scene):
    the lit-length tables and, for INTEGRATION, their closed-form integral
    (lut_gen.passes.analytic_shafts.build_epipolar_tables, the twin's own call); no in-scattering
    tables, whose part the shaft group computes per pixel."""
    width, height = state.render_size
    frame, tables = analytic_shafts.build_epipolar_tables(media, state.camera, state.sun_direction, cascades,
                                                          state.settings, width, height)
    _write_lit_tables(frame, tables, state.settings, state.camera, width, height)
    values = frame.as_values()
    values["Epipolar Depth"] = (frame.t_max, frame.growth, frame.t_max)    # z: read by the tables' group only
    return values


# The last frame's lit-length pixels, packed into again next frame: fresh memory of their size
# (64 MiB at 512 slices x 256 samples x 32 steps) cost its page faults on every frame (up to
# 0.1 s for the forest). Dropped with the shadow maps' atlas (release_buffers).
_pixel_buffers = {}


def release_buffers():
    _pixel_buffers.clear()


def _write_lit_tables(frame, tables, settings, camera, width, height):
    """The lit-length tables, the integral table (when built) and Show Sampling's overlay into
    their images."""
    lit, integral = nodes.epipolar.pack(tables, _pixel_buffers.pop("lit", (None, None)))
    _pixel_buffers["lit"] = (lit, integral)
    luts.write_data_image(names.EPIPOLAR_LIT_IMAGE, lit)
    if integral is not None:
        luts.write_data_image(names.EPIPOLAR_INTEGRAL_IMAGE, integral)
    overlay = np.zeros((1, 1, 4), dtype=np.float32)
    if settings.show_sampling:
        dots = epipolar.sampling_overlay(frame, tables.marched, camera, width, height)
        overlay = np.zeros((height, width, 4), dtype=np.float32)
        overlay[..., 0] = dots
    luts.write_data_image(names.EPIPOLAR_SAMPLING_IMAGE, overlay)
