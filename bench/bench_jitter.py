"""Jittered march steps: how they trade the bands of a few-step brute-force march for noise,
at 8, 16 and 32 steps against a 256-step march, on a row of pillars against a low sun (the
numpy twin, lut_gen.passes.scattering_pass; metrics: lut_gen.verify.banding, fractions of the
shafts' size over the sky). With --figure, a PNG of the 16-step march's error without and with
jitter beside the 256-step frame (docs/jitter.png).

    .venv/bin/python bench/bench_jitter.py [--figure docs/jitter.png]
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import lut_gen                                              # noqa: E402
from lut_gen.store.png import write_png                    # noqa: E402
from lut_gen.verify import banding                          # noqa: E402
from lut_gen.verify.display import display, exposure_of  # noqa: E402
from occluders import CAMERA, Scene, pillars, sun_at    # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--figure", type=Path, default=None)
    args = parser.parse_args()
    luts = lut_gen.bake(resolution="draft")
    scene = Scene(pillars(), CAMERA, sun_at(4.0, 5.0), 384, 216)
    start = time.perf_counter()

    def run(**settings):
        return scene.shafts(luts, scattering_technique="BRUTE_FORCE", **settings)

    reference = run(num_integration_steps=256)
    unshadowed = run(num_integration_steps=256, enable_light_shafts=False)
    sky = ~scene.geometry
    print(f"{'steps':>5} {'jitter':>6} {'banding':>8} {'band step':>9} {'pixel step':>10} {'mean |e|':>9} {'bias':>8}")
    images = {}
    for steps in (8, 16, 32):
        for jittered in (False, True):
            image = run(num_integration_steps=steps, jitter_steps=jittered)
            images[steps, jittered] = image
            m = banding.measure(image, reference, unshadowed, sky)
            print(f"{steps:5d} {'on' if jittered else 'off':>6} {m['banding']:8.3f} {m['banding_step']:9.3f} "
                  f"{m['pixel_step']:10.3f} {m['mean_abs']:9.4f} {m['bias']:8.4f}", flush=True)
    print(f"({time.perf_counter() - start:.0f} s; fractions of the shafts' size, sky pixels)")
    if args.figure:
        # The error of the 16-step march without and with jitter (grey 0, white +50% of the
        # shafts' size, black -50%), beside the 256-step frame itself.
        signal = np.abs((unshadowed - reference) @ banding.LUMINANCE).max()
        panels = [np.repeat(np.clip(0.5 + ((images[16, j] - reference) @ banding.LUMINANCE) / signal, 0, 1)[..., None],
                            3, axis=-1) for j in (False, True)]
        panels.append(display(reference, exposure_of(reference)))
        strip = np.concatenate([p[::-1] for p in panels], axis=1)      # rows top to bottom
        write_png(args.figure, np.clip(np.round(strip * 255), 0, 255).astype(np.uint8))
        print(f"wrote {args.figure}: the error of 16 steps, of 16 jittered steps; the 256-step frame")

if __name__ == "__main__":
    main()
