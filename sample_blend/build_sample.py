"""Build the sample terrain scene of the "Outdoor Light Scattering" sample.

Pure bpy + numpy (no add-on imports), usable two ways:

* as a module::

      from sample_blend import build_sample      # or load it by file path
      objs = build_sample.build_sample_scene(bpy.context.scene, elevation_deg=8.0)

* as a script (writes a .blend; relative paths are relative to the repository root)::

      python sample_blend/build_sample.py --out sample_blend/sample.blend          # bpy module
      blender --background --python sample_blend/build_sample.py -- --out x.blend  # Blender
      ... --wire     # afterwards run bpy.ops.ols.setup_scene() (the add-on's scene wiring)

Scene layout (1 Blender unit = 1 m, Z up, ground at z = 0):

* "OLS Terrain": a ``size_m`` x ``size_m`` height field centred on the origin. A gentle valley
  runs along +Y past the camera; a ridge of mountains (peaks ~600-1200 m) crosses the terrain
  about 3.9 km in front of the camera (around y = +0.2 * size_m), with a high plateau behind it.
* "OLS Camera": 40 m above the valley floor near the -Y edge (y = -0.45 * size_m), looking
  along +Y and 4 degrees up, 28 mm lens.
* "OLS Sun": a Sun lamp; azimuth is measured from +Y toward +X, so the default azimuth 0 puts
  the sun straight ahead of the camera, behind the ridge. At low sun the mountains cast long
  shadows toward the camera.
"""
from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import bpy
from mathutils import Euler, Matrix, Vector

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUT = "sample_blend/sample.blend"

TERRAIN_NAME = "OLS Terrain"
TERRAIN_MATERIAL_NAME = "OLS Terrain Base"
CAMERA_NAME = "OLS Camera"
SUN_NAME = "OLS Sun"
SUN_STRENGTH = 10.0           # extraterrestrial sun intensity of the sample (the add-on's convention)
WORLD_NAME = "Sample Placeholder World"   # the add-on wires its own "OLS World"

# Layout, as fractions of the terrain size (the terrain spans [-size/2, size/2] in x and y).
CAMERA_Y_FRACTION = -0.45      # camera 0.05 * size from the -Y edge
RIDGE_Y_FRACTION = 0.20        # ridge line, ~0.65 * size in front of the camera
CAMERA_HEIGHT_M = 40.0         # above the terrain surface under the camera
CAMERA_PITCH_DEG = 4.0         # above the horizontal
CAMERA_LENS_MM = 28.0
PEAK_HEIGHT_M = 1080.0         # ridge component peak; with the valley floor the top is ~1.2 km

SUN_ANGLE_DEG = 0.545          # the sun's angular diameter


# --------------------------------------------------------------------------------------------
# Heightmap (pure numpy)
# --------------------------------------------------------------------------------------------

