"""The sample terrain scene (sample_blend/build_sample.py): layout, sun helpers, CLI, a render.

Every test starts from ``read_factory_settings(use_empty=True)`` so it can share one process
with the other bpy tests.
"""
import shutil
import os
import math
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from mathutils import Vector  # noqa: E402  (comes with bpy)
from extension import ROOT, SAMPLE_SCRIPT, sample_builder

pytestmark = pytest.mark.bpy

SCRIPT = SAMPLE_SCRIPT


bs = sample_builder()


@pytest.fixture
def fresh_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield bpy.context.scene
    bpy.ops.wm.read_factory_settings(use_empty=True)


@pytest.fixture
def sample(fresh_scene):
    start = time.perf_counter()
    objs = bs.build_sample_scene(fresh_scene)
    print(f"\nbuild_sample_scene (256 x 256 terrain): {time.perf_counter() - start:.3f} s")
    return objs


def _vertices(obj):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


# ---------------------------------------------------------------------------------------------
# Terrain
# ---------------------------------------------------------------------------------------------

def test_heightmap_is_deterministic_and_non_negative():
    xs, ys, h = bs.terrain_heightmap(6000, 128, seed=7)
    _, _, h_again = bs.terrain_heightmap(6000, 128, seed=7)
    _, _, h_other = bs.terrain_heightmap(6000, 128, seed=8)
    assert h.shape == (128, 128)
    np.testing.assert_array_equal(h, h_again)
    assert not np.allclose(h, h_other)
    assert np.isfinite(h).all() and 0.0 <= h.min() < 5.0
    assert xs[0] == -3000 and xs[-1] == 3000 and ys[0] == -3000 and ys[-1] == 3000
    # The shape does not depend on the grid resolution (noise lives in terrain coordinates).
    _, _, h_fine = bs.terrain_heightmap(6000, 255, seed=7)
    np.testing.assert_allclose(h_fine[::2, ::2], h, atol=1e-6)
    _, _, h_ref = bs.terrain_heightmap(6000, 257, seed=7)     # the normalisation grid
    _, _, h_coarse = bs.terrain_heightmap(6000, 129, seed=7)
    np.testing.assert_allclose(h_ref[::2, ::2], h_coarse, atol=1e-6)
    assert h_ref.min() == 0.0


def test_heightmap_rejects_bad_input():
    with pytest.raises(ValueError):
        bs.terrain_heightmap(6000, 1)
    with pytest.raises(ValueError):
        bs.terrain_heightmap(-1.0, 64)


def test_terrain_extent_heights_and_mesh(fresh_scene):
    start = time.perf_counter()
    terrain = bs.build_terrain(fresh_scene)
    print(f"\nbuild_terrain 256 x 256: {time.perf_counter() - start:.3f} s")
    assert terrain.name == "OLS Terrain" and terrain.name in fresh_scene.objects
    mesh = terrain.data
    assert len(mesh.vertices) == 256 * 256
    assert len(mesh.polygons) == 255 * 255
    assert all(len(p.vertices) == 4 for p in mesh.polygons[:10])
    assert not mesh.validate(verbose=False)            # False: nothing had to be fixed
    v = _vertices(terrain)
    np.testing.assert_allclose(v[:, 0].min(), -3000, atol=1e-3)
    np.testing.assert_allclose(v[:, 0].max(), 3000, atol=1e-3)
    np.testing.assert_allclose(v[:, 1].min(), -3000, atol=1e-3)
    np.testing.assert_allclose(v[:, 1].max(), 3000, atol=1e-3)
    assert v[:, 2].min() >= 0.0
    assert 600.0 <= v[:, 2].max() <= 1300.0
    # Normals face up (the height field is seen from above), shading is smooth.
    normals = np.empty(len(mesh.polygons) * 3, dtype=np.float32)
    mesh.polygons.foreach_get("normal", normals)
    assert (normals.reshape(-1, 3)[:, 2] > 0).all()
    smooth = np.empty(len(mesh.polygons), dtype=bool)
    mesh.polygons.foreach_get("use_smooth", smooth)
    assert smooth.all()
    # Ground covers by slope and height: a procedural network feeds the Base Color, with
    # physically plausible albedos (grass 0.06 ... snow 0.73).
    mat = mesh.materials[0]
    assert mat.name == "OLS Terrain Base"
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    assert bsdf.inputs["Base Color"].is_linked
    assert sum(n.bl_idname == "ShaderNodeTexNoise" for n in mat.node_tree.nodes) >= 1
    for cover in (bs.GRASS_ALBEDO, bs.SCRUB_ALBEDO, bs.ROCK_ALBEDO, bs.SNOW_ALBEDO):
        assert 0.03 <= np.mean(cover[:3]) <= 0.8
    # Helper agrees with the vertices.
    h = bs.terrain_heights(terrain)
    assert h.shape == (256, 256)
    assert bs.terrain_height_at(terrain, -3000, -3000) == pytest.approx(h[0, 0])
    assert bs.terrain_height_at(terrain, 3000, 3000) == pytest.approx(h[-1, -1])


