"""Tables that travel with the .blend: a packed file renders on a worker whose cache
is empty and cannot be written, without baking; an unpacked one re-bakes with one line; damaged
packed tables are named and re-baked; no absolute cache path is saved."""
import json
import os
import shutil
import subprocess
import sys

import pytest

from scenes import sample_scene
from extension import ROOT, extension_module, names

bpy = pytest.importorskip("bpy")


def render_blend(blend, out, cache):
    env = dict(os.environ, OLS_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, str(ROOT / "scripts" / "render.py"), "--blend", str(blend),
                           "--resolution", "32x18", "--samples", "1", "--output", str(out)],
                          capture_output=True, text=True, timeout=600, env=env)


@pytest.fixture
def wired_files(addon_package, tmp_path, monkeypatch):
    """The wired sample saved twice: with packed tables and without."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("OLS_CACHE_DIR", str(cache))
    scene = sample_scene(addon_package)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    plain = tmp_path / "plain.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(plain))
    assert bpy.ops.ols.pack_tables() == {"FINISHED"}
    packed = tmp_path / "packed.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(packed))
    return scene, plain, packed, cache


def test_packed_file_renders_without_a_bake_where_the_cache_cannot_be_written(wired_files, tmp_path):
    scene, plain, packed, cache = wired_files
    for blend in (plain, packed):
        assert str(cache).encode() not in blend.read_bytes(), blend      # no absolute cache path
    shutil.rmtree(cache)                               # another machine: the bake is nowhere on disk
    (tmp_path / "file").write_text("not a folder")
    unwritable = tmp_path / "file" / "cache"           # mkdir fails there, even for root
    result = render_blend(packed, tmp_path / "packed.png", unwritable)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "using the tables packed in the file" in result.stdout
    assert "baking" not in result.stdout + result.stderr
    assert (tmp_path / "packed.png").read_bytes().startswith(b"\x89PNG")

    empty = tmp_path / "empty_cache"
    result = render_blend(plain, tmp_path / "plain.png", empty)
    assert result.returncode == 0, result.stderr[-2000:]
    assert len([line for line in result.stdout.splitlines() if "baking them again" in line]) == 1
    assert (tmp_path / "plain.png").exists()


def test_damaged_packed_table_is_named_and_baked_again(addon_package, wired_files, tmp_path, monkeypatch, capsys):
    scene, _, packed, cache = wired_files
    packed_tables = extension_module("addon.scene.tables.packed_tables")
    luts = extension_module("addon.scene.tables.luts")
    key = scene[names.WIRED_KEY]
    image = bpy.data.images[luts.image_name("multiple", key)]
    doc = json.loads(image[names.PACKED_MANIFEST_KEY])
    doc["files"]["optical_depth.exr"] = "0" * 64              # as if its packed bytes had changed
    image[names.PACKED_MANIFEST_KEY] = json.dumps(doc)
    with pytest.raises(addon_package.lut_gen.LutError, match="packed table optical_depth.exr"):
        packed_tables.restore(key)
    damaged = tmp_path / "damaged.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(damaged))
    shutil.rmtree(cache)
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "fresh_cache"))
    capsys.readouterr()
    bpy.ops.wm.open_mainfile(filepath=str(damaged))
    out = capsys.readouterr().out
    assert "packed table optical_depth.exr" in out and "baking them again" in out
    scene = bpy.context.scene
    luts.verify_wired(scene[names.WIRED_KEY])                # re-baked into the fresh cache
    assert (tmp_path / "fresh_cache").is_dir()


def test_render_script_packs_a_blend(addon_package, wired_files, capsys):
    _, plain, _, _ = wired_files
    batch = extension_module("addon.batch")
    packed_tables = extension_module("addon.scene.tables.packed_tables")
    assert batch.main(["--blend", str(plain), "--pack"]) == 0
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("packed ")
    bpy.ops.wm.open_mainfile(filepath=str(plain))
    assert packed_tables.is_packed(bpy.context.scene[names.WIRED_KEY])
    with pytest.raises(SystemExit):
        batch.parse_args(["--sample", "--pack"])             # --pack needs the .blend to save