def _fade(t: np.ndarray) -> np.ndarray:
    """Quintic smoothstep (C2-continuous value-noise interpolation)."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def _value_noise(rng: np.random.Generator, u: np.ndarray, v: np.ndarray, cells: int) -> np.ndarray:
    """Value noise in [-1, 1] on a ``cells`` x ``cells`` lattice; ``u``, ``v`` in [0, 1]."""
    lattice = rng.uniform(-1.0, 1.0, size=(cells + 1, cells + 1))
    fu = np.clip(u, 0.0, 1.0) * cells
    fv = np.clip(v, 0.0, 1.0) * cells
    iu = np.minimum(fu.astype(np.int64), cells - 1)
    iv = np.minimum(fv.astype(np.int64), cells - 1)
    tu = _fade(fu - iu)
    tv = _fade(fv - iv)
    a = lattice[iv, iu]
    b = lattice[iv, iu + 1]
    c = lattice[iv + 1, iu]
    d = lattice[iv + 1, iu + 1]
    top = a + (b - a) * tu
    bottom = c + (d - c) * tu
    return top + (bottom - top) * tv


def _fbm(rng, u, v, base_cells: int, octaves: int, gain: float = 0.5) -> np.ndarray:
    """Fractal Brownian motion of value noise, normalised to roughly [-1, 1]."""
    total = np.zeros_like(u)
    amplitude, norm = 1.0, 0.0
    for octave in range(octaves):
        total += amplitude * _value_noise(rng, u, v, base_cells * 2 ** octave)
        norm += amplitude
        amplitude *= gain
    return total / norm


def _ridged(rng, u, v, base_cells: int, octaves: int, gain: float = 0.5) -> np.ndarray:
    """Ridged multifractal (Musgrave): sharp crests where the noise crosses zero, in [0, 1]."""
    total = np.zeros_like(u)
    weight = np.ones_like(u)
    amplitude, norm = 1.0, 0.0
    for octave in range(octaves):
        signal = 1.0 - np.abs(_value_noise(rng, u, v, base_cells * 2 ** octave))
        signal = signal * signal * weight
        weight = np.clip(signal * 2.0, 0.0, 1.0)
        total += amplitude * signal
        norm += amplitude
        amplitude *= gain
    return total / norm


def _smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


# Grid on which the height field's normalisation constants are measured, whatever the output
# resolution, so that every resolution samples the same landscape (same peaks, same floor).
_REFERENCE_RESOLUTION = 257


def _terrain_fields(u: np.ndarray, v: np.ndarray, seed: int):
    """Unnormalised parts of the height field at terrain coordinates ``u``, ``v`` in [0, 1]
    (u along +X, v along +Y): ``(crests, shape, ground)``: ridged noise (unnormalised), the
    mountains' envelope (ridge mask x peak modulation, <= 1) and the valley ground in metres."""
    rng = np.random.default_rng(seed)   # fresh per call: the same lattices for every grid
    # Ridge line: a wavy crest across the terrain around v = 0.5 + RIDGE_Y_FRACTION.
    wobble = _fbm(rng, u, np.full_like(v, 0.5), 3, 3)
    ridge_v = 0.5 + RIDGE_Y_FRACTION + 0.035 * np.sin(2.0 * np.pi * 1.3 * u + 0.7) + 0.03 * wobble
    d = (v - ridge_v) / 0.11                     # signed distance to the crest, in ridge widths
    front = np.exp(-d * d)                        # toward the camera: falls off to the valley
    back = 0.55 + 0.45 * np.exp(-d * d / 2.5)     # behind: a high plateau hides the far edge
    mask = np.where(d < 0.0, front, back)
    # Mountains: ridged noise for sharp crests, a low-frequency envelope for distinct peaks.
    crests = _ridged(rng, u, v, 6, 6)
    envelope = 0.5 + 0.5 * (0.5 + 0.5 * _fbm(rng, u, v, 3, 2))
    # Valley: gentle rolling ground (a few tens of m), rising toward the sides (in metres).
    rolling = 25.0 * (0.5 + 0.5 * _fbm(rng, u, v, 8, 5))
    sides = 160.0 * _smoothstep(0.12, 0.5, np.abs(u - 0.5)) ** 2 * (0.7 + 0.3 * _fbm(rng, u, v, 4, 3))
    return crests, mask * envelope, rolling + np.maximum(sides, 0.0)


def _combine(fields, crest_range, mountain_max, floor):
    crests, shape, ground = fields
    lo, hi = crest_range
    crests = np.clip((crests - lo) / max(hi - lo, 1e-12), 0.0, 1.0)
    mountains = shape * (0.35 + 0.65 * crests)
    return mountains * (PEAK_HEIGHT_M / mountain_max) + ground - floor