def test_rebuilding_replaces_objects(fresh_scene):
    bs.build_sample_scene(fresh_scene, resolution=32)
    bs.build_sample_scene(fresh_scene, resolution=32)
    assert sorted(o.name for o in bpy.data.objects) == ["OLS Camera", "OLS Sun", "OLS Terrain"]
    assert len(bpy.data.meshes) == 1 and len(bpy.data.cameras) == 1 and len(bpy.data.lights) == 1
    assert len(bpy.data.materials) == 1


# ---------------------------------------------------------------------------------------------
# Camera and layout
# ---------------------------------------------------------------------------------------------

def test_camera_near_ground_looking_plus_y_slightly_up(sample):
    scene, cam, terrain = sample["scene"], sample["camera"], sample["terrain"]
    assert cam.name == "OLS Camera" and scene.camera == cam
    assert 24.0 <= cam.data.lens <= 35.0
    assert cam.data.clip_start == pytest.approx(0.5)
    assert cam.data.clip_end >= 1.0e5
    loc = cam.location
    assert abs(loc.x) < 3000 and abs(loc.y) < 3000
    assert loc.y < -2000                                 # at the -Y side of the terrain
    ground = bs.terrain_height_at(terrain, loc.x, loc.y)
    assert 30.0 <= loc.z - ground <= 50.0
    forward = bs.camera_forward(cam)
    pitch = math.degrees(math.asin(forward.z))
    heading = math.degrees(math.atan2(forward.x, forward.y))  # from +Y toward +X
    assert 3.0 <= pitch <= 5.0
    assert abs(heading) < 1.0
    # matrix_world (after a depsgraph update) agrees with the helper.
    bpy.context.view_layer.update()
    world_forward = cam.matrix_world.to_3x3() @ Vector((0, 0, -1))
    assert (world_forward.normalized() - forward).length < 1e-6


def _skyline(terrain, cam, azimuth_deg, max_distance):
    """Highest elevation angle (deg) of the terrain seen from the camera toward ``azimuth_deg``
    (from +Y toward +X), over ground points closer than ``max_distance`` inside the terrain."""
    az = math.radians(azimuth_deg)
    best = -90.0
    for d in np.arange(50.0, max_distance, 20.0):
        x, y = cam.location.x + d * math.sin(az), cam.location.y + d * math.cos(az)
        if abs(x) > 3000 or abs(y) > 3000:
            break
        best = max(best, math.degrees(math.atan2(bs.terrain_height_at(terrain, x, y) - cam.location.z, d)))
    return best


def test_ridges_in_front_of_camera(sample):
    cam, terrain = sample["camera"], sample["terrain"]
    v = _vertices(terrain)
    forward = bs.camera_forward(cam)
    f = np.array([forward.x, forward.y])
    f /= np.linalg.norm(f)
    side = np.array([f[1], -f[0]])
    rel = v[:, :2] - np.array([cam.location.x, cam.location.y])
    along, across = rel @ f, rel @ side
    # Horizontal half field of view of the camera (sensor fit AUTO, landscape image).
    half_fov = math.atan(0.5 * cam.data.sensor_width / cam.data.lens)
    in_view = (along > 0) & (np.abs(across) < along * math.tan(half_fov))
    ground = bs.terrain_height_at(terrain, cam.location.x, cam.location.y)
    near = in_view & (along < 800)
    assert v[near, 2].max() - ground < 100.0             # a gentle valley near the camera
    # Three ridges at increasing distance, each higher than the one in front of it: foothills
    # ~1.4 km, a middle ridge ~2.9 km, the main range (peaks ~600-1200 m) ~4.5 km away.
    bands = [(1000, 1900), (2300, 3500), (3900, 5700)]
    peaks = []
    for lo, hi in bands:
        band = in_view & (along >= lo) & (along <= hi)
        assert band.sum() > 1000
        peaks.append(np.percentile(v[band, 2], 99) - ground)
    print("\nridge heights (99th percentile above the camera's ground):", np.round(peaks).tolist())
    assert 50.0 < peaks[0] < peaks[1] < peaks[2]
    assert v[in_view & (along >= 3900), 2].max() > 600.0
    # Layers: across the view, each farther ridge shows above the nearer ones in most columns.
    columns = np.linspace(-0.95, 0.95, 21) * math.degrees(half_fov)
    skylines = np.array([[_skyline(terrain, cam, az, limit) for limit in (1900, 3500, 8000)]
                         for az in columns])
    print("skyline elevations (deg) up to 1.9 km, 3.5 km, all:", np.round(skylines, 1).tolist())
    assert np.mean(skylines[:, 1] > skylines[:, 0] + 1.0) >= 0.8
    assert np.mean(skylines[:, 2] > skylines[:, 1] + 1.0) >= 0.5
    # The middle of the view hits the mountains, not the sky, and above the camera.
    depsgraph = bpy.context.evaluated_depsgraph_get()
    hit, location, _normal, _index, obj, _m = sample["scene"].ray_cast(
        depsgraph, cam.location, forward, distance=1.0e5)
    assert hit and obj.name == "OLS Terrain"
    distance = (location - cam.location).length
    print(f"view centre hits the terrain {distance:.0f} m away at z = {location.z:.0f} m")
    assert 1500.0 < distance < 6000.0
    assert location.z > cam.location.z


