"""What a re-render of the wired sample costs after a change (paid by every combination of the
control fuzz and by every F12 or animation frame with Persistent Data): the terrain's emission sampled as a light (the
baseline: what Set Up Scene did before) against not sampled, side by side in one run.

Each variant runs in its own process (Cycles keeps a material's emission sampling from the
first render while Persistent Data keeps the scene), wires the sample at 64 x 36 with 1 Cycles sample, and
times renders after nothing changed, after the sun moved and after a tone-mapping setting
changed (median of --repeat each).

    .venv/bin/python bench/bench_rerender.py [--repeat 5]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from importlib import import_module
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VARIANTS = {"terrain emission sampled as a light (baseline)": "AUTO",
            "terrain emission not sampled (Set Up Scene now)": "NONE"}


def measure(emission_sampling: str, repeat: int) -> dict:
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / "tests"))
    import bpy
    from conftest import import_extension
    pkg = import_extension()
    pkg.register()
    sun_lamps = import_module(pkg.__name__ + ".addon.scene.sun")
    sys.path.insert(0, str(ROOT / "bench"))
    from wired_sample import wired_sample
    scene, terrain = wired_sample(pkg, Path(tempfile.mkdtemp()) / "frame.png")
    for obj in terrain:
        obj.active_material.cycles.emission_sampling = emission_sampling
    scene.ols.enable_light_shafts = False          # Blender's share, not the shafts' numpy work
    sun = sun_lamps.find_sun(scene)

    def render():
        start = time.perf_counter()
        bpy.ops.render.render(write_still=False)
        return time.perf_counter() - start

    render()
    times = {"nothing changed": [], "sun moved": [], "middle gray changed": []}
    for i in range(repeat):
        times["nothing changed"].append(render())
        sun_lamps.set_sun_angles(sun, 10.0 + 3 * i, 30.0)
        times["sun moved"].append(render())
        scene.ols.middle_gray = 0.1 + 0.01 * i
        times["middle gray changed"].append(render())
    return {name: statistics.median(values) for name, values in times.items()}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--variant", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.variant:
        print("RESULT " + json.dumps(measure(args.variant, args.repeat)))
        return
    results = {}
    for name, mode in VARIANTS.items():
        run = subprocess.run([sys.executable, __file__, "--variant", mode, "--repeat", str(args.repeat)],
                             capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))
        line = next((l for l in run.stdout.splitlines() if l.startswith("RESULT ")), None)
        if line is None:
            sys.exit(f"error: the {mode} run failed:\n{run.stderr[-2000:]}")
        results[name] = json.loads(line[len("RESULT "):])
    base = results[next(iter(VARIANTS))]
    print(f"sample scene wired, 64 x 36, 1 Cycles sample, light shafts off, median of {args.repeat}")
    for name, times in results.items():
        print(name)
        for change, seconds in times.items():
            print(f"  {change:22s} {seconds:6.3f} s  {seconds / base[change]:5.2f}x")


if __name__ == "__main__":
    main()
