"""Controls set from Python to anything (issue 9, item 4 and the fuzz bar): NaN, infinities,
ID-property writes past a control's range, random combinations with random sun angles. The
composite stays finite and non-negative and no traceback escapes."""
import os
import time
from importlib import import_module

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from render_util import render_rgb  # noqa: E402

pytestmark = pytest.mark.bpy

# The issue asks for 200 combinations in under 3 minutes; that is still out of reach. On 2
# cores all 200 took 438 s (2026-12-01; 795 s before): with the shafts off a combination costs
# 0.3 s; with them on 1-3 s (shadow maps, the epipolar tables, group rebuilds when modes,
# cascades, PCF or the technique change); 4096-texel shadow maps 5-15 s; the largest epipolar
# tables (up to 16.7 M values) 15-22 s of numpy marching. CI runs 24;
# OLS_FUZZ_COMBINATIONS=200 runs the whole set.
FUZZ_COMBINATIONS = int(os.environ.get("OLS_FUZZ_COMBINATIONS", "24"))
WIDTH, HEIGHT = 64, 36


@pytest.fixture(scope="module")
def wired(tmp_path_factory):
    """The sample scene wired to draft tables, 64 x 36, one Cycles sample."""
    from conftest import import_extension
    cache = tmp_path_factory.mktemp("cache")
    previous = os.environ.get("OLS_CACHE_DIR")
    os.environ["OLS_CACHE_DIR"] = str(cache)
    pkg = import_extension()
    pkg.register()
    batch = import_module(pkg.__name__ + ".addon.batch")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    args = batch.parse_args(["--sample", "--tables", "draft", "--resolution", f"{WIDTH}x{HEIGHT}",
                             "--samples", "1", "--output", str(cache / "x.png")])
    scene = batch.prepare(args)
    batch.apply_options(scene, args)
    ops = import_module(pkg.__name__ + ".addon.ops")
    wiring = import_module(pkg.__name__ + ".addon.scene.wiring")
    directory = ops.bake_if_needed(pkg.lut_gen.AtmosphereParams(), "draft")
    wiring.wire_scene(scene, directory, [o for o in scene.objects if o.select_get()], resolution="draft")
    scene.cycles.samples = 1
    scene.render.use_persistent_data = True        # the terrain's BVH is built once, not per render
    yield pkg, scene, tmp_path_factory.mktemp("renders")
    pkg.unregister()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if previous is None:
        del os.environ["OLS_CACHE_DIR"]
    else:
        os.environ["OLS_CACHE_DIR"] = previous


def numeric_controls(settings):
    return [p for p in settings.bl_rna.properties
            if p.type in {"FLOAT", "INT"} and not getattr(p, "array_length", 0) and not p.is_readonly]


def check_composite(scene, path, what):
    scene.ols.tone_map_exr = True            # the tone mapping's controls reach the EXR too
    rgb = render_rgb(scene, path, composite=True)
    assert rgb.shape == (HEIGHT, WIDTH, 3)
    assert np.isfinite(rgb).all(), what
    assert (rgb >= 0).all(), what
    return rgb


def reset(settings):
    for prop in settings.bl_rna.properties:
        if prop.identifier != "rna_type" and not prop.is_readonly:
            settings.property_unset(prop.identifier)


def test_nan_and_out_of_range_controls_give_a_finite_composite(wired, capfd):
    pkg, scene, renders = wired
    settings = scene.ols
    reset(settings)
    good = check_composite(scene, renders / "good.exr", "defaults")
    assert good.mean() > 0.05                                    # a real picture, not black
    for prop in numeric_controls(settings):
        if prop.type == "FLOAT":
            setattr(settings, prop.identifier, float("nan"))
    nan = check_composite(scene, renders / "nan.exr", "every float control NaN")
    # NaN reads as each control's default: the same picture (the frame values are recomputed).
    assert np.abs(nan - good).max() <= 1e-3 * max(good.max(), 1.0)
    for prop in numeric_controls(settings):                      # past the range, bypassing RNA
        settings[prop.identifier] = 10 ** 9 if prop.type == "INT" else 1e30
    check_composite(scene, renders / "huge.exr", "every numeric control 1e30 / 1e9")
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-3000:]
    reset(settings)


def test_fuzz_random_controls_and_sun_angles(wired, capfd):
    """FUZZ_COMBINATIONS random combinations (fixed seed): each control drawn from its range,
    its extremes, NaN or far past its range; enums and booleans at random; the sun anywhere."""
    pkg, scene, renders = wired
    settings = scene.ols
    sun_lamps = import_module(pkg.__name__ + ".addon.scene.sun")
    sun = sun_lamps.find_sun(scene)
    rng = np.random.default_rng(20261130)
    props = [p for p in settings.bl_rna.properties if p.identifier not in {"rna_type", "control_set"}
             and not p.is_readonly and not getattr(p, "array_length", 0)]
    start = time.perf_counter()
    for combination in range(FUZZ_COMBINATIONS):
        reset(settings)
        for prop in props:
            if rng.random() < 0.5:
                continue
            name = prop.identifier
            if prop.type == "BOOLEAN":
                setattr(settings, name, bool(rng.integers(2)))
            elif prop.type == "ENUM":
                setattr(settings, name, str(rng.choice([item.identifier for item in prop.enum_items])))
            elif prop.type in {"FLOAT", "INT"}:
                lo, hi = prop.hard_min, prop.hard_max
                pick = rng.integers(5)
                if pick == 0:
                    value = lo
                elif pick == 1:
                    value = hi
                elif pick == 2 and prop.type == "FLOAT":
                    value = float("nan")
                elif pick == 3:
                    sign = int(rng.choice([-1, 1]))
                    settings[name] = sign * 1e30 if prop.type == "FLOAT" else sign * 10 ** 9   # an ID-property write
                    continue
                else:
                    soft_lo, soft_hi = prop.soft_min, prop.soft_max
                    value = rng.uniform(soft_lo, soft_hi)
                setattr(settings, name, int(round(value)) if prop.type == "INT" else float(value))
        elevation, azimuth = rng.uniform(-10, 90), rng.uniform(-180, 180)
        sun_lamps.set_sun_angles(sun, elevation, azimuth)
        check_composite(scene, renders / f"fuzz_{combination}.exr",
                        f"combination {combination}: sun {elevation:.1f}/{azimuth:.1f}, "
                        f"{ {p.identifier: getattr(settings, p.identifier) for p in props} }")
    print(f"\n{FUZZ_COMBINATIONS} combinations in {time.perf_counter() - start:.1f} s")
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-3000:]
    reset(settings)
