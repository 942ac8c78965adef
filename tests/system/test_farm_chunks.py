"""Chunked rendering as a farm runs it: frames 1-6 of the sample with Animate Sun, a moving
camera, light adaptation, light shafts and clouds drifting in the wind (a keyframed offset, which
moves the sky's clouds, their shadows and the shafts under them), rendered by scripts/render.py as one job and as three
2-frame chunks, each in its own process with its own empty, read-only cache directory and the
tables packed in the .blend. The frames must be identical (same Cycles seed)."""
import os
import stat
import subprocess
import sys

import numpy as np
import pytest
from extension import ROOT, extension_module, names

bpy = pytest.importorskip("bpy")


def read_exr(path):
    import OpenEXR
    with OpenEXR.File(str(path)) as exr:
        channels = exr.parts[0].channels
        return np.stack([np.asarray(channels[name].pixels) for name in sorted(channels)], axis=-1) \
            if "RGBA" not in channels else np.asarray(channels["RGBA"].pixels)


@pytest.fixture
def packed_animation(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    batch = extension_module("addon.batch")
    packed_tables = extension_module("addon.scene.tables.packed_tables")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    args = batch.parse_args(["--sample", "--tables", "draft", "--resolution", "48x27", "--samples", "1",
                             "--output", str(tmp_path / "x.exr")])
    scene = batch.prepare(args)
    batch.apply_options(scene, args)
    batch.wire(scene, args)
    scene.frame_start, scene.frame_end = 1, 6
    scene.render.fps, scene.render.fps_base = 4, 1.0            # a quarter second a frame: adaptation shows
    settings = scene.ols
    settings.animate_sun = True
    settings.day_start_frame, settings.day_end_frame = 1, 12      # morning: the light grows frame to frame
    settings.light_adaptation = True
    settings.tone_map_exr = True                                 # the adaptation shows in the EXR
    settings.num_integration_steps = 8
    settings.clouds_enabled = True
    settings.cloud_coverage, settings.cloud_base, settings.cloud_scale = 0.5, 600.0, 400.0
    for frame, offset in ((1, (0.0, 0.0)), (6, (900.0, 300.0))):
        settings.cloud_offset = offset
        settings.keyframe_insert("cloud_offset", frame=frame)
    camera = scene.camera
    for frame, shift in ((1, 0.0), (6, 60.0)):
        camera.location.x += shift
        camera.keyframe_insert("location", frame=frame)
    scene.cycles.seed = 5
    packed_tables.pack(scene[names.WIRED_KEY])
    blend = tmp_path / "farm.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    return blend


def render(blend, frames, out, cache):
    cache.mkdir()
    cache.chmod(stat.S_IRUSR | stat.S_IXUSR)                  # empty and read-only: nothing to bake into
    env = {**os.environ, "OLS_CACHE_DIR": str(cache)}
    result = subprocess.run([sys.executable, str(ROOT / "scripts" / "render.py"), "--blend", str(blend),
                             "--frames", frames, "--output", str(out)],
                            capture_output=True, text=True, timeout=900, env=env)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    assert "bake:" not in result.stdout, "a worker baked although the tables are packed"
    return result


def test_chunks_in_separate_processes_equal_one_job(packed_animation, tmp_path):
    render(packed_animation, "1-6", tmp_path / "one" / "f_####.exr", tmp_path / "cache_one")
    for start in (1, 3, 5):
        result = render(packed_animation, f"{start}-{start + 1}", tmp_path / "chunks" / "f_####.exr",
                        tmp_path / f"cache_{start}")
        assert "light adaptation" in result.stdout                      # the chunk adapts
    one = [read_exr(tmp_path / "one" / f"f_{f:04d}.exr") for f in range(1, 7)]
    chunks = [read_exr(tmp_path / "chunks" / f"f_{f:04d}.exr") for f in range(1, 7)]
    for frame, (a, b) in enumerate(zip(one, chunks), start=1):
        assert np.isfinite(a).all() and a.mean() > 1e-3, frame          # a real picture
        assert np.abs(a - b).max() <= 1e-5, (frame, np.abs(a - b).max())
    assert np.abs(one[0] - one[5]).max() > 1e-2                        # the frames move
