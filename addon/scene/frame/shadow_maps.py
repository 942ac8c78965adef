"""The sun's cascaded shadow maps for the light-shaft pass: the scene's evaluated meshes
rendered orthographically along the sun direction by lut_gen.passes.shadow_map, stored in two
images the "OLS Light Shafts" group reads ("OLS Shadow Map", "OLS Shadow Cascades").

They are rendered again before each frame is composited (see frame_update), since sun, camera
and geometry may all have moved (frame_state has the camera and sun of the frame); the camera model and the cascade rectangles reach the group
through the "OLS Frame Values" image.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import bpy
import numpy as np

from ....lut_gen.passes import scattering_pass, shadow_map, shadow_raster
from ....lut_gen.tables import process_tuning
from ..tables import luts
from . import frame_state
from .. import names

MIN_NEAR = 1.0              # m: the first split; the camera's clip start when larger


def scene_triangles(depsgraph, threads: int = 1) -> np.ndarray:
    """(M, 3, 3) world-space triangles of every evaluated mesh that casts shadows, instances
    included. Instances of one geometry (a forest of instanced trees, a colonnade of linked
    duplicates) share its local triangles, read once, and are placed by their matrices in one
    numpy product: for 10 000 instanced trees 0.22 s a frame, against 0.54 s reading the
    mesh again for each (bench/bench_instances.py). ``threads``: how many share the placing
    (the forest's 0.66 M triangles: 0.05 s on one)."""
    local = {}          # geometry -> (3T, 3) local triangle corners, or None without triangles
    placed = {}         # geometry -> the world matrices of its instances
    for instance in depsgraph.object_instances:
        # Tested per instance, not cached per object: Blender hands every geometry-nodes
        # instance in one temporary object, its data swapped.
        key = _geometry_key(instance.object)
        if key is None:
            continue
        if key not in local:
            local[key] = _local_corners(instance.object)
        if local[key] is not None:
            placed.setdefault(key, []).append(np.array(instance.matrix_world, dtype=np.float64))
    # Every instance's corners written once, straight into the result: adding the translations
    # into a temporary and concatenating copied the forest's 0.66 M triangles twice (0.08 s).
    counts = [len(local[key]) * len(matrices) for key, matrices in placed.items()]
    triangles = np.empty((sum(counts), 3))
    parts = []
    for (key, matrices), end in zip(placed.items(), np.cumsum(counts)):
        matrices = np.stack(matrices)
        corners = local[key]
        out = triangles[end - len(corners) * len(matrices):end].reshape(len(matrices), len(corners), 3)
        pieces = max(1, min(threads, len(matrices) // 256))      # a thread's share worth its start
        bounds = np.linspace(0, len(matrices), pieces + 1).astype(int)
        parts += [(corners, matrices[a:b], out[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]
    if threads <= 1 or len(parts) <= 1:
        for part in parts:
            _place(*part)
    else:
        with ThreadPoolExecutor(min(threads, len(parts)), thread_name_prefix="OLS shadow casters") as pool:
            for done in [pool.submit(_place, *part) for part in parts]:
                done.result()
    return triangles.reshape(-1, 3, 3)


def _geometry_key(obj):
    """The key of the evaluated mesh ``obj`` casts its shadow with (shared by the instances of
    one geometry, apart for each object whose modifiers made its own); None when it casts none."""
    if obj.type != "MESH" or not getattr(obj, "visible_shadow", True) or obj.hide_render:
        return None
    if obj.name == names.CLOUD_SHADOW_OBJECT:
        # The clouds' shadow-only layer is a partial occluder, not a solid one: the shadow
        # maps would make it a roof over the whole scene.
        return None
    return obj.data.as_pointer() if obj.data is not None else obj.as_pointer()


def _place(corners, matrices, out):
    """Local corners (3T, 3) placed by each of ``matrices`` (N, 4, 4) into ``out`` (N, 3T, 3)."""
    # All instances' rotations side by side, (3, 3N): one matrix product places every corner
    # of every instance (einsum took 0.4 s for the forest, this 0.04 s).
    rotations = matrices[:, :3, :3].transpose(2, 0, 1).reshape(3, -1)
    world = (corners @ rotations).reshape(len(corners), len(matrices), 3).transpose(1, 0, 2)
    np.add(world, matrices[:, None, :3, 3], out=out)


def _local_corners(obj):
    """(3T, 3) the evaluated mesh's triangle corners in object space; None without triangles."""
    mesh = obj.to_mesh()
    try:
        mesh.calc_loop_triangles()
        count = len(mesh.loop_triangles)
        if count == 0:
            return None
        coordinates = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", coordinates)
        indices = np.empty(count * 3, dtype=np.int64)
        mesh.loop_triangles.foreach_get("vertices", indices)
    finally:
        obj.to_mesh_clear()
    return coordinates.reshape(-1, 3)[indices]


def far_depth(camera: shadow_map.Camera, triangles, clip_end: float, near: float) -> float:
    """View depth of the farthest geometry (capped by the camera's clip end): beyond it nothing
    can shadow the air."""
    if len(triangles) == 0:
        return max(near * 2.0, 1.0)
    # The corners' depths as one product, less the camera's: subtracting the position from
    # every corner first made a copy of them all (the forest's 2 M corners: 0.02 s a frame).
    forward = np.asarray(camera.forward, dtype=np.float64)
    depth = float(np.max(triangles.reshape(-1, 3) @ forward) - np.asarray(camera.position, dtype=np.float64) @ forward)
    return float(np.clip(depth, near * 2.0, max(clip_end, near * 2.0)))


@dataclass(frozen=True)
class Casters:
    """The frame's shadow casters: world-space triangles (M, 3, 3), and the view depths the
    cascades span (``far`` is their last split: the epipolar grid is laid out from it)."""
    triangles: np.ndarray
    near: float
    far: float


def casters(state: frame_state.FrameState, depsgraph) -> Casters:
    """The meshes as evaluated in ``depsgraph`` that cast shadows, and the cascades' depth range
    (reads Blender data: the main thread only)."""
    resolution = int(state.settings.shadow_map_resolution)
    if resolution < 16:
        raise frame_state.ShadowMapError(f"shadow map resolution {resolution} is too small; pick 512 or more")
    triangles = scene_triangles(depsgraph, process_tuning.cores())
    near = max(state.clip_start, MIN_NEAR)
    return Casters(triangles, near, far_depth(state.camera, triangles, state.camera.clip_end, near))


def rasterise(state: frame_state.FrameState, found: Casters, on_cascade=None) -> shadow_map.ShadowCascades:
    """The cascades of ``found`` for the frame's camera, sun and settings (``on_cascade``: as
    shadow_map.render_cascades takes it)."""
    settings = state.settings
    return shadow_map.render_cascades(found.triangles, state.camera, state.sun_direction,
                                      int(settings.shadow_map_resolution), settings.num_cascades,
                                      settings.cascade_partitioning_factor, found.near, found.far,
                                      threads=process_tuning.cores(), on_cascade=on_cascade)


def render(state: frame_state.FrameState, depsgraph) -> shadow_map.ShadowCascades:
    """Render the cascades for the frame's camera, sun and settings (meshes as evaluated in
    ``depsgraph``)."""
    return rasterise(state, casters(state, depsgraph))


# The last packed atlas, packed into again next frame (see pack_atlas): as large as the atlas
# image (32 MiB at the default 6 x 1024, 512 MiB at 6 x 4096), dropped with the images.
_atlas_buffer = {}


def write_images(cascades: shadow_map.ShadowCascades):
    """The packed atlas and parameter table into the two images (created or resized)."""
    atlas = shadow_map.pack_atlas(cascades, out=_atlas_buffer.pop("atlas", None))
    _atlas_buffer["atlas"] = atlas
    for name, pixels in ((names.SHADOW_MAP_IMAGE, atlas), (names.SHADOW_CASCADES_IMAGE, shadow_map.pack_parameters(cascades))):
        luts.write_data_image(name, pixels)


def release_buffer():
    """Free the atlas kept for the next frame (the shafts are off, or the scene is unwired)."""
    _atlas_buffer.clear()


def ensure_images(resolution: int, count: int):
    """The two images at the size ``resolution`` and ``count`` need (contents: all lit until
    the first render writes them)."""
    atlas = bpy.data.images.get(names.SHADOW_MAP_IMAGE)
    params = bpy.data.images.get(names.SHADOW_CASCADES_IMAGE)
    blocks = -(-count // shadow_map.CASCADES_PER_BLOCK)
    if (atlas is None or params is None or tuple(atlas.size) != (blocks * resolution, resolution)
            or tuple(params.size) != (count + 1, len(shadow_map.PARAM_ROWS))):
        empty = np.broadcast_to(np.float32(shadow_raster.EMPTY_DEPTH), (count, resolution, resolution))   # no copy
        write_images(shadow_map.ShadowCascades(np.eye(3), np.zeros((count, 2)), np.ones((count, 2)),
                                               np.ones(count), empty))
    return bpy.data.images[names.SHADOW_MAP_IMAGE], bpy.data.images[names.SHADOW_CASCADES_IMAGE]


def frame_values(cascades: shadow_map.ShadowCascades) -> dict:
    """The "OLS Frame Values" rows that come from the cascades."""
    values = {"Light Right": cascades.frame[0], "Light Up": cascades.frame[1],
              "Far Depth": float(cascades.far_depths[-1])}
    biases = cascades.biases()
    for i in range(cascades.count):
        values[f"Cascade {i} Center"] = (*cascades.centers[i], cascades.far_depths[i])
        values[f"Cascade {i} Half"] = (*cascades.halves[i], biases[i])
    return values


def camera_values(camera: shadow_map.Camera) -> dict:
    """The "OLS Frame Values" rows that come from the camera."""
    return {"Camera Position": camera.position, "Camera Forward": camera.forward,
            "Camera Right": camera.rotation[:, 0], "Camera Up": camera.rotation[:, 1],
            "Tan Half FOV": (camera.tan_half_fov[0], camera.tan_half_fov[1], 0.0),
            "Sky Depth": scattering_pass.sky_depth(camera.clip_end)}


def images_intact(shadow_test_group) -> bool:
    """False when the shadow-map images the group reads were removed or emptied (then the
    groups are rebuilt with new ones)."""
    if shadow_test_group is None:
        return False
    images = [node.image for node in shadow_test_group.nodes if node.bl_idname == "CompositorNodeImage"]
    return bool(images) and all(image is not None and image.size[0] > 0 and image.size[1] > 0 for image in images)


def remove_images(*extra_names):
    """Drop the shadow-map images (and ``extra_names``) when the scene is unwired."""
    release_buffer()
    for name in (names.SHADOW_MAP_IMAGE, names.SHADOW_CASCADES_IMAGE) + extra_names:
        image = bpy.data.images.get(name)
        if image is not None:
            bpy.data.images.remove(image)
