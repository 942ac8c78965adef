"""The scattering passes under EEVEE (in a subprocess: EEVEE aborts the process without EGL).
EEVEE's depth pass holds about the clip end for the sky, not Cycles' 1e10: the sky must still
pass through the aerial perspective untouched, and the light shafts must run without NaN."""
import json
import subprocess
import sys
import textwrap

import pytest

from scenes import egl  # noqa: F401  (fixture: skips without EGL)
from extension import ROOT

pytest.importorskip("bpy")

SCRIPT = textwrap.dedent("""
    import json, os, sys
    sys.path.insert(0, {tests!r})
    os.environ["OLS_CACHE_DIR"] = {cache!r}
    import numpy as np, bpy
    from pathlib import Path
    from conftest import import_extension
    pkg = import_extension(); pkg.register()
    from scenes import compositor_output, depth_image, sample_scene
    from render_util import render_rgb
    out = Path({out!r})
    scene = sample_scene(pkg)
    scene.render.engine = "BLENDER_EEVEE"
    scene.eevee.taa_render_samples = 2
    assert bpy.ops.ols.setup_scene(resolution="draft") == {{"FINISHED"}}
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    tree = scene.compositing_node_group
    tree.nodes["OLS Tone Mapping"].mute = True
    scene.ols.enable_light_shafts = False
    raw = render_rgb(scene, out / "raw.exr")
    aerial = render_rgb(scene, out / "aerial.exr", composite=True)
    scene.ols.enable_light_shafts = True
    scene.ols.num_integration_steps = 8
    shafts = render_rgb(scene, out / "shafts.exr", composite=True)
    compositor_output(scene, depth_image)
    depth = render_rgb(scene, out / "depth.exr", composite=True)[..., 0]
    sky = depth >= 0.95 * scene.camera.data.clip_end
    print("RESULT", json.dumps({{
        "sky_fraction": float(sky.mean()), "sky_max_depth": float(depth[sky].max()),
        "sky_unchanged": float(np.abs(aerial[sky] - raw[sky]).max()),
        "terrain_changed": float(np.abs(aerial[~sky] - raw[~sky]).mean()),
        "finite": bool(np.isfinite(shafts).all()), "shafts_mean": float(shafts.mean())}}))
""")


def test_eevee_sky_passes_through_and_shafts_render(egl, tmp_path):  # noqa: F811
    script = SCRIPT.format(tests=str(ROOT / "tests"), cache=str(tmp_path / "cache"), out=str(tmp_path))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    line = next((l for l in result.stdout.splitlines() if l.startswith("RESULT ")), None)
    assert line is not None, result.stdout[-2000:] + result.stderr[-2000:]
    values = json.loads(line[len("RESULT "):])
    assert 0.1 < values["sky_fraction"] < 0.9 and values["sky_max_depth"] < 1e9      # EEVEE's sky depth
    assert values["sky_unchanged"] < 1e-6 and values["terrain_changed"] > 1e-4
    assert values["finite"] and values["shafts_mean"] > 0
