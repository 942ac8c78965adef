"""Instanced-geometry benchmark: what the shadow maps pay per frame for a forest of 10 000 trees
put on a grid by a geometry-nodes Instance on Points (tests/instanced_forest.py), the current
gathering (addon/scene/frame/shadow_maps.scene_triangles) against a baseline revision's, side by
side in one run, then the rasterisation of what it gathered into the cascades for a camera 2 m
up at the forest's edge.

Goal (as for the light-shaft pass): the per-frame numpy work at most 0.5 s at 1024-texel maps.

    .venv/bin/python bench/bench_instances.py [--baseline 8a1737a] [--trees 10000] [--repeat 3]
        [--resolution 1024] [--cascades 6]
"""
import argparse
import ast
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
GATHER_PATH = "addon/scene/frame/shadow_maps.py"


def baseline_gather(revision, names):
    """The baseline's scene_triangles (and the helpers it calls), taken from git and run with
    numpy and the add-on's names: the module itself imports the package relatively."""
    shown = subprocess.run(["git", "show", f"{revision}:{GATHER_PATH}"], cwd=ROOT, capture_output=True, text=True)
    if shown.returncode:
        raise SystemExit(f"error: revision {revision} has no {GATHER_PATH}")
    tree = ast.parse(shown.stdout)
    functions = [node for node in tree.body if isinstance(node, ast.FunctionDef)
                 and node.name in {"scene_triangles", "_local_corners"}]
    namespace = {"np": np, "names": names}
    exec(compile(ast.Module(body=functions, type_ignores=[]), "baseline", "exec"), namespace)
    return namespace["scene_triangles"]


def best(call, repeat):
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = call()
        times.append(time.perf_counter() - start)
    return min(times), result


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--baseline", default="8a1737a")
    parser.add_argument("--trees", type=int, default=10_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--resolution", type=int, default=1024)
    parser.add_argument("--cascades", type=int, default=6)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT / "scripts"))
    import render as launcher
    pkg = launcher.import_extension()
    import bpy
    from importlib import import_module
    from instanced_forest import forest
    shadow_maps = import_module(pkg.__name__ + ".addon.scene.frame.shadow_maps")
    names = import_module(pkg.__name__ + ".addon.scene.names")
    shadow_map = pkg.lut_gen.passes.shadow_map
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    forest(scene, count=args.trees, spacing=12.0)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    old_time, old = best(lambda: baseline_gather(args.baseline, names)(depsgraph), args.repeat)
    new_time, new = best(lambda: shadow_maps.scene_triangles(depsgraph), args.repeat)
    from occluders import look_at, sun_at
    side = 12.0 * (round(args.trees ** 0.5) - 1) / 2
    # At the forest's edge, 2 m up, looking in along it toward a sun 4 deg high.
    camera = look_at(np.array([-side - 5.0, 0.0, 2.0]), np.array([0.0, 0.0, 2.0]))
    sun = sun_at(4.0, 80.0)
    raster_time, _ = best(lambda: shadow_map.render_cascades(new, camera, sun, args.resolution, args.cascades, 0.95,
                                                             1.0, 2 * side + 10.0), args.repeat)
    print(f"forest of {args.trees} instanced trees: {len(new)} triangles (baseline {len(old)}); best of {args.repeat}")
    print(f"  gather   baseline {args.baseline}: {old_time:7.3f} s   current {new_time:7.3f} s   "
          f"ratio {new_time / old_time:.3f}x")
    print(f"  rasterise {args.cascades} cascades at {args.resolution}: {raster_time:.3f} s")
    print(f"  per-frame numpy (gather + rasterise): {new_time + raster_time:.3f} s   (goal <= 0.5 s)")


if __name__ == "__main__":
    main()
