"""Compositor passes benchmark (Cycles CPU): the sample scene at 1280 x 720, 16 samples,
rendered without compositing and with the add-on's passes (aerial perspective + tone mapping),
printed side by side with the ratio. Goal for the scattering pass: <= 1.5x.

    .venv/bin/python bench/bench_passes.py [--resolution 1280x720] [--samples 16]
"""
import argparse
import importlib
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--resolution", default="1280x720")
    parser.add_argument("--samples", type=int, default=16)
    args = parser.parse_args()
    os.environ.setdefault("OLS_CACHE_DIR", str(Path(tempfile.gettempdir()) / "ols_bench_cache"))
    import render as launcher
    package = launcher.import_extension()
    import bpy
    batch = importlib.import_module(package.__name__ + ".addon.batch")
    options = batch.parse_args(["--sample", "--output", "unused.png", "--resolution", args.resolution,
                                "--samples", str(args.samples), "--sun-elevation", "15", "--sun-azimuth", "35"])
    scene = batch.prepare(options)
    batch.apply_options(scene, options)
    assert bpy.ops.ols.setup_scene() == {"FINISHED"}
    times = {}
    for label, compositing in (("render only", False), ("render + passes", True), ("render only", False),
                               ("render + passes", True)):
        scene.render.use_compositing = compositing
        start = time.perf_counter()
        bpy.ops.render.render(write_still=False)
        times[label] = min(times.get(label, 1e9), time.perf_counter() - start)
    base = times["render only"]
    print(f"Cycles CPU, {os.cpu_count()} cores, {args.resolution}, {args.samples} samples (best of 2)")
    for label, seconds in times.items():
        print(f"  {label:<20} {seconds:8.2f} s   {seconds / base:6.2f}x")
    print(f"  passes alone: {times['render + passes'] - base:.2f} s (goal: <= 0.5x of the render)")


if __name__ == "__main__":
    main()
