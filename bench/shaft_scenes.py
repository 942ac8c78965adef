"""Scenes for timing the light-shaft pass (bench_shaft_pass): the sample, a colonnade and a
forest of 10 000 instanced trees, each wired to draft tables with light shafts on.

- "sample": the sample terrain, its camera, the sun at 15 deg.
- "colonnade": 14 pillars under a lintel and a block beside them on a 4 km plane, the camera
  2 m up facing a sun 4 deg high through the pillars (many thin shadow edges against a low sun).
- "forest": 10 000 cone trees put by a geometry-nodes Instance on Points on a 1.2 km grid, the
  camera 5 m up at the forest's edge facing a sun 10 deg high through the trunks.

``pkg``: the extension package, registered. Each builder starts from an empty file."""
import math
import sys
from importlib import import_module
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))


def _module(pkg, name):
    return import_module(f"{pkg.__name__}.addon.{name}")


def _box(name, lo, hi):
    import bpy
    mesh = bpy.data.meshes.new(name)
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    vertices = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
                (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    mesh.from_pydata(vertices, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _camera(location, pitch_deg, lens=35.0):
    """A camera at ``location`` looking along +Y, ``pitch_deg`` above the horizon."""
    import bpy
    data = bpy.data.cameras.new("Camera")
    data.lens = lens
    data.clip_end = 20000.0
    camera = bpy.data.objects.new("Camera", data)
    camera.location = location
    camera.rotation_euler = (math.radians(90.0 + pitch_deg), 0.0, 0.0)
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera
    return camera


def _sun():
    import bpy
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    bpy.context.scene.collection.objects.link(sun)
    return sun


def _ground(size):
    return _box("Ground", (-size / 2, -size / 2, -1.0), (size / 2, size / 2, 0.0))


def _colonnade_objects():
    ground = _ground(4000.0)
    for i in range(14):
        x = (i - 6.5) * 3.0
        _box(f"Pillar {i}", (x - 0.5, -0.5, 0.0), (x + 0.5, 0.5, 6.0))
    _box("Lintel", (-21.0, -0.75, 6.0), (21.0, 0.75, 7.0))
    _box("Block", (26.0, -2.0, 0.0), (30.0, 2.0, 4.0))
    _camera((0.0, -25.0, 2.0), 6.0)
    _sun()
    return [ground]


def _forest_objects():
    import bpy
    import instanced_forest
    ground = _ground(4000.0)
    instanced_forest.forest(bpy.context.scene, count=10_000, spacing=12.0)
    _camera((3.0, -620.0, 5.0), 4.0)
    _sun()
    return [ground]


SCENES = {
    "sample": (None, 15.0, 35.0),
    "colonnade": (_colonnade_objects, 4.0, 0.0),
    "forest": (_forest_objects, 10.0, 0.0),
}


def wired(pkg, name, width, height, output):
    """The scene ``name`` wired to draft tables at width x height, light shafts on, 1 Cycles
    sample; returns the scene."""
    import bpy
    batch = _module(pkg, "batch")
    baking = _module(pkg, "baking")
    wiring = _module(pkg, "scene.setup.wiring")
    build, elevation, azimuth = SCENES[name]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    options = ["--resolution", f"{width}x{height}", "--samples", "1", "--output", str(output),
               "--sun-elevation", str(elevation), "--sun-azimuth", str(azimuth), "--tables", "draft"]
    if build is None:
        args = batch.parse_args(["--sample"] + options)
        scene = batch.prepare(args)
        terrain = [o for o in scene.objects if o.select_get()]
    else:
        terrain = build()
        args = batch.parse_args(options)
        scene = batch.prepare(args)
    batch.apply_options(scene, args)
    directory = baking.bake_if_needed(pkg.lut_gen.AtmosphereParams(), "draft")
    wiring.wire_scene(scene, directory, terrain, resolution="draft")
    scene.ols.enable_light_shafts = True
    scene.cycles.samples = 1
    return scene
