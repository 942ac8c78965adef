"""Bake benchmark: draft and default bake times split by stage, this tree side by side with a
baseline run of another revision, and their ratios.

    .venv/bin/python bench/bench_bake.py                    # against the three-wavelength baker
    .venv/bin/python bench/bench_bake.py --against 3f596fa  # the first working baker
    .venv/bin/python bench/bench_bake.py --against HEAD~3   # against any git revision
    .venv/bin/python bench/bench_bake.py --against none     # this tree only
    .venv/bin/python bench/bench_bake.py --fog --against 591d75c   # morning fog and clear sky, default tables

Each bake is the first of a fresh process, as a first Set Up Scene, a farm worker or a batch render
meets it (a second bake in the same process finds glibc's heap grown and ran up to 20% faster before
lut_gen/tables/process_tuning.py); the two sides alternate, --repeats times each, and the medians
are compared. The goals on this 2-core machine, set when the background bake and its draft preview
came in: default <= 15 s and <= 0.6x of the baker before its speed-up (run --against 041da50),
draft <= 2 s. Against the three-wavelength baker (the default baseline) the ratios are the price of 12 + 7
wavelengths, the separate Mie table and the ground.

--fog times the morning-fog preset (lut_gen.model.air_presets.FOG_PRESETS: 300 m visibility, 50 m
deep, orders until converged) and the clear sky, both at the default resolution. The goals, set
when fog came in: the fog <= 60 s on this machine, the clear sky no slower than the baseline.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
THREE_WAVELENGTH_BAKER = "9e56945"   # the last commit before the spectral bake
GOALS = {"draft": 2.0, "default": 15.0,      # a draft preview within seconds of a change
         "morning-fog": 60.0}                 # fog bakes until its orders converge
FOG_PRESET = "morning-fog"
# The last commit (2026-12-04) before the default bake was sped up on every core and by per-cell
# optical depth; the speed-up's goal was this ratio of its time.
BAKER_BEFORE_SPEEDUP, SPEEDUP_RATIO = "041da50", 0.6


def worker(source: str, case: str):
    sys.path.insert(0, source)
    import lut_gen
    if case == FOG_PRESET:
        from lut_gen.model.air_presets import air_preset_changes
        params, resolution = lut_gen.AtmosphereParams(**air_preset_changes(FOG_PRESET)), "default"
    else:
        params, resolution = lut_gen.AtmosphereParams(), case
    start = time.perf_counter()
    luts = lut_gen.bake(params, resolution=resolution)
    elapsed = time.perf_counter() - start
    stages = {k: v for k, v in luts.timings.items() if k != "higher orders (total)"}
    if case == FOG_PRESET:
        # Twenty orders: their sum, not a line each.
        orders = [k for k in stages if k.startswith("order ")]
        stages = {k: v for k, v in stages.items() if k not in orders}
        stages[f"orders (converged: {luts.orders_used})"] = sum(luts.timings[k] for k in orders)
    stages["total"] = elapsed
    print(json.dumps(stages))


def run_once(source: Path, case: str) -> dict:
    """One bake, the first of a fresh process (what a first Set Up Scene, a farm worker or a
    batch render waits for; a second bake in the same process finds the heap grown)."""
    out = subprocess.run([sys.executable, __file__, "--worker", str(source), case],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def medians(runs: list) -> dict:
    return {stage: statistics.median(run[stage] for run in runs if stage in run) for stage in runs[0]}


def checkout(revision: str) -> Path:
    target = Path(tempfile.mkdtemp(prefix="ols-bench-"))
    subprocess.run(["git", "-C", str(ROOT), "archive", revision, "lut_gen"], check=True,
                   stdout=open(target / "src.tar", "wb"))
    subprocess.run(["tar", "-xf", "src.tar"], cwd=target, check=True)
    return target


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        return worker(sys.argv[2], sys.argv[3])
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--against", default=THREE_WAVELENGTH_BAKER, help="git revision of the baseline, or none")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--fog", action="store_true", help="the morning-fog preset and the clear sky at the "
                                                           "default resolution instead of draft and default")
    args = parser.parse_args()
    baseline_src = None if args.against == "none" else checkout(args.against)
    print(f"{os.cpu_count()} cores; baseline: {args.against}; median of {args.repeats} fresh processes each, "
          "the two sides alternating")
    for resolution in ((FOG_PRESET, "default") if args.fog else ("draft", "default")):
        now_runs, base_runs = [], []
        for _ in range(args.repeats):
            now_runs.append(run_once(ROOT, resolution))
            if baseline_src:
                base_runs.append(run_once(baseline_src, resolution))
        now = medians(now_runs)
        base = medians(base_runs) if base_runs else {}
        print(f"\n{resolution:<11} stage                now [s]   baseline [s]   now/baseline")
        for stage in list(now) + [s for s in base if s not in now]:
            n, b = now.get(stage), base.get(stage)
            cells = [f"{n:9.2f}" if n is not None else "        -", f"{b:12.2f}" if b is not None else "           -",
                     f"{n / b:12.2f}x" if n and b else "            -"]
            print(f"  {stage:<28}{cells[0]}   {cells[1]}   {cells[2]}")
        verdict = "met" if now["total"] <= GOALS[resolution] else "NOT met"
        print(f"  goal: total <= {GOALS[resolution]:.0f} s: {verdict}")
        if not args.fog and resolution == "default" and base and args.against.startswith(BAKER_BEFORE_SPEEDUP):
            ratio = now["total"] / base["total"]
            print(f"  goal: total <= {SPEEDUP_RATIO}x of {BAKER_BEFORE_SPEEDUP}: {'met' if ratio <= SPEEDUP_RATIO else 'NOT met'} "
                  f"({ratio:.2f}x)")
        if args.fog and resolution == "default" and base:
            print(f"  goal: no slower than the baseline: {'met' if now['total'] <= base['total'] * 1.03 else 'NOT met'} "
                  "(within 3%, the spread of fresh processes)")


if __name__ == "__main__":
    main()