def terrain_heightmap(size_m: float = 6000.0, resolution: int = 256, seed: int = 7):
    """The terrain's height field: ``(xs, ys, heights)``.

    ``xs`` and ``ys`` are the ``resolution`` grid coordinates in metres (centred on the origin);
    ``heights[i, j]`` is the height at ``(xs[j], ys[i])``, >= 0 (the floor is at 0). Deterministic
    for a given ``seed``; the same landscape at every resolution (finer grids sample it more
    densely); the layout scales with ``size_m`` in x and y (see the module docstring).
    """
    if resolution < 2:
        raise ValueError(f"resolution must be >= 2, got {resolution}")
    if not size_m > 0:
        raise ValueError(f"size_m must be > 0, got {size_m}")
    s = float(size_m)

    # Normalisation constants from the fixed reference grid.
    ref = np.linspace(0.0, 1.0, _REFERENCE_RESOLUTION)
    ref_fields = _terrain_fields(*np.meshgrid(ref, ref), seed)
    crests, shape, _ = ref_fields
    crest_range = (float(crests.min()), float(crests.max()))
    mountain_max = float(_combine((crests, shape, 0.0), crest_range, 1.0, 0.0).max()) / PEAK_HEIGHT_M
    ref_heights = _combine(ref_fields, crest_range, mountain_max, 0.0)
    floor = float(ref_heights.min())

    lin = np.linspace(0.0, 1.0, resolution)
    if resolution == _REFERENCE_RESOLUTION:
        heights = ref_heights - floor
    else:
        fields = _terrain_fields(*np.meshgrid(lin, lin), seed)   # rows along +Y
        heights = _combine(fields, crest_range, mountain_max, floor)
    heights = np.maximum(heights, 0.0)
    xs = (lin - 0.5) * s
    return xs, xs.copy(), heights


# --------------------------------------------------------------------------------------------
# Terrain object
# --------------------------------------------------------------------------------------------

def _remove_object(name: str) -> None:
    """Remove an existing object of that name (and its now unused data) so names stay exact."""
    obj = bpy.data.objects.get(name)
    if obj is None:
        return
    data = obj.data
    bpy.data.objects.remove(obj, do_unlink=True)
    if data is not None and data.users == 0:
        for kind, collection in ((bpy.types.Mesh, bpy.data.meshes),
                                 (bpy.types.Camera, bpy.data.cameras),
                                 (bpy.types.Light, bpy.data.lights)):
            if isinstance(data, kind):
                collection.remove(data)
                break


def _ensure_node_tree(idblock) -> None:
    """Give a material/world its node tree. Blender 5 creates material trees up front and
    deprecates ``use_nodes`` (new worlds still need it), so set it only when there is none."""
    if idblock.node_tree is None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            idblock.use_nodes = True


# Ground covers (linear albedo): measured spectral albedos averaged to RGB, roughly (grass
# 0.05-0.15, dry scrub 0.15-0.25, bare rock 0.15-0.3, old snow 0.6-0.8).
GRASS_ALBEDO = (0.055, 0.085, 0.030, 1.0)
SCRUB_ALBEDO = (0.150, 0.130, 0.080, 1.0)
ROCK_ALBEDO = (0.200, 0.180, 0.160, 1.0)
SNOW_ALBEDO = (0.700, 0.720, 0.760, 1.0)
SNOW_LINE_M = 850.0            # snow lies above this on slopes flatter than ~35 deg
ROCK_SLOPE_COS = (0.92, 0.80)  # from grass (cos slope above the first) to rock (below the second)


def _socket(sockets, identifier):
    return next(socket for socket in sockets if socket.identifier == identifier)


def _mix_colour(tree, factor, a, b):
    """A Mix node (colour) of sockets/values ``a`` and ``b`` by ``factor``; returns its output."""
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    for identifier, value in (("Factor_Float", factor), ("A_Color", a), ("B_Color", b)):
        socket = _socket(mix.inputs, identifier)
        if isinstance(value, bpy.types.NodeSocket):
            tree.links.new(value, socket)
        else:
            socket.default_value = value
    return _socket(mix.outputs, "Result_Color")


def _map_range(tree, value, low, high):
    """0 at ``low``, 1 at ``high`` (either order), smoothstep in between."""
    node = tree.nodes.new("ShaderNodeMapRange")
    node.interpolation_type = "SMOOTHSTEP"
    tree.links.new(value, node.inputs["Value"])
    node.inputs["From Min"].default_value, node.inputs["From Max"].default_value = low, high
    return node.outputs["Result"]


