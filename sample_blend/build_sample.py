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
  runs along +Y past the camera; three ridges cross it at increasing distance, each higher than
  the one in front so that the aerial perspective shows as layers: foothills (~100 m) about
  1.4 km in front of the camera, a middle ridge (~250-550 m) about 2.9 km away and the main
  range (peaks ~600-1200 m, a high plateau behind it) about 4.5 km away (``RIDGES``). A pass
  cuts through all three toward azimuth ``GAP_AZIMUTH_DEG`` (20 deg, the ``sunset`` look's sun),
  down to the valley floor, so that a low sun shines through it toward the camera between the
  ridges' shadows.
* "OLS Camera": 40 m above the valley floor near the -Y edge (y = -0.45 * size_m), looking
  along +Y and 4 degrees up, 28 mm lens.
* "OLS Sun": a Sun lamp; azimuth is measured from +Y toward +X, so the default azimuth 0 puts
  the sun straight ahead of the camera, behind the ridges. At low sun the mountains cast long
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
# Three ridges across the valley at increasing distance, each higher than the one in front so
# that its crests show above it: (crest line y fraction, share of the peak height, front and back
# half-widths in terrain fractions, share of the ridge's height that does not depend on the crest
# noise: lower is more rugged). Seen from the camera they stand ~1.4, ~2.9 and ~4.5 km away.
RIDGES = (
    (-0.215, 0.12, 0.035, 0.045, 0.75),   # foothills, ~80-170 m
    (0.035, 0.60, 0.050, 0.060, 0.65),    # middle ridge, ~250-700 m
    (0.30, 1.00, 0.075, None, 0.50),      # main range, peaks ~0.9-1.2 km; a high plateau behind
)
GAP_AZIMUTH_DEG = 20.0         # a pass through every ridge, seen from the camera toward the
                               # azimuth of the `sunset` look: a low sun shines through it
CAMERA_HEIGHT_M = 40.0         # above the terrain surface under the camera
CAMERA_PITCH_DEG = 4.0         # above the horizontal
CAMERA_LENS_MM = 28.0
PEAK_HEIGHT_M = 1080.0         # mountains' peak; with the valley floor the top is ~1.2 km

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


def _smooth_max(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """max(a, b) with a rounded crease of width ``k`` where the two meet (a valley floor
    between two ridges instead of a sharp fold)."""
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return a + (b - a) * h + k * h * (1.0 - h)


def _terrain_fields(u: np.ndarray, v: np.ndarray, seed: int):
    """Unnormalised parts of the height field at terrain coordinates ``u``, ``v`` in [0, 1]
    (u along +X, v along +Y): ``(crests, shapes, cut, ground)``: ridged noise (unnormalised),
    one envelope per ridge (ridge mask x share of the peak height x crest line, <= 1), the
    pass through the ridges (0 on its floor, 1 away from it) and the valley ground in metres."""
    rng = np.random.default_rng(seed)   # fresh per call: the same lattices for every grid
    crests = _ridged(rng, u, v, 6, 6)   # sharp crests, shared by the ridges
    shapes = []
    side = np.abs(u - 0.5) * 2.0        # 0 on the view axis, 1 at the side edges
    # Noise along the ridges depends on u only: evaluated once per distinct u (grid column).
    u_values, u_index = np.unique(u, return_inverse=True)
    along_ridge = np.full_like(u_values, 0.5)

    def along_u(cells, octaves, gain=0.5):
        return _fbm(rng, u_values, along_ridge, cells, octaves, gain)[u_index].reshape(u.shape)

    # Spurs and gullies down the flanks: a ridge is wider where this noise is high.
    width = 0.65 + 0.7 * _fbm(rng, u, v, 10, 4)
    for k, (ridge_y, share, front_w, back_w, _base) in enumerate(RIDGES):
        # A wavy crest line across the terrain; the main range bends toward the camera at the
        # sides so that it still closes the view at the frame's edges.
        ridge_v = (0.5 + ridge_y + 0.03 * np.sin(2.0 * np.pi * (1.1 + 0.4 * k) * u + 0.7 + 1.9 * k)
                   + 0.025 * along_u(3, 3) - (0.06 * side * side if back_w is None else 0.0))
        # The crest's height along the ridge: jagged peaks and saddles.
        skyline = 0.7 + 0.3 * along_u(4 + 2 * k, 6, gain=0.55)
        d = (v - ridge_v) / width                         # signed distance to the crest
        front = np.exp(-(d / front_w) ** 2)               # toward the camera: down to the valley
        if back_w is None:                                # behind the main range: a high plateau
            back = 0.55 + 0.45 * np.exp(-(d / front_w) ** 2 / 2.5)
        else:
            back = np.exp(-(d / back_w) ** 2)
        mask = np.where(d < 0.0, front, back)
        if k == 1:      # the middle ridge is lower at the right, toward the `golden-hour` sun
            share = share * (1.0 - 0.4 * _smoothstep(0.6, 0.9, u))
        shapes.append(share * mask * skyline)
    # The pass: a valley floor ~60-120 m wide along the line of sight toward GAP_AZIMUTH_DEG, whose
    # flanks widen with the distance from the camera (a V-shaped notch in each ridge).
    az = math.radians(GAP_AZIMUTH_DEG)
    du, dv = u - 0.5, v - (0.5 + CAMERA_Y_FRACTION)
    across = du * math.cos(az) - dv * math.sin(az)
    along = np.maximum(du * math.sin(az) + dv * math.cos(az), 0.0)
    floor_w = 0.005 + 0.006 * along
    cut = _smoothstep(0.0, 1.0, (np.abs(across) - floor_w) / (0.02 + 0.08 * along))
    # Valley: gentle rolling ground (a few tens of m), rising toward the sides (in metres).
    rolling = 25.0 * (0.5 + 0.5 * _fbm(rng, u, v, 8, 5))
    sides = 160.0 * _smoothstep(0.12, 0.5, np.abs(u - 0.5)) ** 2 * (0.7 + 0.3 * _fbm(rng, u, v, 4, 3))
    return crests, np.stack(shapes), cut, rolling + np.maximum(sides, 0.0)


def _mountains(fields, crest_range):
    """The mountains' height (unscaled, peak ~1): the ridges, smoothly merged, cut by the pass."""
    crests, shapes, cut, _ground = fields
    lo, hi = crest_range
    crests = np.clip((crests - lo) / max(hi - lo, 1e-12), 0.0, 1.0)
    base = np.array([ridge[4] for ridge in RIDGES])[:, None, None]
    ridges = shapes * (base + (1.0 - base) * crests)
    merged = ridges[0]
    for ridge in ridges[1:]:
        merged = _smooth_max(merged, ridge, 0.04)
    return merged * cut


def _combine(fields, crest_range, mountain_max, floor):
    return _mountains(fields, crest_range) * (PEAK_HEIGHT_M / mountain_max) + fields[3] - floor


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
    crests = ref_fields[0]
    crest_range = (float(crests.min()), float(crests.max()))
    mountain_max = float(_mountains(ref_fields, crest_range).max())
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
# 0.05-0.15, dry scrub 0.15-0.25, bare rock 0.08-0.3, old snow 0.6-0.8).
GRASS_ALBEDO = (0.055, 0.085, 0.030, 1.0)
SCRUB_ALBEDO = (0.150, 0.130, 0.080, 1.0)
ROCK_ALBEDO = (0.130, 0.106, 0.082, 1.0)         # brownish-grey weathered rock (the mean)
ROCK_LIGHT_ALBEDO = (0.230, 0.215, 0.190, 1.0)   # paler bands and freshly broken faces
ROCK_DARK_ALBEDO = (0.075, 0.068, 0.058, 1.0)    # lichen-dark and wet patches, dark bands
SNOW_ALBEDO = (0.720, 0.740, 0.780, 1.0)
OLD_SNOW_ALBEDO = (0.600, 0.620, 0.660, 1.0)     # older, wind-packed snow
SNOW_LINE_M = 680.0            # snow lies above this (ragged by ~+-120 m) on slopes flatter than ~55 deg
SNOW_SLOPE_COS = (0.44, 0.60)  # from bare (cos slope below the first) to full snow (above the second)
ROCK_SLOPE_COS = (0.80, 0.64)  # from grass (cos slope above the first) to rock (below the second)
ALPINE_M = (650.0, 1050.0)      # grass thins out with height: rock reaches gentler slopes up there
STRATA_SPACING_M = 60.0        # vertical spacing of the rock's bands


def _socket(sockets, identifier):
    return next(socket for socket in sockets if socket.identifier == identifier)


def _set(tree, socket, value):
    if isinstance(value, bpy.types.NodeSocket):
        tree.links.new(value, socket)
    else:
        socket.default_value = value


def _mix_colour(tree, factor, a, b, blend="MIX"):
    """A Mix node (colour) of sockets/values ``a`` and ``b`` by ``factor``; returns its output."""
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = blend
    for identifier, value in (("Factor_Float", factor), ("A_Color", a), ("B_Color", b)):
        _set(tree, _socket(mix.inputs, identifier), value)
    return _socket(mix.outputs, "Result_Color")


def _map_range(tree, value, low, high):
    """0 at ``low``, 1 at ``high`` (either order), smoothstep in between."""
    node = tree.nodes.new("ShaderNodeMapRange")
    node.interpolation_type = "SMOOTHSTEP"
    tree.links.new(value, node.inputs["Value"])
    node.inputs["From Min"].default_value, node.inputs["From Max"].default_value = low, high
    return node.outputs["Result"]


def _math(tree, operation, *values):
    """A Math node of sockets/values; returns its output."""
    node = tree.nodes.new("ShaderNodeMath")
    node.operation = operation
    for socket, value in zip(node.inputs, values):
        _set(tree, socket, value)
    return node.outputs[0]


def _noise(tree, vector, scale, detail, roughness=0.5, distortion=0.0):
    """A Noise texture node (fBm, "Musgrave-like" with detail) at ``vector``; returns its Fac."""
    node = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(vector, node.inputs["Vector"])
    for name, value in (("Scale", scale), ("Detail", detail), ("Roughness", roughness),
                        ("Distortion", distortion)):
        node.inputs[name].default_value = value
    return node.outputs["Fac"]


def _scaled(colour, k):
    return tuple(min(1.0, k * c) for c in colour[:3]) + (1.0,)


def _rock_colour(tree, position):
    """Bare rock: brownish grey, with large tonal patches (Noise), blocky faces (Voronoi), bands
    along the height that wander across the slopes (Wave: strata) and lichen-dark patches."""
    tone = _noise(tree, position, 0.0025, 6.0, 0.6)           # ~400 m patches
    rock = _mix_colour(tree, _map_range(tree, tone, 0.36, 0.64),
                       _scaled(ROCK_ALBEDO, 0.8), _scaled(ROCK_ALBEDO, 1.2))
    strata = tree.nodes.new("ShaderNodeTexWave")
    strata.wave_type = "BANDS"
    strata.bands_direction = "Z"
    strata.wave_profile = "SIN"
    tree.links.new(position, strata.inputs["Vector"])
    # Blender's Z bands run at phase 20 * scale * z: one band every STRATA_SPACING_M.
    strata.inputs["Scale"].default_value = 2.0 * math.pi / (20.0 * STRATA_SPACING_M)
    strata.inputs["Distortion"].default_value = 10.0
    strata.inputs["Detail"].default_value = 4.0
    strata.inputs["Detail Scale"].default_value = 0.8
    strata.inputs["Detail Roughness"].default_value = 0.6
    band = strata.outputs["Fac"]
    # The bands show in places only (~600 m patches).
    bedded = _map_range(tree, _noise(tree, position, 0.0016, 3.0), 0.4, 0.6)
    rock = _mix_colour(tree, _math(tree, "MULTIPLY", _math(tree, "MULTIPLY", _map_range(tree, band, 0.6, 0.95), bedded), 0.35),
                       rock, ROCK_LIGHT_ALBEDO)
    blocks = tree.nodes.new("ShaderNodeTexVoronoi")           # ~45 m faces, each a little
    blocks.feature = "F1"                                     # paler or darker
    tree.links.new(position, blocks.inputs["Vector"])
    blocks.inputs["Scale"].default_value = 1.0 / 45.0
    cell = tree.nodes.new("ShaderNodeSeparateColor")
    tree.links.new(blocks.outputs["Color"], cell.inputs["Color"])
    rock = _mix_colour(tree, 1.0, rock, _math(tree, "MULTIPLY_ADD", cell.outputs["Red"], 0.3, 0.85),
                       blend="MULTIPLY")
    lichen = _noise(tree, position, 0.02, 8.0, 0.65, 0.4)     # ragged ~50 m patches
    dark = _math(tree, "MAXIMUM", _map_range(tree, lichen, 0.55, 0.67),
                 _math(tree, "MULTIPLY", _math(tree, "MULTIPLY", _map_range(tree, band, 0.25, 0.0), bedded), 0.45))
    return _mix_colour(tree, _math(tree, "MULTIPLY", dark, 0.85), rock, ROCK_DARK_ALBEDO)


def _terrain_material() -> bpy.types.Material:
    """Ground covers by slope and height from Blender's own procedural textures: grass and dry
    scrub in the valley and up the gentler slopes (mottled by noise), bare rock on steep slopes
    and, higher up, on gentler ones too (tonal patches, strata, blocky faces, lichen-dark patches),
    snow on the high ground but the steepest faces. The colour feeds the Principled BSDF's Base
    Color, which the add-on's OLS Terrain group takes over (it keeps this network)."""
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
    position = geometry.outputs["Position"]
    normal = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(geometry.outputs["Normal"], normal.inputs["Vector"])
    slope_cos = normal.outputs["Z"]
    height = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(position, height.inputs["Vector"])
    z = height.outputs["Z"]
    # Large patches (~300 m) and fine mottling (~20 m) break up every boundary.
    patches = _noise(tree, position, 0.003, 4.0)
    mottle = _noise(tree, position, 0.05, 6.0)
    cover = _mix_colour(tree, _map_range(tree, patches, 0.42, 0.62), GRASS_ALBEDO, SCRUB_ALBEDO)
    cover = _mix_colour(tree, _map_range(tree, mottle, 0.3, 0.7), cover, _scaled(SCRUB_ALBEDO, 0.8))
    # Grass up to ROCK_SLOPE_COS; the limit wanders with the noise and, higher up, with the height.
    alpine = _map_range(tree, _math(tree, "MULTIPLY_ADD", patches, 200.0, z), *ALPINE_M)
    lift = _math(tree, "MULTIPLY_ADD", alpine, 0.12, _math(tree, "MULTIPLY", mottle, -0.08))
    rock = _map_range(tree, _math(tree, "SUBTRACT", slope_cos, lift),
                      ROCK_SLOPE_COS[0] + 0.04, ROCK_SLOPE_COS[1] + 0.04)
    ground = _mix_colour(tree, rock, cover, _rock_colour(tree, position))
    # Snow above a ragged line, on all but the steepest faces (their limit ragged too).
    high = _map_range(tree, _math(tree, "MULTIPLY_ADD", patches, 400.0, z),
                      SNOW_LINE_M + 100.0, SNOW_LINE_M + 260.0)
    flat = _map_range(tree, _math(tree, "MULTIPLY_ADD", mottle, 0.16, slope_cos),
                      SNOW_SLOPE_COS[0] + 0.08, SNOW_SLOPE_COS[1] + 0.08)
    snow = _math(tree, "MULTIPLY", high, flat)
    snow_colour = _mix_colour(tree, _map_range(tree, _noise(tree, position, 0.01, 4.0), 0.4, 0.65),
                              SNOW_ALBEDO, OLD_SNOW_ALBEDO)
    tree.links.new(_mix_colour(tree, snow, ground, snow_colour), bsdf.inputs["Base Color"])
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
