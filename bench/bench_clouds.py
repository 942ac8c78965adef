"""Cloud-layer benchmark (Cycles CPU): what the clouds add to the sample's render and to its
light-shaft pass, clouds off and on side by side in one process.

For each cloud setting (off, then on with the given preset) the sample is rendered
- with the compositor off: the Cycles render (the world with the "OLS Clouds" branch and the
  shadow-only layer under the sun);
- with the compositor on and light shafts on (--technique): render + aerial perspective + shafts
  + tone mapping, every frame paying for its shadow maps and, for epipolar sampling, its tables
  (the per-frame cache is cleared before each render).
The light-shaft pass is the difference of the two. Printed: the medians of --repeats renders and
the ratios clouds on / clouds off, with Cycles' adaptive sampling (the default: a pixel stops
when its noise is under the threshold, so a clear sky stops early and cloud edges take more of
the samples) and with a fixed --samples per pixel (what the shaders cost).

    .venv/bin/python bench/bench_clouds.py [--resolution 480x270] [--samples 64] [--repeats 3]
        [--clouds fair-weather-cumulus] [--technique BRUTE_FORCE|EPIPOLAR_SAMPLING]
        [--sampling both|adaptive|fixed]

Goals: clouds add at most 25% to the 64-sample render and at most 30% to the light-shaft pass.
"""
import argparse
import importlib
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT / "bench"))


def timed(scene, repeats, compositing, forget):
    """Median seconds of ``repeats`` renders after one that warms the caches."""
    import bpy
    scene.render.use_compositing = compositing
    times = []
    for run in range(repeats + 1):
        forget()
        start = time.perf_counter()
        bpy.ops.render.render(write_still=False)
        if run:
            times.append(time.perf_counter() - start)
    return statistics.median(times)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", default="480x270")
    parser.add_argument("--samples", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--clouds", default="fair-weather-cumulus")
    parser.add_argument("--technique", default="BRUTE_FORCE", choices=("BRUTE_FORCE", "EPIPOLAR_SAMPLING"))
    parser.add_argument("--sampling", default="both", choices=("both", "adaptive", "fixed"))
    args = parser.parse_args(argv)
    os.environ.setdefault("OLS_CACHE_DIR", str(Path(tempfile.gettempdir()) / "ols_bench_cache"))
    import render as launcher
    pkg = launcher.import_extension()
    wired_sample = importlib.import_module("wired_sample").wired_sample
    frame_update = importlib.import_module(pkg.__name__ + ".addon.scene.frame.frame_update")
    width, height = (int(v) for v in args.resolution.split("x"))
    with tempfile.TemporaryDirectory() as folder:
        scene, _ = wired_sample(pkg, Path(folder) / "bench.png", width, height)
        scene.cycles.samples = args.samples
        scene.ols.scattering_technique = args.technique
        samplings = ("adaptive", "fixed") if args.sampling == "both" else (args.sampling,)
        results = {}
        for sampling in samplings:
            scene.cycles.use_adaptive_sampling = sampling == "adaptive"
            for clouds in (False, True):
                scene.ols.clouds_enabled = clouds
                if clouds:
                    scene.ols.cloud_preset = args.clouds.upper().replace("-", "_")
                render = timed(scene, args.repeats, False, frame_update.forget)
                whole = timed(scene, args.repeats, True, frame_update.forget)
                results[sampling, clouds] = (render, whole, whole - render)
    print(f"sample {width}x{height}, {args.samples} samples, light shafts {args.technique}, "
          f"clouds {args.clouds}; median of {args.repeats}")
    for sampling in samplings:
        print(f" {sampling} sampling")
        for label, index in (("render (compositor off)", 0), ("render + passes", 1), ("light-shaft pass", 2)):
            off, on = results[sampling, False][index], results[sampling, True][index]
            print(f"  {label:26s} clouds off {off:7.2f} s   on {on:7.2f} s   on/off {on / max(off, 1e-9):5.2f}x")


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else None)
