"""What a sun move costs the world-lighting panoramas (addon/scene/frame/skylight.py): the sky and
ground panoramas for the default tables computed per pixel with Luts.sky_radiance and
Luts.ground_radiance, tables re-packed on every call (the baseline: what skylight did before),
the same with the packed tables kept (Luts.keep_packed), lut_gen.passes.panorama, and what a move
costs now: the panoramas plus the camera's twilight correction (lut_gen.passes.sky_view: its
grid integrated, then read for every panorama pixel), side by side in one run, with the largest
difference from the baseline (the correction's own, by design, in the last row).

    .venv/bin/python bench/bench_skylight.py [--repeat 5] [--height 500] [--elevation 10]
"""
import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import lut_gen  # noqa: E402
from lut_gen.passes import panorama, sky_view  # noqa: E402

SIZE = (512, 256)               # addon/scene/frame/skylight.py's


def per_pixel(luts, sun, height):
    """The baseline, as skylight.panoramas was: every pixel's look-up, directions included."""
    d = panorama.directions.__wrapped__(*SIZE)
    view = (max(height, 0.0), d[..., 2], sun[2], d @ sun)
    start = time.perf_counter()
    sky = luts.sky_radiance(*view)
    middle = time.perf_counter()
    ground = luts.ground_radiance(*view)
    return (sky, ground), (middle - start, time.perf_counter() - middle)


def fast(luts, sun, height):
    d = panorama.directions(*SIZE)
    view = (max(height, 0.0), d[:, :1, 2], sun[2], d @ sun)
    start = time.perf_counter()
    sky = panorama.sky(luts, *view)
    middle = time.perf_counter()
    ground = panorama.ground(luts, *view)
    return (sky, ground), (middle - start, time.perf_counter() - middle)


def corrected(luts, sun, height):
    """skylight.update's work for a sun move: the correction and the corrected panoramas."""
    start = time.perf_counter()
    view = sky_view.compute(luts, height, float(sun[2]))
    (sky, ground), (sky_s, ground_s) = fast(luts, sun, height)
    d = panorama.directions(*SIZE)
    sky = sky + sky_view.correction_at(luts.params, view, d[..., 2], d @ sun)
    return (sky, ground), (time.perf_counter() - start - ground_s, ground_s)


def worst_relative_difference(new, old):
    """max |new - old| / old where old is above 1e-6 of its maximum."""
    significant = old > 1e-6 * old.max()
    return float((np.abs(new.astype(np.float64) - old)[significant] / old[significant]).max(initial=0.0))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--height", type=float, default=500.0, help="camera height (m)")
    parser.add_argument("--elevation", type=float, default=10.0, help="sun elevation (deg)")
    args = parser.parse_args()
    directory, _ = lut_gen.store.cache.bake_into(lut_gen.AtmosphereParams())
    luts = lut_gen.load(directory)
    packed = dataclasses.replace(luts, _packed=None).keep_packed()
    e = np.radians(args.elevation)
    sun = np.array([0.6 * np.cos(e), 0.8 * np.cos(e), np.sin(e)])
    rows = {"per-pixel look-ups, re-packed (baseline)": lambda: per_pixel(luts, sun, args.height),
            "per-pixel look-ups, packed kept": lambda: per_pixel(packed, sun, args.height),
            "lut_gen.passes.panorama, packed kept": lambda: fast(packed, sun, args.height),
            "panorama + twilight correction (now)": lambda: corrected(packed, sun, args.height)}
    results = {}
    for name, run in rows.items():
        run()                   # the first call packs the kept tables (once per bake in the add-on)
        best = None
        for _ in range(args.repeat):
            start = time.perf_counter()
            images, parts = run()
            total = time.perf_counter() - start
            if best is None or total < best[0]:
                best = (total, parts)
        results[name] = best, images
    (base, _), (sky_base, ground_base) = results["per-pixel look-ups, re-packed (baseline)"]
    print(f"default tables {luts.dims}, {SIZE[0]} x {SIZE[1]} panoramas, sun {args.elevation:g} deg, "
          f"camera {args.height:g} m, best of {args.repeat}")
    print(f"{'':42s} {'total':>8s} {'ratio':>6s} {'sky':>8s} {'ground':>8s}  max rel. difference sky / ground")
    for name, ((seconds, (sky_s, ground_s)), (sky, ground)) in results.items():
        print(f"{name:42s} {seconds:6.3f} s {seconds / base:5.2f}x {sky_s:6.3f} s {ground_s:6.3f} s  "
              f"{worst_relative_difference(sky, sky_base):.1e} / {worst_relative_difference(ground, ground_base):.1e}")


if __name__ == "__main__":
    main()