def _terrain_material() -> bpy.types.Material:
    """Ground covers by slope and height from Blender's own procedural textures: grass and dry
    scrub in the valley (mottled by noise), bare rock on steep slopes, snow on the high, flatter
    ground. The colour feeds the Principled BSDF's Base Color, which the add-on's OLS Terrain
    group takes over (it keeps this network)."""
    mat = bpy.data.materials.get(TERRAIN_MATERIAL_NAME)
    if mat is not None:
        return mat
    mat = bpy.data.materials.new(TERRAIN_MATERIAL_NAME)
    _ensure_node_tree(mat)
    tree = mat.node_tree
    tree.nodes.clear()
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    bsdf.inputs["Roughness"].default_value = 0.9
    bsdf.inputs["Specular IOR Level"].default_value = 0.2

    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    normal = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(geometry.outputs["Normal"], normal.inputs["Vector"])
    position = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(geometry.outputs["Position"], position.inputs["Vector"])
    # Large patches (~300 m) and fine mottling (~20 m) break up every boundary.
    patches, mottle = (tree.nodes.new("ShaderNodeTexNoise") for _ in range(2))
    for noise, scale, detail in ((patches, 0.003, 4.0), (mottle, 0.05, 6.0)):
        tree.links.new(geometry.outputs["Position"], noise.inputs["Vector"])
        noise.inputs["Scale"].default_value = scale
        noise.inputs["Detail"].default_value = detail
    cover = _mix_colour(tree, _map_range(tree, patches.outputs["Fac"], 0.42, 0.62), GRASS_ALBEDO, SCRUB_ALBEDO)
    cover = _mix_colour(tree, _map_range(tree, mottle.outputs["Fac"], 0.3, 0.7), cover,
                        tuple(0.8 * c for c in SCRUB_ALBEDO[:3]) + (1.0,))
    jitter = tree.nodes.new("ShaderNodeMath")                 # slope threshold wanders with the noise
    jitter.operation = "MULTIPLY_ADD"
    tree.links.new(mottle.outputs["Fac"], jitter.inputs[0])
    jitter.inputs[1].default_value = 0.08
    tree.links.new(normal.outputs["Z"], jitter.inputs[2])
    rock = _map_range(tree, jitter.outputs[0], ROCK_SLOPE_COS[0] + 0.04, ROCK_SLOPE_COS[1] + 0.04)
    ground = _mix_colour(tree, rock, cover, ROCK_ALBEDO)
    high = tree.nodes.new("ShaderNodeMath")
    high.operation = "MULTIPLY_ADD"                           # a ragged snow line
    tree.links.new(patches.outputs["Fac"], high.inputs[0])
    high.inputs[1].default_value = 250.0
    tree.links.new(position.outputs["Z"], high.inputs[2])
    flat = _map_range(tree, normal.outputs["Z"], 0.72, 0.85)
    snow = tree.nodes.new("ShaderNodeMath")
    snow.operation = "MULTIPLY"
    tree.links.new(_map_range(tree, high.outputs[0], SNOW_LINE_M + 125.0, SNOW_LINE_M + 225.0), snow.inputs[0])
    tree.links.new(flat, snow.inputs[1])
    tree.links.new(_mix_colour(tree, snow.outputs[0], ground, SNOW_ALBEDO), bsdf.inputs["Base Color"])
    mat.diffuse_color = ROCK_ALBEDO       # viewport solid colour
    mat.roughness = 0.9
    return mat


def build_terrain(scene: bpy.types.Scene, size_m: float = 6000.0, resolution: int = 256,
                  seed: int = 7) -> bpy.types.Object:
    """Create the "OLS Terrain" height-field object (replacing an existing one) in ``scene``.

    ``resolution`` is the number of vertices per side. The object carries its grid as custom
    properties (``ols_size_m``, ``ols_resolution``, ``ols_seed``) for :func:`terrain_height_at`.
    """
    xs, ys, heights = terrain_heightmap(size_m, resolution, seed)
    n = resolution
    gx, gy = np.meshgrid(xs, ys)
    co = np.stack([gx.ravel(), gy.ravel(), heights.ravel()], axis=1).astype(np.float32)

    idx = np.arange(n * n, dtype=np.int32).reshape(n, n)
    # Counter-clockwise seen from above (+x then +y): normals point up (+Z).
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1).reshape(-1, 4)
    n_faces = quads.shape[0]

    _remove_object(TERRAIN_NAME)
    mesh = bpy.data.meshes.new(TERRAIN_NAME)
    mesh.vertices.add(n * n)
    mesh.vertices.foreach_set("co", co.ravel())
    mesh.loops.add(4 * n_faces)
    mesh.loops.foreach_set("vertex_index", quads.ravel())
    mesh.polygons.add(n_faces)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 4 * n_faces, 4, dtype=np.int32))

    # Planar UVs over the whole terrain (0..1), handy for textures the add-on may add.
    uv_layer = mesh.uv_layers.new(name="UVMap")
    span = float(size_m)
    uv = np.stack([(co[:, 0] + 0.5 * span) / span, (co[:, 1] + 0.5 * span) / span], axis=1)
    uv_layer.data.foreach_set("uv", uv[quads.ravel()].astype(np.float32).ravel())

    mesh.update(calc_edges=True)
    mesh.shade_smooth()
    mesh.materials.append(_terrain_material())

    obj = bpy.data.objects.new(TERRAIN_NAME, mesh)
    obj["ols_size_m"] = float(size_m)
    obj["ols_resolution"] = int(resolution)
    obj["ols_seed"] = int(seed)
    scene.collection.objects.link(obj)
    return obj


