"""What verifying the tables costs Set Up Scene: loading the default bake's six table
files into Blender images without verification (the baseline: what setup did before) and with it,
cold (every file hashed) and warm (hashes cached by size and mtime), side by side in one run.

    .venv/bin/python bench/bench_table_setup.py [--repeat 3]
"""
import argparse
import sys
import time
from importlib import import_module
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    import bpy
    from conftest import import_extension
    pkg = import_extension()
    lut_gen = import_module(pkg.__name__ + ".lut_gen")
    luts_module = import_module(pkg.__name__ + ".addon.scene.tables.luts")
    manifest = lut_gen.store.manifest
    directory, _ = lut_gen.store.cache.bake_into(lut_gen.AtmosphereParams())

    def fresh_images():
        bpy.ops.wm.read_factory_settings(use_empty=True)

    def load_only():
        """The baseline: load_images with the verification taken out (what setup did before)."""
        verify = luts_module.verify_bake
        luts_module.verify_bake = lambda d, key=None: lut_gen.store.exr_header.read_key(d)
        try:
            for image in luts_module.load_images(directory).values():
                image.pixels[0]
        finally:
            luts_module.verify_bake = verify

    def verified(cold):
        if cold:
            manifest._hash_cache.clear()
            lut_gen.store.exr_header._header_key_cache.clear()
        images = luts_module.load_images(directory)
        for image in images.values():
            image.pixels[0]

    rows = {"load without verification (baseline)": load_only,
            "load_images, verification cold": lambda: verified(True),
            "load_images, verification warm": lambda: verified(False)}
    times = {}
    for name, run in rows.items():
        best = float("inf")
        for _ in range(args.repeat):
            fresh_images()
            start = time.perf_counter()
            run()
            best = min(best, time.perf_counter() - start)
        times[name] = best
    base = times["load without verification (baseline)"]
    print(f"default bake in {directory} ({sum(p.stat().st_size for p in directory.glob('*.exr')) / 2**20:.0f} MiB)")
    for name, seconds in times.items():
        print(f"{name:42s} {seconds:6.2f} s  {seconds / base:5.2f}x")


if __name__ == "__main__":
    main()
