"""How long the analytic model (Atmosphere Model > Analytic) takes to show a changed atmosphere,
against the draft preview bake, side by side in one run.

The sample is set up under the analytic model (timed: no bake). Then, for a new aerosol density
each time, the time from the slider change to the rebuilt groups (the media groups only), and
for comparison the draft bake of the same density and its swap into a scene on the tables (what
the precomputed model shows first). The renders themselves are not included.

    .venv/bin/python bench/bench_analytic.py
"""
import os
import sys
import tempfile
import time
from importlib import import_module
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOAL_PREVIEW_S = 1.0
CHANGES = (1.37, 2.11, 0.64)


def main():
    os.environ["OLS_CACHE_DIR"] = tempfile.mkdtemp(prefix="ols_bench_analytic_")
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / "tests"))
    import bpy
    from extension import import_extension
    pkg = import_extension()
    pkg.register()
    baking = import_module(pkg.__name__ + ".addon.baking")
    settings = import_module(pkg.__name__ + ".addon.settings")
    from scenes import sample_scene
    scene = sample_scene(pkg)
    scene.ols.atmosphere_model = "ANALYTIC"
    start = time.perf_counter()
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    print(f"Set Up Scene under the analytic model: {time.perf_counter() - start:.2f} s (no bake)")

    analytic = []
    for density in CHANGES:
        start = time.perf_counter()
        scene.ols.aerosol_density = density
        analytic.append(time.perf_counter() - start)

    scene.ols.atmosphere_model = "PRECOMPUTED"          # in a script: stays on the analytic groups until ...
    params = settings.atmosphere_params(scene.ols).validate()
    baking.swap_in(scene, baking.bake_if_needed(params, "draft"))     # on the tables (not timed)
    draft = []
    for density in CHANGES:
        scene.ols.aerosol_density = density + 0.01          # not cached
        start = time.perf_counter()
        baking.swap_in(scene, baking.bake_if_needed(settings.atmosphere_params(scene.ols).validate(), "draft"),
                       preview=True)
        draft.append(time.perf_counter() - start)
    mean_analytic, mean_draft = sum(analytic) / len(analytic), sum(draft) / len(draft)
    print(f"slider change to the analytic groups: {mean_analytic:.3f} s (each {', '.join(f'{t:.3f}' for t in analytic)})")
    print(f"slider change to the draft preview bake swapped in: {mean_draft:.3f} s")
    print(f"ratio analytic / draft: {mean_analytic / mean_draft:.2f}x; goal under {GOAL_PREVIEW_S:g} s: "
          f"{'met' if mean_analytic < GOAL_PREVIEW_S else 'not met'}")
    pkg.unregister()


if __name__ == "__main__":
    main()
