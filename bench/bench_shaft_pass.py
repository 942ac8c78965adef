"""The whole light-shaft pass, epipolar sampling against brute force, on several scenes and
sizes: what the pass adds to a render, shadow maps and tables included.

For each scene (bench/shaft_scenes.py: the sample, a colonnade, a forest of 10 000 instanced
trees) and size, the frame is rendered once (1 Cycles sample) and the compositor then fed from
it (bench/saved_render.py: the renders below skip Cycles and its run-to-run noise, which is
the same with and without the pass). Three configurations, best of --repeat, the add-on's
per-frame cache cleared before each so every render pays for the shadow maps and tables as a
new animation frame would:
- the scattering pass off (its aerial perspective and light-shaft nodes muted; tone mapping runs);
- light shafts on, brute force;
- light shafts on, epipolar sampling.
The pass is a render minus the render without it; the ratio is epipolar / brute force
(goals: <= 0.25x at 960 x 540, <= 0.15x at 1920 x 1080), and the PSNR between the two
techniques' linear output (bar: 40 dB).

Per stage, the per-frame numpy work of each technique (best of --repeat calls of the frame
update outside a render): shadow maps (gathering the triangles and rasterising), the epipolar
lit-length tables, the in-scattering tables, packing and writing the images, and the rest
(goal: <= 0.5 s at 1024-texel shadow maps). The compositor's share is the pass minus it.

    .venv/bin/python bench/bench_shaft_pass.py [--scenes sample,colonnade,forest]
        [--sizes 960x540,1920x1080] [--repeat 2]
"""
import argparse
import os
import sys
import tempfile
import threading
import time
from collections import defaultdict
from importlib import import_module
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT / "bench"))

TECHNIQUES = ("BRUTE_FORCE", "EPIPOLAR_SAMPLING")


