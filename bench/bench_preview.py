"""How long a user looks at the old sky after changing the atmosphere (a slider in the Additional
set), with the draft preview against without it, side by side in one run.

The sample is wired to the default tables (baked first, not timed). Then, for a new aerosol
density each time (nothing cached), the time from the change to:
  - the analytic model standing in (baking.show_analytic_stand_in, as the Bake Tables operator
    does just before it starts the bake's thread);
  - the preview on screen: the draft bake (addon/baking.py's BackgroundBake) and its swap into
    the scene (the node groups rebuilt);
  - the full tables on screen after the preview: the default bake finished and swapped in;
  - the full tables on screen without a preview (the baseline: what a change did before).
The operator's timer in the UI adds up to 0.2 s to each and the change waits 0.75 s for a slider
drag to settle (props.REBAKE_DELAY_S); neither is included.

    .venv/bin/python bench/bench_preview.py
"""
import os
import sys
import tempfile
import time
from importlib import import_module
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOAL_PREVIEW_S = 1.0


def main():
    os.environ["OLS_CACHE_DIR"] = tempfile.mkdtemp(prefix="ols_bench_preview_")
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / "tests"))
    import bpy
    from extension import import_extension
    pkg = import_extension()
    pkg.register()
    batch = import_module(pkg.__name__ + ".addon.batch")
    baking = import_module(pkg.__name__ + ".addon.baking")
    settings = import_module(pkg.__name__ + ".addon.settings")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    args = batch.parse_args(["--sample", "--tables", "default", "--resolution", "64x36", "--samples", "1",
                             "--output", str(Path(tempfile.mkdtemp()) / "x.png")])
    scene = batch.prepare(args)
    batch.apply_options(scene, args)
    batch.wire(scene, args)

    def change(density):
        scene.ols.aerosol_density = density
        return settings.atmosphere_params(scene.ols).validate()

    # With the preview: the analytic model stands in at once (what the Bake Tables operator does
    # right after starting the bake), then the draft.
    start = time.perf_counter()
    params = change(1.37)
    assert baking.wants_preview(params, "default") and baking.analytic_can_stand_in(scene)
    baking.show_analytic_stand_in(scene)
    stand_in_shown = time.perf_counter()
    bake = baking.BackgroundBake(params, "default", preview=True)
    while not (bake.preview_ready or bake.done):
        time.sleep(0.01)
    preview_baked = time.perf_counter()
    baking.swap_in(scene, bake.preview_directory, preview=True)
    preview_shown = time.perf_counter()
    bake.wait()
    baking.swap_in(scene, bake.directory)
    full_after_preview = time.perf_counter()

    # Without it (the baseline).
    start_plain = time.perf_counter()
    plain = baking.BackgroundBake(change(1.53), "default", preview=False)
    plain.wait()
    baking.swap_in(scene, plain.directory)
    full_plain = time.perf_counter()

    to_preview = preview_shown - start
    print(f"change -> analytic stand-in on screen {stand_in_shown - start:6.2f} s (goal {GOAL_PREVIEW_S:.0f} s)")
    print(f"change -> preview on screen   {to_preview:6.2f} s (draft bake {preview_baked - start:.2f} s, "
          f"swap {preview_shown - preview_baked:.2f} s; goal {GOAL_PREVIEW_S:.0f} s)")
    print(f"change -> full tables, after the preview {full_after_preview - start:6.2f} s")
    print(f"change -> full tables, no preview (baseline) {full_plain - start_plain:6.2f} s")
    print(f"first look: {to_preview / (full_plain - start_plain):.2f}x of the baseline's wait; "
          f"full tables: {(full_after_preview - start) / (full_plain - start_plain):.2f}x")


if __name__ == "__main__":
    main()