def terrain_heights(obj: bpy.types.Object) -> np.ndarray:
    """The terrain's vertex heights as a ``(resolution, resolution)`` array (rows along +Y)."""
    n = int(obj["ols_resolution"])
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(n, n, 3)[:, :, 2].astype(np.float64)


def terrain_height_at(obj: bpy.types.Object, x: float, y: float) -> float:
    """Bilinear height of the terrain's surface at world ``(x, y)`` (object at the origin,
    unrotated, as built); coordinates outside are clamped to the edge."""
    n = int(obj["ols_resolution"])
    s = float(obj["ols_size_m"])
    h = terrain_heights(obj)
    fx = min(max((x - obj.location.x) / s + 0.5, 0.0), 1.0) * (n - 1)
    fy = min(max((y - obj.location.y) / s + 0.5, 0.0), 1.0) * (n - 1)
    j, i = min(int(fx), n - 2), min(int(fy), n - 2)
    tx, ty = fx - j, fy - i
    top = h[i, j] * (1 - tx) + h[i, j + 1] * tx
    bottom = h[i + 1, j] * (1 - tx) + h[i + 1, j + 1] * tx
    return float(top * (1 - ty) + bottom * ty + obj.location.z)


# --------------------------------------------------------------------------------------------
# Camera
# --------------------------------------------------------------------------------------------

def build_camera(scene: bpy.types.Scene) -> bpy.types.Object:
    """Create "OLS Camera" near the -Y edge, 40 m above the terrain, looking +Y and 4 deg up.

    Uses the scene's "OLS Terrain" (if any) for its size and the ground height; without one it
    assumes a 6 km flat ground at z = 0. Sets ``scene.camera``.
    """
    terrain = bpy.data.objects.get(TERRAIN_NAME)
    if terrain is not None and TERRAIN_NAME in scene.objects and "ols_size_m" in terrain:
        size = float(terrain["ols_size_m"])
        x, y = 0.0, CAMERA_Y_FRACTION * size
        ground = terrain_height_at(terrain, x, y)
    else:
        x, y, ground = 0.0, CAMERA_Y_FRACTION * 6000.0, 0.0

    _remove_object(CAMERA_NAME)
    cam = bpy.data.cameras.new(CAMERA_NAME)
    cam.type = "PERSP"
    cam.lens = CAMERA_LENS_MM
    cam.sensor_width = 36.0
    cam.sensor_fit = "AUTO"
    cam.clip_start = 0.5
    cam.clip_end = 1.0e6

    obj = bpy.data.objects.new(CAMERA_NAME, cam)
    obj.location = (x, y, ground + CAMERA_HEIGHT_M)
    # A camera looks along its local -Z; rotating it by 90 deg about X points it along +Y,
    # and the extra pitch tilts it up.
    obj.rotation_mode = "XYZ"
    obj.rotation_euler = Euler((math.radians(90.0 + CAMERA_PITCH_DEG), 0.0, 0.0), "XYZ")
    scene.collection.objects.link(obj)
    scene.camera = obj
    return obj


def camera_forward(obj: bpy.types.Object) -> Vector:
    """World-space viewing direction of a camera object (its local -Z), unit length."""
    return (_world_rotation(obj) @ Vector((0.0, 0.0, -1.0))).normalized()


# --------------------------------------------------------------------------------------------
# Sun
# --------------------------------------------------------------------------------------------

