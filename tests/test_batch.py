"""Headless rendering (addon/batch.py via scripts/render.py): options, and one-line errors with
exit status 1 for bad input."""
import subprocess
import sys
from importlib import import_module
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def batch(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    return import_module(addon_package.__name__ + ".addon.batch")


def error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert err and err[-1].startswith("error: ")
    return err[-1]


def test_missing_blend(batch, tmp_path, capsys):
    assert batch.main(["--blend", str(tmp_path / "nope.blend"), "--output", str(tmp_path / "o.png")]) == 1
    assert "does not exist" in error_line(capsys)


def test_no_camera_and_no_sun(batch, tmp_path, capsys):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    blend = tmp_path / "empty.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    assert batch.main(["--blend", str(blend), "--output", str(tmp_path / "o.png")]) == 1
    assert "no camera" in error_line(capsys)
    camera = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    assert batch.main(["--blend", str(blend), "--output", str(tmp_path / "o.png")]) == 1
    assert "no Sun lamp" in error_line(capsys)


def test_eevee_without_egl_is_reported(batch, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(batch, "egl_available", lambda: False)
    assert batch.main(["--sample", "--engine", "EEVEE", "--output", str(tmp_path / "o.png")]) == 1
    assert "EEVEE needs EGL" in error_line(capsys)


def test_damaged_tables_are_reported(batch, tmp_path, capsys, addon_package):
    ops = import_module(addon_package.__name__ + ".addon.ops")
    directory = ops.bake_if_needed(addon_package.lut_gen.AtmosphereParams(), "draft")
    path = directory / "multiple_scattering.exr"
    path.write_bytes(path.read_bytes()[:4096])          # header intact, pixels cut off
    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert batch.main(["--sample", "--tables", "draft", "--output", str(tmp_path / "o.png")]) == 1
    line = error_line(capsys)
    assert "multiple_scattering.exr" in line and ("damaged" in line or "cannot be read" in line)


def test_unwritable_output(batch, tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert batch.main(["--sample", "--tables", "draft", "--output", str(tmp_path / "file" / "o.png")]) == 1
    assert "cannot write" in error_line(capsys)


def test_frames_follow_the_animated_sun(batch, tmp_path, addon_package):
    assert batch.main(["--sample", "--tables", "draft", "--resolution", "32x18", "--samples", "1",
                       "--frames", "1-2", "--output", str(tmp_path / "frame_####")]) == 0
    assert sorted(p.name for p in tmp_path.glob("frame_*.png")) == ["frame_0001.png", "frame_0002.png"]
    scene = bpy.context.scene
    scene.ols.animate_sun = True
    scene.frame_start, scene.frame_end = 1, 100
    sun = bpy.data.objects["OLS Sun"]
    directions = []
    for frame in (10, 50, 90):
        scene.frame_set(frame)
        directions.append(np.array(sun.matrix_world.col[2][:3]))
    assert directions[1][2] > directions[0][2] and directions[0][0] * directions[2][0] < 0   # rises, crosses
    scene.frame_set(50)
    noon = np.array(sun.data.color)
    scene.frame_set(10)
    morning = np.array(sun.data.color)
    assert morning[2] / morning[0] < noon[2] / noon[0]     # the low morning sun is redder


def test_script_entry_point_runs(tmp_path):
    out = tmp_path / "s.png"
    env = {"OLS_CACHE_DIR": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin"}
    result = subprocess.run([sys.executable, str(ROOT / "scripts" / "render.py"), "--sample", "--tables", "draft",
                             "--resolution", "64x36", "--samples", "2", "--output", str(out)],
                            capture_output=True, text=True, timeout=600, env=env)
    assert result.returncode == 0, result.stderr[-2000:]
    assert out.read_bytes().startswith(b"\x89PNG")
