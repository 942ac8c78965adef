"""The per-frame numpy work of the light-shaft pass, stage by stage, against a baseline
revision side by side (the goal: the frame update <= 0.5 s at 1024-texel shadow maps).

Each scene of bench/shaft_scenes.py is wired once; then the frame update (what render_pre
runs before each frame is composited, epipolar sampling on) is called --frames times for this
tree and for the baseline revision's code alternately, the per-frame cache cleared before each
so every call pays as a new animation frame would. The baseline is the extension at
``--against`` (a git worktree under a temporary folder), imported as a second package beside
this one in the same Blender process: the same scene, depsgraph and tables feed both. Printed:
the median seconds per stage of each, and new / baseline.

    .venv/bin/python bench/bench_frame_numpy.py [--against HEAD] [--scenes sample,colonnade,forest]
        [--size 960x540] [--frames 5]
"""
import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
from importlib import import_module
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT / "bench"))

from bench_shaft_pass import StageTimer     # noqa: E402  (bench/ on the path)

# (module under the package, function, stage); stages nest: "frame update" holds them all.
STAGES = (("addon.scene.frame.shadow_maps", "scene_triangles", "gather triangles"),
          ("lut_gen.passes.shadow_map", "render_cascades", "rasterise"),
          ("addon.scene.frame.shadow_maps", "write_images", "shadow images"),
          ("lut_gen.passes.min_max", "build", "min/max maps"),
          ("lut_gen.passes.epipolar", "build_tables", "lit-length tables"),
          ("lut_gen.passes.epipolar_air", "build", "in-scattering"),
          ("addon.nodes.epipolar", "pack", "pack tables"),
          ("addon.scene.frame.frame_update", "update_frame", "frame update"))
PRINTED = ("gather triangles", "rasterise", "shadow images", "min/max maps", "lit-length tables", "in-scattering",
           "pack tables", "other", "frame update")


def stage_timer(package) -> StageTimer:
    """A StageTimer (bench_shaft_pass's) over ``package``'s STAGES functions."""
    timer = StageTimer()
    for module_name, attribute, stage in STAGES:
        timer.wrap(import_module(f"{package}.{module_name}"), attribute, stage)
    return timer


def frame_seconds(timer, package, scene, depsgraph) -> dict:
    """{stage: seconds} of one frame update from a cleared cache; "other" is the rest."""
    frame_update = import_module(f"{package}.addon.scene.frame.frame_update")
    frame_update.forget()
    timer.reset()
    frame_update.update_frame(scene, depsgraph)
    seconds = dict(timer.seconds)
    # min/max runs inside the lit-length tables; a stage on a worker thread overlaps the others.
    inner = [s for s in PRINTED[:-2] if s != "min/max maps" and s not in timer.beside]
    seconds["other"] = seconds["frame update"] - sum(seconds.get(s, 0.0) for s in inner)
    seconds["beside"] = sorted(timer.beside)
    return seconds


def baseline_package(revision, name="ols_baseline"):
    """The extension at ``revision`` (a detached worktree) imported as package ``name``."""
    folder = Path(tempfile.mkdtemp(prefix="ols_frame_baseline_")) / "tree"
    subprocess.run(["git", "worktree", "add", "--detach", str(folder), revision], cwd=ROOT, check=True,
                   capture_output=True)
    spec = importlib.util.spec_from_file_location(name, folder / "__init__.py", submodule_search_locations=[str(folder)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return name, folder


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--against", default="HEAD", help="git revision of the baseline, or none")
    parser.add_argument("--scenes", default="sample,colonnade,forest")
    parser.add_argument("--size", default="960x540")
    parser.add_argument("--resolution", default="1024", help="shadow-map texels")
    parser.add_argument("--frames", type=int, default=5, help="frame updates per side and scene; medians print")
    args = parser.parse_args()
    os.environ.setdefault("OLS_CACHE_DIR", str(Path(tempfile.gettempdir()) / "ols_bench_cache"))
    import render as launcher
    pkg = launcher.import_extension()
    import bpy
    import shaft_scenes
    sides = [("new", pkg.__name__)]
    worktree = None
    if args.against != "none":
        name, worktree = baseline_package(args.against)
        sides.insert(0, ("base", name))
        # Both sides read the tables this tree baked (only the frame update is timed): a
        # baseline of another baker version would refuse them.
        # (A revision before lut_gen/store/exr_io.py was split holds BAKER_VERSION there.)
        base_store = import_module(f"{name}.lut_gen.store")
        base_header = getattr(base_store, "exr_header", None) or import_module(f"{name}.lut_gen.store.exr_io")
        base_header.BAKER_VERSION = import_module(f"{pkg.__name__}.lut_gen.store.exr_header").BAKER_VERSION
    timers = {label: stage_timer(package) for label, package in sides}
    width, height = (int(v) for v in args.size.split("x"))
    output = Path(tempfile.mkdtemp(prefix="ols_bench_")) / "frame.png"
    print(f"{os.cpu_count()} cores; baseline {args.against}; {args.size}, {args.resolution} texels; median of "
          f"{args.frames} frames each, alternating", flush=True)
    try:
        for scene_name in args.scenes.split(","):
            scene = shaft_scenes.wired(pkg, scene_name, width, height, output)
            scene.ols.shadow_map_resolution = args.resolution
            scene.ols.scattering_technique = "EPIPOLAR_SAMPLING"
            import_module(f"{pkg.__name__}.addon.scene.setup.wiring").match_light_shaft_layout(scene)
            depsgraph = bpy.context.evaluated_depsgraph_get()
            for label, package in sides:                            # warm-up: first-call costs
                frame_seconds(timers[label], package, scene, depsgraph)
            runs = {label: [] for label, _ in sides}
            for _ in range(args.frames):
                for label, package in sides:
                    runs[label].append(frame_seconds(timers[label], package, scene, depsgraph))
            _print(scene_name, runs)
    finally:
        if worktree is not None:
            subprocess.run(["git", "worktree", "remove", "--force", str(worktree)], cwd=ROOT, capture_output=True)


def _print(scene_name, runs):
    print(f"\n{scene_name}: median s per stage")
    print(f"{'':6} " + " ".join(f"{s[:12]:>12}" for s in PRINTED))
    medians = {label: {s: float(np.median([r.get(s, 0.0) for r in frames])) for s in PRINTED}
               for label, frames in runs.items()}
    for label, median in medians.items():
        print(f"{label:6} " + " ".join(f"{median[s]:12.3f}" for s in PRINTED))
    for label, frames in runs.items():
        if frames[0]["beside"]:
            print(f"  ({label}: {', '.join(frames[0]['beside'])} on a worker thread, beside the others; "
                  "not part of 'other')")
    if len(medians) == 2:
        base, new = medians["base"], medians["new"]
        print(f"{'ratio':6} " + " ".join(f"{new[s] / base[s] if base[s] > 1e-4 else float('nan'):12.2f}"
                                         for s in PRINTED), flush=True)


if __name__ == "__main__":
    main()