class StageTimer:
    """Wraps module functions so each call's time adds to its stage, by name; ``beside`` names
    the stages that ran on another thread than the main one (their time overlaps the others')."""

    def __init__(self):
        self.seconds = defaultdict(float)
        self.beside = set()

    def wrap(self, module, attribute, stage):
        original = getattr(module, attribute)

        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self.seconds[stage] += time.perf_counter() - start
                if threading.current_thread() is not threading.main_thread():
                    self.beside.add(stage)
        setattr(module, attribute, timed)

    def reset(self):
        self.seconds.clear()
        self.beside.clear()


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", default="sample,colonnade,forest")
    parser.add_argument("--sizes", default="960x540,1920x1080")
    parser.add_argument("--repeat", type=int, default=2, help="runs per configuration; the best counts")
    args = parser.parse_args()
    os.environ.setdefault("OLS_CACHE_DIR", str(Path(tempfile.gettempdir()) / "ols_bench_cache"))
    import render as launcher
    pkg = launcher.import_extension()
    import bpy
    import saved_render
    import shaft_scenes          # puts tests/ on the path: render_util
    import render_util

    def module(name):
        return import_module(f"{pkg.__name__}.{name}")

    frame_update = module("addon.scene.frame.frame_update")
    wiring = module("addon.scene.setup.wiring")
    compositor = module("addon.scene.setup.compositor")
    shadow_maps = module("addon.scene.frame.shadow_maps")
    names = module("addon.scene.names")
    display = module("lut_gen.verify.display")
    timer = StageTimer()
    timer.wrap(shadow_maps, "scene_triangles", "gather triangles")
    timer.wrap(module("lut_gen.passes.shadow_map"), "render_cascades", "rasterise")
    timer.wrap(shadow_maps, "write_images", "shadow images")
    timer.wrap(module("lut_gen.passes.epipolar"), "build_tables", "lit-length tables")
    timer.wrap(module("lut_gen.passes.epipolar_air"), "build", "in-scattering tables")
    timer.wrap(module("addon.nodes.epipolar"), "pack", "pack tables")
    timer.wrap(frame_update, "_epipolar_tables", "epipolar total")
    timer.wrap(frame_update, "update_frame", "frame update")

    def configure(scene, shafts, technique="BRUTE_FORCE"):
        """Shafts on with ``technique``, or (shafts False) the whole scattering pass off: the
        aerial perspective muted too, as the epipolar technique makes the whole image and its
        input (the aerial perspective) is then not evaluated; tone mapping runs in all."""
        scene.ols.scattering_technique = technique
        scene.ols.enable_light_shafts = shafts
        wiring.match_light_shaft_layout(scene)
        compositor.sync_settings(scene)
        aerial = scene.compositing_node_group.nodes.get(names.AERIAL_NODE)
        aerial.mute = not shafts

    def best_render(scene):
        best = 1e9
        for _ in range(args.repeat):
            frame_update.forget()
            start = time.perf_counter()
            bpy.ops.render.render(write_still=False)
            best = min(best, time.perf_counter() - start)
        return best

    def linear_frame(scene, path):
        """The pass's linear output (tone mapping muted), as the accuracy tests compare it."""
        tone = scene.compositing_node_group.nodes.get(names.TONE_NODE)
        tone.mute = True
        try:
            return render_util.render_rgb(scene, path, composite=True)
        finally:
            tone.mute = False
            scene.render.use_compositing = True

    def numpy_stages(scene):
        """{stage: seconds} of the best frame update (by its total)."""
        depsgraph = bpy.context.evaluated_depsgraph_get()
        best = None
        for _ in range(args.repeat + 1):
            frame_update.forget()
            timer.reset()
            frame_update.update_frame(scene, depsgraph)
            if best is None or timer.seconds["frame update"] < best["frame update"]:
                best = dict(timer.seconds)
        return best

    rows = []
    output = Path(tempfile.mkdtemp(prefix="ols_bench_")) / "frame.png"
    for name in args.scenes.split(","):
        for size in args.sizes.split(","):
            width, height = (int(v) for v in size.split("x"))
            print(f"{name} {size}: setting up", flush=True)
            scene = shaft_scenes.wired(pkg, name, width, height, output)
            saved = saved_render.save(scene)
            result = {}
            for technique in (None,) + TECHNIQUES:
                configure(scene, technique is not None, technique or "BRUTE_FORCE")
                saved_render.use(scene, saved)              # a layout rebuild relinks Render Layers
                bpy.ops.render.render(write_still=False)    # the layout's first render compiles it
                result[technique] = best_render(scene)
                if technique is not None:
                    result[technique + " numpy"] = numpy_stages(scene)
                    result[technique + " image"] = linear_frame(scene, output.parent / f"{name}_{size}_{technique}.exr")
            off = result.pop(None)
            for technique in TECHNIQUES:
                result[technique] -= off
            result["psnr"] = display.display_psnr(result.pop("EPIPOLAR_SAMPLING image"), result.pop("BRUTE_FORCE image"))
            rows.append((name, size, result))
            epipolar, brute = result["EPIPOLAR_SAMPLING"], result["BRUTE_FORCE"]
            print(f"  compositor without the pass {off:.2f} s; pass: brute force {brute:.2f} s, "
                  f"epipolar {epipolar:.2f} s = {epipolar / max(brute, 1e-9):.2f}x; "
                  f"epipolar vs brute force {result['psnr']:.1f} dB", flush=True)

    print("\nThe whole pass (aerial perspective + light shafts: render with it minus without), best of", args.repeat)
    print(f"{'scene':10} {'size':>10} {'brute s':>8} {'epipolar s':>10} {'ratio':>6} {'goal':>5} {'PSNR dB':>8}")
    for name, size, result in rows:
        goal = {"960x540": 0.25, "1920x1080": 0.15}.get(size, float("nan"))
        brute, epipolar = result["BRUTE_FORCE"], result["EPIPOLAR_SAMPLING"]
        print(f"{name:10} {size:>10} {brute:8.2f} {epipolar:10.2f} {epipolar / max(brute, 1e-9):6.2f} {goal:5.2f}"
              f" {result['psnr']:8.1f}")
    stages = ("gather triangles", "rasterise", "shadow images", "lit-length tables", "in-scattering tables",
              "pack tables")
    print("\nPer-frame numpy work, epipolar sampling (s; goal: frame update <= 0.5 s at 1024 texels)")
    print(f"{'scene':10} {'size':>10} " + " ".join(f"{s[:12]:>12}" for s in stages) + f" {'other':>8} {'frame':>8}"
          f" {'compositor':>10}")
    for name, size, result in rows:
        numpy = result["EPIPOLAR_SAMPLING numpy"]
        total = numpy.get("frame update", 0.0)
        other = total - sum(numpy.get(s, 0.0) for s in stages)
        composite = result["EPIPOLAR_SAMPLING"] - total
        print(f"{name:10} {size:>10} " + " ".join(f"{numpy.get(s, 0.0):12.3f}" for s in stages)
              + f" {other:8.3f} {total:8.3f} {composite:10.2f}")
    print("\nBrute force: per-frame numpy work (shadow maps only) and the compositor's share (s)")
    for name, size, result in rows:
        total = result["BRUTE_FORCE numpy"].get("frame update", 0.0)
        print(f"{name:10} {size:>10} frame update {total:6.3f}  compositor {result['BRUTE_FORCE'] - total:6.2f}")


if __name__ == "__main__":
    main()
