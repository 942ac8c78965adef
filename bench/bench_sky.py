"""Sky benchmark (Cycles CPU): the sample scene rendered with the "OLS Sky" world vs the same
scene with Blender's built-in Sky Texture (MULTIPLE_SCATTERING), equal resolution and samples,
printed side by side with their ratio; and the time to get the default LUT set into Blender
images (EXR load vs numpy foreach_set).

    .venv/bin/python bench/bench_sky.py [--resolution 480x270] [--samples 16] [--repeats 3]

Goals: OLS Sky <= 1.5x the Sky Texture; LUT upload < 1 s.
"""
import argparse
import importlib
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))


def timed_render(scene, repeats):
    """Median seconds of ``repeats`` renders, after one that warms caches (BVH, images)."""
    import bpy
    times = []
    for run in range(repeats + 1):
        start = time.perf_counter()
        bpy.ops.render.render(write_still=False)
        if run:
            times.append(time.perf_counter() - start)
    return statistics.median(times)


def sky_texture_world(scene, sun):
    import bpy
    world = bpy.data.worlds.new("Blender Sky Texture")
    world.use_nodes = True
    nodes = world.node_tree.nodes
    nodes.clear()
    sky = nodes.new("ShaderNodeTexSky")
    sky.sky_type = "MULTIPLE_SCATTERING"
    direction = sun.matrix_world.to_3x3().col[2]
    sky.sun_elevation = math.asin(direction[2])
    sky.sun_rotation = math.atan2(direction[0], direction[1])
    background = nodes.new("ShaderNodeBackground")
    output = nodes.new("ShaderNodeOutputWorld")
    world.node_tree.links.new(sky.outputs["Color"], background.inputs["Color"])
    world.node_tree.links.new(background.outputs[0], output.inputs["Surface"])
    return world


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--resolution", default="480x270")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=3, help="timed renders per world; the median counts")
    args = parser.parse_args()
    os.environ.setdefault("OLS_CACHE_DIR", str(Path(tempfile.gettempdir()) / "ols_bench_cache"))

    import render as launcher
    package = launcher.import_extension()
    import bpy
    import numpy as np
    batch = importlib.import_module(package.__name__ + ".addon.batch")
    wiring = importlib.import_module(package.__name__ + ".addon.scene.setup.wiring")
    sun_mod = importlib.import_module(package.__name__ + ".addon.scene.sun")
    lut_gen = package.lut_gen

    options = batch.parse_args(["--sample", "--output", "unused.png", "--resolution", args.resolution,
                                "--samples", str(args.samples), "--sun-elevation", "15", "--sun-azimuth", "35"])
    scene = batch.prepare(options)
    batch.apply_options(scene, options)
    assert bpy.ops.ols.setup_scene() == {"FINISHED"}
    sun = sun_mod.find_sun(scene)
    print(f"Cycles CPU, {os.cpu_count()} cores, {args.resolution}, {args.samples} samples, median of {args.repeats}")

    ols_world = scene.world
    ols_time = timed_render(scene, args.repeats)
    wiring.wire_world(scene, sun, light_scene=1.0)
    ols_lit_time = timed_render(scene, args.repeats)
    scene.world = sky_texture_world(scene, sun)
    sky_time = timed_render(scene, args.repeats)
    scene.world = ols_world
    print(f"\n  {'world':<44} {'render [s]':>10} {'vs Sky Texture':>15}")
    for label, seconds in (("Blender Sky Texture (MULTIPLE_SCATTERING)", sky_time),
                           ("OLS Sky (sample lighting: Light Scene 0)", ols_time),
                           ("OLS Sky lighting the scene (Light Scene 1)", ols_lit_time)):
        print(f"  {label:<44} {seconds:10.2f} {seconds / sky_time:14.2f}x")
    print("  goal: OLS Sky <= 1.5x the Sky Texture")

    # LUT upload: the default set as Blender images.
    directory = Path(os.environ["OLS_CACHE_DIR"]) / lut_gen.store.cache.key_for(lut_gen.AtmosphereParams())
    luts = lut_gen.load(directory)
    start = time.perf_counter()
    for table in ("single", "higher", "multiple"):
        rgb = lut_gen.tables.atlas.pack(luts.table(table))
        height, width, _ = rgb.shape
        rgba = np.empty((height, width, 4), np.float32)
        rgba[..., :3] = rgb
        rgba[..., 3] = 1.0
        image = bpy.data.images.new(f"bench {table}", width, height, alpha=True, float_buffer=True)
        image.pixels.foreach_set(rgba.ravel())
    upload = time.perf_counter() - start
    for image in list(bpy.data.images):
        if image.name.startswith("OLS "):
            bpy.data.images.remove(image)
    start = time.perf_counter()
    images = importlib.import_module(package.__name__ + ".addon.scene.tables.luts").load_images(directory)
    for image in images.values():
        image.pixels[0]                      # force the pixels to load
    load = time.perf_counter() - start
    print(f"\n  LUT set into Blender images: foreach_set of the 3 default atlases {upload:.2f} s, "
          f"EXR load of all {len(images)} files {load:.2f} s (goal < 1 s)")


if __name__ == "__main__":
    main()