def sun_direction(elevation_deg: float, azimuth_deg: float) -> Vector:
    """Unit vector toward the sun: elevation above the horizon, azimuth from +Y toward +X."""
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return Vector((math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)))


def sun_rotation(elevation_deg: float, azimuth_deg: float) -> Euler:
    """XYZ Euler for a Sun lamp whose local +Z (the direction toward the sun; it shines along
    -Z) has the given elevation and azimuth (from +Y toward +X).

    R = Rz(-az) @ Rx(el - 90 deg): Rx turns +Z to (0, cos el, sin el), Rz then swings it
    from +Y toward +X by ``az``.
    """
    return Euler((math.radians(elevation_deg - 90.0), 0.0, math.radians(-azimuth_deg)), "XYZ")


def _world_rotation(obj: bpy.types.Object) -> Matrix:
    """Rotation part of the object's world matrix, computed from its current properties (unlike
    ``obj.matrix_world``, which is only refreshed by a depsgraph update)."""
    matrix = obj.matrix_basis.copy()
    parent = obj.parent
    while parent is not None:
        matrix = parent.matrix_basis @ (obj.matrix_parent_inverse @ matrix)
        obj, parent = parent, parent.parent
    return matrix.to_3x3().normalized()


def direction_to_sun(obj: bpy.types.Object) -> Vector:
    """World-space unit vector toward the sun for a Sun lamp object (its local +Z)."""
    return (_world_rotation(obj) @ Vector((0.0, 0.0, 1.0))).normalized()


def elevation_azimuth(direction) -> tuple[float, float]:
    """Inverse of :func:`sun_direction`: (elevation_deg, azimuth_deg in (-180, 180])."""
    d = Vector(direction).normalized()
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, d.z))))
    azimuth = math.degrees(math.atan2(d.x, d.y))
    return elevation, azimuth


def build_sun(scene: bpy.types.Scene, elevation_deg: float = 8.0,
              azimuth_deg: float = 0.0) -> bpy.types.Object:
    """Create the "OLS Sun" Sun lamp (strength 1, angular diameter 0.545 deg) aimed so that the
    direction toward the sun has the given elevation and azimuth (from +Y toward +X)."""
    _remove_object(SUN_NAME)
    light = bpy.data.lights.new(SUN_NAME, type="SUN")
    light.energy = SUN_STRENGTH
    light.angle = math.radians(SUN_ANGLE_DEG)
    light.color = (1.0, 1.0, 1.0)
    obj = bpy.data.objects.new(SUN_NAME, light)
    obj.location = (0.0, 0.0, 1500.0)  # irrelevant for a sun; above the terrain for the viewport
    obj.rotation_mode = "XYZ"
    obj.rotation_euler = sun_rotation(elevation_deg, azimuth_deg)
    scene.collection.objects.link(obj)
    return obj


# --------------------------------------------------------------------------------------------
# Whole scene
# --------------------------------------------------------------------------------------------

def _placeholder_world(scene: bpy.types.Scene) -> bpy.types.World:
    """A plain pale-blue world if the scene has none (the add-on wires the real sky later)."""
    if scene.world is not None:
        return scene.world
    world = bpy.data.worlds.get(WORLD_NAME) or bpy.data.worlds.new(WORLD_NAME)
    _ensure_node_tree(world)
    background = next((n for n in world.node_tree.nodes if n.type == "BACKGROUND"), None)
    if background is not None:
        background.inputs["Color"].default_value = (0.45, 0.6, 0.85, 1.0)
        background.inputs["Strength"].default_value = 1.0
    world.color = (0.45, 0.6, 0.85)
    scene.world = world
    return world


