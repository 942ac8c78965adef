"""Bake benchmark: draft and default bake times split by stage, this tree side by side with a
baseline run of another revision, and their ratios.

    .venv/bin/python bench/bench_bake.py                    # against the three-wavelength baker
    .venv/bin/python bench/bench_bake.py --against 3f596fa  # the first working baker
    .venv/bin/python bench/bench_bake.py --against HEAD~3   # against any git revision
    .venv/bin/python bench/bench_bake.py --against none     # this tree only

Each side runs in its own process (best of --repeats). The goals on this 2-core machine:
default <= 30 s (stretch <= 15 s) for the spectral bake, draft <= 5 s. The baseline bakes
the sample's three wavelengths (what lut_gen.bake() did before the spectral bake), so the
ratios are the price of 12 + 7 wavelengths, the separate Mie table and the ground.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
THREE_WAVELENGTH_BAKER = "9e56945"   # the last commit before the spectral bake
GOALS = {"draft": 5.0, "default": 30.0}


def worker(source: str, resolution: str, repeats: int):
    sys.path.insert(0, source)
    import lut_gen
    best = None
    for _ in range(repeats):
        start = time.perf_counter()
        luts = lut_gen.bake(resolution=resolution)
        stages = {k: v for k, v in luts.timings.items() if k != "higher orders (total)"}
        stages["total"] = time.perf_counter() - start
        if best is None or stages["total"] < best["total"]:
            best = stages
    print(json.dumps(best))


def run_side(source: Path, resolution: str, repeats: int) -> dict:
    out = subprocess.run([sys.executable, __file__, "--worker", str(source), resolution, str(repeats)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def checkout(revision: str) -> Path:
    target = Path(tempfile.mkdtemp(prefix="ols-bench-"))
    subprocess.run(["git", "-C", str(ROOT), "archive", revision, "lut_gen"], check=True,
                   stdout=open(target / "src.tar", "wb"))
    subprocess.run(["tar", "-xf", "src.tar"], cwd=target, check=True)
    return target


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        return worker(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--against", default=THREE_WAVELENGTH_BAKER, help="git revision of the baseline, or none")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    baseline_src = None if args.against == "none" else checkout(args.against)
    print(f"{os.cpu_count()} cores; baseline: {args.against}; best of {args.repeats}")
    for resolution in ("draft", "default"):
        now = run_side(ROOT, resolution, args.repeats)
        base = run_side(baseline_src, resolution, args.repeats) if baseline_src else {}
        print(f"\n{resolution:<8} stage                   now [s]   baseline [s]   now/baseline")
        for stage in list(now) + [s for s in base if s not in now]:
            n, b = now.get(stage), base.get(stage)
            cells = [f"{n:9.2f}" if n is not None else "        -", f"{b:12.2f}" if b is not None else "           -",
                     f"{n / b:12.2f}x" if n and b else "            -"]
            print(f"  {stage:<28}{cells[0]}   {cells[1]}   {cells[2]}")
        verdict = "met" if now["total"] <= GOALS[resolution] else "NOT met"
        print(f"  goal: total <= {GOALS[resolution]:.0f} s: {verdict}")


if __name__ == "__main__":
    main()
