"""Light-shaft pass benchmark (Cycles CPU): the sample scene at 1280 x 720, 16 samples.

Epipolar sampling: the same pass with the epipolar technique, as a ratio of what the
brute-force pass adds (goal <= 1/4, stretch 1/8).

Goal: the scattering pass with light shafts at 32 steps adds <= 50% to a 16-sample
Cycles render of the sample (defaults otherwise: single LUT, multiple UNOCCLUDED, 6 cascades,
shadow map 1024).

Full renders (best of --repeat): render only (compositing off), render + aerial perspective +
tone mapping (light shafts off), render + the passes with light shafts at --steps.

Compositor only: the frame is rendered once and saved as a multilayer EXR; the compositor's
Render Layers nodes are muted and their links moved to an Image node reading that EXR. With no
live Render Layers node Blender skips the Cycles render and runs only the handlers (render_pre:
the shadow maps) and the compositor, so each configuration is timed without re-rendering:
the pipeline with our groups muted, aerial perspective + tone mapping, light shafts at 8, 16 and
--steps steps (the per-step cost is the slope), optionally the INTEGRATION single-scattering
mode and the shafts without PCF (one shadow-map tap per step instead of five). The add-on's
per-frame cache of the shadow maps is cleared before each timed render, so every number pays
for the shadow maps as an animation frame would; they are also timed alone.

    .venv/bin/python bench/bench_light_shafts.py [--resolution 1280x720] [--samples 16] [--steps 32]
        [--repeat 2] [--no-extras]
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
sys.path.insert(0, str(ROOT / "bench"))

SHAFTS_NODE = "OLS Light Shafts"        # addon.scene.names.SHAFTS_NODE (a bench may run an older checkout)
GROUP_NODES = ("OLS Aerial Perspective", "OLS Light Shafts", "OLS Tone Mapping")


class HandlerErrors:
    """Blender prints exceptions raised in app handlers through sys.excepthook and carries on
    (the frame renders without the pass): record them so a broken pass fails the benchmark
    instead of timing a pass-through."""

    def __init__(self):
        self.errors = []
        self._previous = sys.excepthook
        sys.excepthook = self._hook

    def _hook(self, kind, value, tb):
        self.errors.append(f"{kind.__name__}: {value}")
        self._previous(kind, value, tb)

    def check(self, what):
        if self.errors:
            errors, self.errors = self.errors, []
            raise RuntimeError(f"{what}: a handler raised {errors[-1]} (the add-on may be mid-edit)")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--resolution", default="1280x720")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--steps", type=int, default=32, help="light-shaft integration steps (the goal's 32)")
    parser.add_argument("--repeat", type=int, default=2, help="runs per configuration; the best counts")
    parser.add_argument("--no-extras", action="store_true",
                        help="skip the INTEGRATION-mode and no-PCF compositor runs")
    args = parser.parse_args()
    os.environ.setdefault("OLS_CACHE_DIR", str(Path(tempfile.gettempdir()) / "ols_bench_cache"))
    import render as launcher
    import saved_render
    package = launcher.import_extension()
    import bpy

    def module(*names):
        """The first of ``names`` (this layout's path, then older ones) that imports."""
        for name in names:
            try:
                return importlib.import_module(f"{package.__name__}.addon.{name}")
            except ImportError:
                pass
        return None

    batch = module("batch")
    compositor = module("scene.setup.compositor", "scene.compositor")
    shadow_maps = module("scene.frame.shadow_maps", "scene.shadow_maps")
    wiring = module("scene.setup.wiring", "scene.wiring")
    frame_update = module("scene.frame.frame_update", "scene.frame_update")
    frame_state = module("scene.frame.frame_state")
    errors = HandlerErrors()

    options = batch.parse_args(["--sample", "--output", "unused.png", "--resolution", args.resolution,
                                "--samples", str(args.samples), "--sun-elevation", "15", "--sun-azimuth", "35"])
    scene = batch.prepare(options)
    batch.apply_options(scene, options)
    assert bpy.ops.ols.setup_scene() == {"FINISHED"}
    errors.check("setup")
    tree = scene.compositing_node_group
    settings = scene.ols

    def configure(shafts=True, steps=args.steps, single="LUT", smooth=True, technique="BRUTE_FORCE"):
        if hasattr(settings, "scattering_technique"):
            settings.scattering_technique = technique
        settings.enable_light_shafts = shafts
        settings.num_integration_steps = steps
        settings.single_scattering_mode = single
        settings.smooth_shadows = smooth
        wiring.match_light_shaft_layout(scene)      # rebuild now, not inside the timed render
        compositor.sync_settings(scene)             # (un)mutes the shaft node
        node = tree.nodes.get(SHAFTS_NODE)
        if shafts and (node is None or node.mute):
            raise RuntimeError("the light-shaft node is missing or muted after configuring")

    def invalidate():
        """Make the next render redo the per-frame work (shadow maps), as a new frame would."""
        forget = getattr(frame_update, "forget", None)
        if forget is not None:
            forget()

    def timed_render(label, check_shafts=False, runs=None):
        best = 1e9
        for _ in range(runs or args.repeat):
            invalidate()
            start = time.perf_counter()
            bpy.ops.render.render(write_still=False)
            best = min(best, time.perf_counter() - start)
            errors.check(label)
            node = tree.nodes.get(SHAFTS_NODE)
            if check_shafts and (node is None or node.mute):
                raise RuntimeError(f"{label}: the add-on switched the light shafts off during the render")
        print(f"    {label}: {best:.2f} s", flush=True)
        return best

    rows = []               # (section, label, seconds)
    total = time.perf_counter()
    configure(shafts=True)                                      # build the goal's layout up front
    # Warm-up (Cycles loads its kernels and builds the scene the first time): a tiny render.
    samples, percentage = scene.cycles.samples, scene.render.resolution_percentage
    scene.cycles.samples, scene.render.resolution_percentage = 1, 10
    bpy.ops.render.render(write_still=False)
    errors.check("warm-up render")
    scene.cycles.samples, scene.render.resolution_percentage = samples, percentage
    print("full renders ...", flush=True)
    # Shafts off for the plain render too: the add-on's render_pre renders the shadow maps for an
    # unmuted shaft node even when compositing is off.
    configure(shafts=False)
    scene.render.use_compositing = False
    render_only = timed_render("render only")
    rows.append(("full", "render only (compositing off)", render_only))
    scene.render.use_compositing = True
    # One run: informational (the compositor-only rows measure the same pass without Cycles' noise).
    rows.append(("full", "render + aerial + tone (no shafts), 1 run",
                 timed_render("render + aerial + tone", runs=1)))
    configure(shafts=True)
    full_shafts = timed_render(f"render + shafts {args.steps}", check_shafts=True)
    rows.append(("full", f"render + aerial + shafts {args.steps} + tone", full_shafts))

    # -- shadow maps alone ------------------------------------------------------------------
    depsgraph = bpy.context.evaluated_depsgraph_get()
    shadow_seconds = render_seconds = 1e9
    for _ in range(3):
        start = time.perf_counter()
        state = frame_state.read(scene, depsgraph) if frame_state else scene    # older layouts took the scene
        cascades = shadow_maps.render(state, depsgraph)
        middle = time.perf_counter()
        shadow_maps.write_images(cascades)
        end = time.perf_counter()
        shadow_seconds, render_seconds = min(shadow_seconds, end - start), min(render_seconds, middle - start)

    # -- compositor only --------------------------------------------------------------------
    print("compositor only ...", flush=True)
    saved = saved_render.save(scene)
    errors.check("reference render")

    def use_saved_render():
        saved_render.use(scene, saved)

    def compositor_only(label, runs=None, **config):
        configure(**config)
        use_saved_render()          # again: a layout rebuild relinks the shafts to Render Layers
        seconds = timed_render(label, check_shafts=config.get("shafts", True), runs=runs)
        rows.append(("comp", label, seconds))
        return seconds

    configure(shafts=False)
    use_saved_render()
    muted = {name: tree.nodes[name].mute for name in GROUP_NODES if name in tree.nodes}
    for name in muted:
        tree.nodes[name].mute = True
    empty = timed_render("pipeline")
    rows.append(("comp", "pipeline (our groups muted)", empty))
    for name, state in muted.items():
        tree.nodes[name].mute = state
    aerial = compositor_only("aerial + tone", shafts=False)
    step_counts = sorted({8, 16, args.steps})
    per_steps = {n: compositor_only(f"aerial + shafts {n} + tone", steps=n) for n in step_counts}
    epipolar = compositor_only(f"aerial + shafts {args.steps} EPIPOLAR + tone", technique="EPIPOLAR_SAMPLING")
    if not args.no_extras:
        compositor_only(f"shafts {args.steps}, single INTEGRATION, 1 run", runs=1, single="INTEGRATION")
        compositor_only(f"shafts {args.steps}, no PCF (1 tap), 1 run", runs=1, smooth=False)
    configure(shafts=True)

    # -- report -----------------------------------------------------------------------------
    threads = scene.render.threads if scene.render.threads_mode == "FIXED" else os.cpu_count()
    print()
    print(f"Cycles {scene.cycles.device}, {os.cpu_count()} cores ({threads} threads), {args.resolution}, "
          f"{args.samples} samples, light shafts {args.steps} steps, {settings.num_cascades} cascades, "
          f"shadow map {settings.shadow_map_resolution}, single {settings.single_scattering_mode}, "
          f"multiple {settings.multiple_scattering_mode} (best of {args.repeat}; total {time.perf_counter() - total:.0f} s)")
    print(f"  {'full render':<46} {'seconds':>8}  {'vs render only':>14}")
    for section, label, seconds in rows:
        if section == "full":
            print(f"  {label:<46} {seconds:8.2f}  {seconds / render_only:13.2f}x")
    print(f"  {'compositor only (Cycles skipped)':<46} {'seconds':>8}  {'vs render only':>14}")
    for section, label, seconds in rows:
        if section == "comp":
            print(f"  {label:<46} {seconds:8.2f}  {seconds / render_only:13.2f}x")
    print(f"  {'shadow maps alone (render + write_images)':<46} {shadow_seconds:8.2f}  "
          f"{shadow_seconds / render_only:13.2f}x   (rasterising {render_seconds:.2f} s)")
    # The compositing time is measured directly (compositor only, shadow maps included); the
    # difference of two full renders says the same thing with Cycles' run-to-run noise on top.
    added = per_steps[args.steps] - empty
    full_added = full_shafts - render_only
    print(f"pass alone: {added:.2f} s = {100 * added / render_only:.0f}% of the render (goal <= 50%)"
          f"   [full renders' difference: {full_added:.2f} s = {100 * full_added / render_only:.0f}%]")
    epipolar_added = epipolar - empty
    print(f"epipolar sampling: {epipolar_added:.2f} s = {epipolar_added / max(added, 1e-9):.2f}x of brute force "
          f"(goal <= 0.25, stretch 0.125); {100 * epipolar_added / render_only:.0f}% of the render")
    xs = list(per_steps)
    mean_x, mean_y = sum(xs) / len(xs), sum(per_steps.values()) / len(xs)
    slope = (sum((x - mean_x) * (per_steps[x] - mean_y) for x in xs)
             / max(sum((x - mean_x) ** 2 for x in xs), 1e-9))
    fixed = per_steps[xs[0]] - slope * xs[0] - aerial
    print(f"per step: {slope:.3f} s at {args.resolution} (fit over {', '.join(map(str, xs))} steps; "
          f"shafts fixed cost {fixed:.2f} s incl. shadow maps)")


if __name__ == "__main__":
    main()