def build_sample_scene(scene: bpy.types.Scene | None = None, elevation_deg: float = 8.0,
                       azimuth_deg: float = 0.0, *, size_m: float = 6000.0,
                       resolution: int = 256, seed: int = 7) -> dict:
    """Build terrain, camera and sun in ``scene`` (default: the context scene) and set the
    render settings (Cycles, 1280 x 720, metric units, opaque film).

    Returns ``{"terrain", "camera", "sun", "world", "scene"}``. Re-running replaces the OLS
    objects instead of adding numbered copies.
    """
    if scene is None:
        scene = bpy.context.scene
    terrain = build_terrain(scene, size_m=size_m, resolution=resolution, seed=seed)
    camera = build_camera(scene)
    sun = build_sun(scene, elevation_deg=elevation_deg, azimuth_deg=azimuth_deg)
    world = _placeholder_world(scene)

    scene.render.engine = "CYCLES"
    scene.render.resolution_x = 1280
    scene.render.resolution_y = 720
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.unit_settings.system = "METRIC"
    scene.unit_settings.scale_length = 1.0
    scene.unit_settings.length_unit = "METERS"
    return {"terrain": terrain, "camera": camera, "sun": sun, "world": world, "scene": scene}


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------

def _script_args(argv: list[str]) -> list[str]:
    """Arguments meant for this script: everything after ``--`` when present (Blender's
    convention), else ``argv[1:]`` (nothing when run by the Blender executable)."""
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    if bpy.app.binary_path and argv and Path(argv[0]).name == Path(bpy.app.binary_path).name:
        return []   # inside the Blender executable without "--": argv holds Blender's own flags
    return argv[1:]


def _operator_exists(module: str, name: str) -> bool:
    # bpy.ops.<module>.<name> always resolves to a wrapper (hasattr is always True); the list of
    # really registered operators is what dir() returns.
    return name in dir(getattr(bpy.ops, module))


def _register_extension_from_repo() -> None:
    """Register the extension from this checkout (the way scripts/render.py does), so that
    --wire also works with the bpy module or a Blender without the extension installed."""
    spec = importlib.util.spec_from_file_location("ols_render_launcher", REPO_ROOT / "scripts" / "render.py")
    launcher = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(launcher)
    launcher.import_extension()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="build_sample.py",
        description="Build the Outdoor Light Scattering sample terrain scene into a .blend file.")
    parser.add_argument("--out", default=DEFAULT_OUT,
                        help=f"output .blend (relative to the repository root; default {DEFAULT_OUT})")
    parser.add_argument("--elevation", type=float, default=8.0, help="sun elevation, degrees")
    parser.add_argument("--azimuth", type=float, default=0.0,
                        help="sun azimuth, degrees from +Y (camera forward) toward +X")
    parser.add_argument("--resolution", type=int, default=256, help="terrain vertices per side")
    parser.add_argument("--seed", type=int, default=7, help="terrain noise seed")
    parser.add_argument("--tables", choices=("default", "draft"), default="default",
                        help="table resolution baked by --wire")
    parser.add_argument("--wire", action="store_true",
                        help="after building, run bpy.ops.ols.setup_scene() (needs the add-on enabled)")
    args = parser.parse_args(_script_args(sys.argv if argv is None else argv))
    if args.resolution < 2:
        parser.error("--resolution must be >= 2")

    out = Path(args.out)
    if not out.is_absolute():
        out = REPO_ROOT / out
    out.parent.mkdir(parents=True, exist_ok=True)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    start = time.perf_counter()
    build_sample_scene(bpy.context.scene, elevation_deg=args.elevation, azimuth_deg=args.azimuth,
                       resolution=args.resolution, seed=args.seed)
    print(f"build_sample: scene built in {time.perf_counter() - start:.2f} s")

    if args.wire:
        if not _operator_exists("ols", "setup_scene"):
            _register_extension_from_repo()
        if not _operator_exists("ols", "setup_scene"):
            print("build_sample: error: --wire needs the operator bpy.ops.ols.setup_scene, which is "
                  "not registered; enable the Outdoor Light Scattering extension first (e.g. run "
                  "inside Blender with the extension installed)", file=sys.stderr)
            return 2
        terrain = bpy.data.objects[TERRAIN_NAME]
        for obj in bpy.context.scene.objects:
            obj.select_set(obj == terrain)
        bpy.context.view_layer.objects.active = terrain
        result = bpy.ops.ols.setup_scene(resolution=args.tables)
        if "FINISHED" not in result:
            print(f"build_sample: error: bpy.ops.ols.setup_scene() returned {set(result)}",
                  file=sys.stderr)
            return 3

    bpy.ops.wm.save_as_mainfile(filepath=str(out))
    print(f"build_sample: wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