def test_pass_lets_a_low_sun_through(sample):
    """A pass through every ridge toward the `sunset` look's sun (1.5 deg up, azimuth
    GAP_AZIMUTH_DEG): the sun's rays reach the valley along it, while the ridges on either side
    shadow it, so the light-shaft pass has shafts to draw."""
    cam, terrain = sample["camera"], sample["terrain"]
    az = bs.GAP_AZIMUTH_DEG
    slope = math.tan(math.radians(1.5))
    for d in np.arange(0.0, 9000.0, 20.0):
        x, y = cam.location.x + d * math.sin(math.radians(az)), cam.location.y + d * math.cos(math.radians(az))
        if abs(x) > 3000 or abs(y) > 3000:
            break
        assert bs.terrain_height_at(terrain, x, y) < cam.location.z + d * slope - 10.0, d
    in_pass = _skyline(terrain, cam, az, 8000)
    flanks = [_skyline(terrain, cam, az + offset, 8000) for offset in (-12.0, -8.0, 8.0, 12.0)]
    print(f"\nskyline in the pass {in_pass:.1f} deg, beside it", np.round(flanks, 1).tolist())
    assert in_pass < 1.0 and min(flanks) > 4.0


def test_scene_settings(sample):
    scene = sample["scene"]
    assert scene.render.engine == "CYCLES"
    assert (scene.render.resolution_x, scene.render.resolution_y) == (1280, 720)
    assert scene.render.resolution_percentage == 100
    assert scene.unit_settings.system == "METRIC"
    assert scene.unit_settings.scale_length == pytest.approx(1.0)
    assert scene.render.film_transparent is False
    assert set(sample) >= {"terrain", "camera", "sun"}


# ---------------------------------------------------------------------------------------------
# Sun
# ---------------------------------------------------------------------------------------------

ANGLES = [(8.0, 0.0), (0.0, 0.0), (3.0, 45.0), (-4.0, -30.0), (12.0, 90.0), (30.0, -90.0),
          (45.0, 135.0), (60.0, 180.0), (75.0, -170.0), (89.0, 10.0)]


@pytest.mark.parametrize("elevation, azimuth", ANGLES)
def test_sun_helpers_invert_each_other(fresh_scene, elevation, azimuth):
    sun = bs.build_sun(fresh_scene, elevation_deg=elevation, azimuth_deg=azimuth)
    assert sun.name == "OLS Sun" and sun.data.type == "SUN"
    d = bs.direction_to_sun(sun)
    expected = Vector((math.sin(math.radians(azimuth)) * math.cos(math.radians(elevation)),
                       math.cos(math.radians(azimuth)) * math.cos(math.radians(elevation)),
                       math.sin(math.radians(elevation))))
    assert (d - expected).length < 1e-6
    assert (bs.sun_direction(elevation, azimuth) - expected).length < 1e-12
    el, az = bs.elevation_azimuth(d)
    assert el == pytest.approx(elevation, abs=1e-4)
    assert (az - azimuth + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-4)
    # Euler -> direction -> Euler: the rotation rebuilt from the direction is the same rotation.
    again = bs.sun_rotation(*bs.elevation_azimuth(d))
    assert (again.to_matrix() @ Vector((0, 0, 1)) - d).length < 1e-6
    # The lamp shines along its local -Z, i.e. away from the sun; matrix_world agrees.
    bpy.context.view_layer.update()
    shine = sun.matrix_world.to_3x3() @ Vector((0, 0, -1))
    assert (shine.normalized() + expected).length < 1e-5


def test_sun_lamp_settings(fresh_scene):
    sun = bs.build_sun(fresh_scene)
    assert sun.data.energy == pytest.approx(10.0)
    assert sun.data.angle == pytest.approx(math.radians(0.545))
    el, az = bs.elevation_azimuth(bs.direction_to_sun(sun))
    assert el == pytest.approx(8.0) and az == pytest.approx(0.0, abs=1e-9)


