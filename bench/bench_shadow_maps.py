"""Shadow-map rasterisation benchmark: the sample's terrain (256 x 256 grid, ~130 000 triangles)
into 6 cascades at 1024 texels for the sample's camera and sun, the current rasteriser against a
baseline revision's (loaded from git), side by side in one run.

Goal: <= 0.5 s (2.1 s at the baseline on an idle 2-core machine).

    .venv/bin/python bench/bench_shadow_maps.py [--baseline 7311c96] [--repeat 3] [--resolution 1024]
"""
import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def sample_triangles():
    """(triangles, camera, sun direction, near, far) of the sample scene, built with bpy."""
    import bpy
    from sample_blend import build_sample
    from lut_gen.passes.shadow_map import Camera
    bpy.ops.wm.read_factory_settings(use_empty=True)
    objects = build_sample.build_sample_scene(bpy.context.scene, elevation_deg=15.0, azimuth_deg=35.0)
    bpy.context.view_layer.update()          # matrix_world of the new camera and sun
    mesh, matrix = objects["terrain"].data, np.array(objects["terrain"].matrix_world)
    mesh.calc_loop_triangles()
    coordinates = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", coordinates)
    indices = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int64)
    mesh.loop_triangles.foreach_get("vertices", indices)
    world = coordinates.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]
    triangles = world[indices].reshape(-1, 3, 3)
    camera_object = objects["camera"]
    scene = bpy.context.scene
    corners = np.array([tuple(v) for v in camera_object.data.view_frame(scene=scene)])
    depth = abs(corners[0, 2])
    camera = Camera(np.array(camera_object.matrix_world.translation),
                    np.array(camera_object.matrix_world.to_3x3().normalized()),
                    (float(np.abs(corners[:, 0]).max() / depth), float(np.abs(corners[:, 1]).max() / depth)),
                    camera_object.data.clip_end)
    sun = np.array(objects["sun"].matrix_world.to_3x3().col[2])
    far = float(np.max((triangles.reshape(-1, 3) - camera.position) @ camera.forward))
    return triangles, camera, sun / np.linalg.norm(sun), max(camera_object.data.clip_start, 1.0), far


# Where the rasteriser lives: today's layout, then the flat lut_gen of older revisions.
RASTERISER_PATHS = ("lut_gen/passes/shadow_map.py", "lut_gen/shadow_map.py")


def baseline_module(revision):
    for candidate in RASTERISER_PATHS:
        shown = subprocess.run(["git", "show", f"{revision}:{candidate}"], cwd=ROOT, capture_output=True, text=True)
        if shown.returncode == 0:
            source = shown.stdout
            break
    else:
        raise SystemExit(f"error: revision {revision} has none of {', '.join(RASTERISER_PATHS)}")
    path = Path(tempfile.mkdtemp()) / "baseline_shadow_map.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("baseline_shadow_map", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module          # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def best_time(module, args, repeat):
    best, result = 1e9, None
    for _ in range(repeat):
        start = time.perf_counter()
        result = module.render_cascades(*args)
        best = min(best, time.perf_counter() - start)
    return best, result


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--baseline", default="7311c96", help="git revision of the baseline rasteriser")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--resolution", type=int, default=1024)
    args = parser.parse_args()
    from lut_gen.passes import shadow_map
    triangles, camera, sun, near, far = sample_triangles()
    call = (triangles, camera, sun, args.resolution, 6, 0.95, near, far)
    baseline, old = best_time(baseline_module(args.baseline), call, args.repeat)
    current, new = best_time(shadow_map, call, args.repeat)
    covered = (old.depths > -1e8) & (new.depths > -1e8)
    print(f"{len(triangles)} triangles, 6 cascades at {args.resolution} (best of {args.repeat})")
    print(f"  baseline {args.baseline}: {baseline:.3f} s")
    print(f"  current:           {current:.3f} s   ratio {current / baseline:.2f}x   (goal <= 0.5 s)")
    print(f"  same coverage: {np.array_equal(old.depths > -1e8, new.depths > -1e8)}, largest depth difference "
          f"{np.abs(old.depths - new.depths)[covered].max():.2e} m")


if __name__ == "__main__":
    main()
