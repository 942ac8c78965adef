"""The control fuzz (tests/addon/test_hostile_controls.py): random combinations of every control
and sun on a 64 x 36 render of the wired sample, this checkout against a baseline commit,
side by side in one run. Each variant runs in its own process on the same combinations (the
test's generator and seed); the wired scene's set-up is not timed.

    .venv/bin/python bench/bench_fuzz.py [--combinations 40] [--baseline 669a183]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from importlib import import_module
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
WIDTH, HEIGHT = 64, 36


def measure(code_root: Path, combinations: int) -> dict:
    """Seconds of ``combinations`` fuzz renders with the extension of ``code_root``."""
    import importlib.util
    sys.path.insert(0, str(code_root))
    sys.path.insert(0, str(code_root / "tests"))      # its conftest imports its extension
    import numpy as np
    from conftest import import_extension
    from render_util import render_rgb
    # The combinations of this checkout's test, for either variant.
    spec = importlib.util.spec_from_file_location("fuzz_combinations", ROOT / "tests" / "control_fuzz.py")
    fuzz = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fuzz)
    FUZZ_SEED, fuzzed_properties, random_combination = fuzz.FUZZ_SEED, fuzz.fuzzed_properties, fuzz.random_combination
    os.environ["OLS_CACHE_DIR"] = tempfile.mkdtemp()
    pkg = import_extension()
    pkg.register()
    sun_lamps = import_module(pkg.__name__ + ".addon.scene.sun")
    sys.path.insert(0, str(ROOT / "bench"))
    from wired_sample import wired_sample
    out = Path(tempfile.mkdtemp())
    scene, _ = wired_sample(pkg, out / "x.png", WIDTH, HEIGHT)
    render_rgb(scene, out / "warm.exr", composite=True)
    settings, sun = scene.ols, sun_lamps.find_sun(scene)
    rng = np.random.default_rng(FUZZ_SEED)
    props = fuzzed_properties(settings)
    times = []
    for combination in range(combinations):
        elevation, azimuth = random_combination(settings, props, rng)
        sun_lamps.set_sun_angles(sun, elevation, azimuth)
        settings.tone_map_exr = True
        start = time.perf_counter()
        render_rgb(scene, out / f"fuzz_{combination}.exr", composite=True)
        times.append(time.perf_counter() - start)
    return {"total": sum(times), "slowest": max(times), "median": sorted(times)[len(times) // 2]}


def run_variant(code_root: Path, combinations: int) -> dict:
    result = subprocess.run([sys.executable, __file__, "--measure", str(code_root), "--combinations", str(combinations)],
                            capture_output=True, text=True, cwd=str(ROOT))
    if result.returncode != 0:
        raise SystemExit(f"error: the run of {code_root} failed:\n{result.stderr[-3000:]}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--combinations", type=int, default=40)
    parser.add_argument("--baseline", default="669a183", help="commit to compare with (default: before render_detail)")
    parser.add_argument("--measure", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        print(json.dumps(measure(Path(args.measure), args.combinations)))
        return
    with tempfile.TemporaryDirectory() as worktree:
        subprocess.run(["git", "worktree", "add", "--detach", worktree, args.baseline], cwd=ROOT, check=True,
                       capture_output=True)
        try:
            base = run_variant(Path(worktree), args.combinations)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", worktree], cwd=ROOT, capture_output=True)
    now = run_variant(ROOT, args.combinations)
    print(f"{args.combinations} fuzz combinations at {WIDTH} x {HEIGHT} (renders only):")
    for name, value in (("baseline " + args.baseline, base), ("this checkout", now)):
        print(f"  {name:24s} total {value['total']:7.1f} s  median {value['median']:.2f} s  slowest {value['slowest']:.2f} s")
    print(f"  ratio (this / baseline): total {now['total'] / base['total']:.2f}x, "
          f"slowest {now['slowest'] / base['slowest']:.2f}x")


if __name__ == "__main__":
    main()
