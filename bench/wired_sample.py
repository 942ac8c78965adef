"""The sample scene wired to draft tables at a small size, 1 Cycles sample, for the benches
that time re-renders (bench_rerender, bench_fuzz). ``pkg``: the extension package, registered
(of this checkout or of a baseline's)."""
from importlib import import_module


def wired_sample(pkg, output, width=64, height=36):
    """(scene, terrain objects) of the wired sample rendering to ``output``."""
    import bpy
    batch = import_module(pkg.__name__ + ".addon.batch")
    baking = _first_module(pkg, "addon.baking", "addon.ops")      # the bake service's home, then and now
    wiring = _first_module(pkg, "addon.scene.setup.wiring", "addon.scene.wiring")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    args = batch.parse_args(["--sample", "--tables", "draft", "--resolution", f"{width}x{height}",
                             "--samples", "1", "--output", str(output)])
    scene = batch.prepare(args)
    batch.apply_options(scene, args)
    directory = baking.bake_if_needed(pkg.lut_gen.AtmosphereParams(), "draft")
    terrain = [o for o in scene.objects if o.select_get()]
    wiring.wire_scene(scene, directory, terrain, resolution="draft")
    scene.cycles.samples = 1
    scene.render.use_persistent_data = True     # the terrain's BVH is built once, not per render
    return scene, terrain


def _first_module(pkg, *names):
    """The first of ``names`` that imports: benches run this checkout and older baselines."""
    for name in names[:-1]:
        try:
            return import_module(f"{pkg.__name__}.{name}")
        except ImportError:
            pass
    return import_module(f"{pkg.__name__}.{names[-1]}")