def test_sun_direction_follows_parent(fresh_scene):
    sun = bs.build_sun(fresh_scene, elevation_deg=10.0, azimuth_deg=0.0)
    parent = bpy.data.objects.new("parent", None)
    fresh_scene.collection.objects.link(parent)
    parent.rotation_euler = (0.0, 0.0, math.radians(-90.0))  # turns +Y toward +X
    sun.parent = parent
    el, az = bs.elevation_azimuth(bs.direction_to_sun(sun))
    assert el == pytest.approx(10.0) and az == pytest.approx(90.0)


# ---------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------

def _run_script(*args, timeout=300):
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=timeout, cwd=str(ROOT))


def test_script_writes_blend(tmp_path):
    out = tmp_path / "sub" / "sample.blend"
    proc = _run_script("--out", str(out), "--elevation", "5")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert out.is_file() and out.stat().st_size > 100_000
    with bpy.data.libraries.load(str(out)) as (data_from, _data_to):
        names = sorted(data_from.objects)
        materials = list(data_from.materials)
    assert names == ["OLS Camera", "OLS Sun", "OLS Terrain"]
    assert "OLS Terrain Base" in materials


def test_script_accepts_blender_style_args(tmp_path):
    out = tmp_path / "blender_style.blend"
    proc = _run_script("--ignored-blender-flag", "--", "--out", str(out), "--resolution", "16")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert out.is_file()


def test_script_wire_saves_a_wired_scene_that_reopens_anywhere(tmp_path):
    """--wire registers the extension from the checkout, bakes and saves a wired .blend. Opened
    where the baked tables are missing (another machine), the load handler bakes them again."""
    out = tmp_path / "wired.blend"
    env = dict(os.environ, OLS_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.run([sys.executable, str(SCRIPT), "--out", str(out), "--resolution", "16", "--wire",
                           "--tables", "draft"], capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    shutil.rmtree(tmp_path / "cache")
    check = (
        "import sys, importlib.util\n"
        f"spec = importlib.util.spec_from_file_location('launcher', {str(ROOT / 'scripts' / 'render.py')!r})\n"
        "launcher = importlib.util.module_from_spec(spec); spec.loader.exec_module(launcher)\n"
        "launcher.import_extension()\n"
        "import bpy, os\n"
        f"bpy.ops.wm.open_mainfile(filepath={str(out)!r})\n"
        "scene = bpy.context.scene\n"
        "image = next(i for i in bpy.data.images if i.name.startswith('OLS multiple'))\n"
        "print('WORLD', scene.world.name, 'MATERIAL', bpy.data.objects['OLS Terrain'].active_material.name)\n"
        "print('TABLES', os.path.exists(bpy.path.abspath(image.filepath)), image.size[0] > 0)\n"
    )
    proc = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "WORLD OLS World MATERIAL OLS Terrain OLS Terrain" in proc.stdout
    assert "TABLES True True" in proc.stdout


# ---------------------------------------------------------------------------------------------
# Render
# ---------------------------------------------------------------------------------------------

def test_low_res_cycles_render_shows_mountains(sample, tmp_path):
    scene = sample["scene"]
    world = bpy.data.worlds.new("white")
    with warnings.catch_warnings():          # World.use_nodes is deprecated in Blender 5
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    background = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    background.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    scene.cycles.device = "CPU"
    scene.cycles.samples = 2
    scene.cycles.use_denoising = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.render.image_settings.file_format = "PNG"
    path = tmp_path / "sample_render.png"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    assert path.is_file()

    image = bpy.data.images.load(str(path))
    w, h = image.size
    assert (w, h) == (64, 36)
    px = np.empty(w * h * image.channels, dtype=np.float32)
    image.pixels.foreach_get(px)
    rgb = px.reshape(h, w, image.channels)[::-1, :, :3]     # row 0 = top of the image
    lum = rgb.mean(axis=2)
    print(f"\nrender mean {lum.mean():.3f}; row means top to bottom:",
          np.round(lum.mean(axis=1), 2).tolist())
    assert lum.mean() > 0.05                                 # not black
    assert lum[:3].mean() > 0.9                              # white sky at the top
    assert 0.01 < lum[-6:].mean() < 0.75                      # lit but darker ground below
    # The mountains rise above the image centre (the camera looks 4 deg up, peaks reach ~15 deg)
    # and their skyline is jagged, not a flat horizon.
    terrain = lum < 0.75
    skyline = np.argmax(terrain, axis=0)                     # first terrain row per column
    assert terrain.any(axis=0).all()
    assert skyline.min() < h // 2
    assert skyline.max() - skyline.min() >= 3
