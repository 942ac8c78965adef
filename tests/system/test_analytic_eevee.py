"""EEVEE renders of the analytic model's "OLS Sky" (Atmosphere Model > Analytic) vs its numpy
twin, lut_gen.model.analytic.sky_parts. The render runs in a subprocess (EEVEE aborts the process
without EGL) and the test skips with the reason where the probe fails."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from extension import ROOT
from scenes import egl  # noqa: F401  (fixture: skips without EGL)
from test_eevee import HEIGHT, LENS, PITCH, RENDER_SCRIPT, SENSOR, WIDTH, camera_directions

pytest.importorskip("bpy")
OpenEXR = pytest.importorskip("OpenEXR")

# test_eevee's script, set up under the analytic model: no tables (luts None).
WIRE = "wiring.wire_scene(scene, args[\"luts\"], [], sun)"
ANALYTIC_SCRIPT = RENDER_SCRIPT.replace(WIRE, "scene.ols.atmosphere_model = 'ANALYTIC'\n" + WIRE)


@pytest.mark.parametrize("elevation", [25.0, 4.0])
def test_eevee_analytic_sky_matches_its_twin(egl, tmp_path, elevation):  # noqa: F811
    import lut_gen
    from lut_gen.model import analytic
    assert WIRE in RENDER_SCRIPT
    out = tmp_path / "eevee.exr"
    args = dict(width=WIDTH, height=HEIGHT, lens=LENS, sensor=SENSOR, pitch=PITCH, elevation=elevation,
                azimuth=20.0, luts=None, out=str(out))
    script = ANALYTIC_SCRIPT.format(scripts=str(ROOT / "scripts"), args=json.dumps(args))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    with OpenEXR.File(str(out)) as exr:
        channels = exr.channels()
        rendered = np.asarray((channels.get("RGBA") or channels["RGB"]).pixels[..., :3], dtype=np.float64)

    el, az = math.radians(elevation), math.radians(20.0)
    sun = np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])
    d = camera_directions()
    air, ground = analytic.sky_parts(analytic.media(lut_gen.AtmosphereParams()), 2.0, d, sun)
    twin = ((air * 0.5 + ground) * 10.0).mean(axis=2)
    disc = (d @ sun > math.cos(math.radians(2.0))).any(axis=2)
    # pixels the horizon crosses mix sky and ground: EEVEE's jittered samples and the twin's 4 x 4
    # grid split them differently
    horizon = (d[..., 2] < 0).any(axis=2) & (d[..., 2] > 0).any(axis=2)
    err = (np.abs(rendered - twin) / np.maximum(twin, 1e-9))[~disc & ~horizon]
    print(f"analytic sky in EEVEE, sun {elevation} deg: median {np.median(err):.2e}, p99 {np.percentile(err, 99):.2e}")
    assert rendered.mean() > 0.01 and np.isfinite(rendered).all()
    assert np.median(err) <= 0.02
