"""EXR files of a bake: round trip, atlas layout, atomic writes, clear errors on bad files."""
import json
import os
from pathlib import Path

import numpy as np
import pytest

import lut_gen
from lut_gen import LutError
from lut_gen.tables import atlas
from lut_gen.store import manifest
from lut_gen.store.exr_header import FILES

OpenEXR = pytest.importorskip("OpenEXR")


@pytest.fixture(scope="module")
def small_luts():
    return lut_gen.bake(resolution=(8, 16, 8, 4), orders=2)


@pytest.fixture
def saved(small_luts, tmp_path):
    lut_gen.save(small_luts, tmp_path / "luts")
    return tmp_path / "luts"


def test_round_trip_is_exact(small_luts, saved):
    loaded = lut_gen.load(saved)
    for name in ("single", "higher", "multiple", "optical_depth", "ambient"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(small_luts, name))
    assert loaded.params == small_luts.params and loaded.orders == 2
    # The tables, the bake manifest written after them, the directory lock; no temporaries left.
    assert sorted(p.name for p in saved.iterdir()) == sorted([*FILES.values(), "bake_manifest.json",
                                                              ".ols_bake.lock"])


def test_atlas_layout_matches_the_documented_packing(small_luts, saved):
    with OpenEXR.File(str(saved / FILES["multiple"])) as exr:
        pixels = exr.channels()["RGB"].pixels[::-1]          # EXR rows top-down -> bottom-up
        header = dict(exr.header())
    n_h, n_a, n_s, n_t = small_luts.dims
    assert pixels.shape == (n_h * n_s, n_t * n_a, 3)
    i_h, i_a, i_s, i_t = 5, 11, 3, 2
    np.testing.assert_array_equal(pixels[i_h * n_s + i_s, i_t * n_a + i_a], small_luts.multiple[i_h, i_a, i_s, i_t])
    assert json.loads(header["ols.dims"]) == [n_h, n_a, n_s, n_t]
    assert json.loads(header["ols.params"])["mie_g"] == small_luts.params.mie_g
    np.testing.assert_array_equal(atlas.unpack(atlas.pack(small_luts.single), small_luts.dims), small_luts.single)


def test_files_are_readable_by_others(saved):
    assert (saved / FILES["single"]).stat().st_mode & 0o044


def test_missing_directory_and_file(saved, tmp_path):
    with pytest.raises(LutError, match="not a directory"):
        lut_gen.load(tmp_path / "nope")
    (saved / FILES["ambient"]).unlink()
    with pytest.raises(LutError, match="ambient_skylight.exr is missing"):
        lut_gen.load(saved)


def test_truncated_file(saved):
    path = saved / FILES["single"]
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(LutError, match="single_scattering.exr is damaged"):
        lut_gen.load(saved)
    reseal(saved)               # even with a manifest that vouches for it, OpenEXR refuses it
    with pytest.raises(LutError, match="single_scattering.exr is corrupt or truncated"):
        lut_gen.load(saved)


def reseal(directory):
    """Rewrite the bake manifest over whatever the directory now holds: the checks behind the
    manifest (layout, bake keys, pixel hashes) must still catch a tampered directory."""
    key = json.loads((directory / manifest.MANIFEST).read_text())["bake_key"]
    manifest.write(directory, key, FILES.values())


def test_garbage_file(saved):
    (saved / FILES["optical_depth"]).write_bytes(b"not an exr")
    with pytest.raises(LutError, match="optical_depth.exr"):
        lut_gen.load(saved)


def rewrite(path: Path, change_header=None, change_pixels=None):
    with OpenEXR.File(str(path)) as exr:
        header = dict(exr.header())
        pixels = exr.channels()["RGB"].pixels.copy()
    header = {k: v for k, v in header.items() if k.startswith("ols.")}
    header.update({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage})
    if change_header:
        change_header(header)
    if change_pixels:
        change_pixels(pixels)
    with OpenEXR.File(header, {"RGB": pixels}) as exr:
        exr.write(str(path))


def test_layout_version_mismatch(saved):
    for name in FILES.values():
        rewrite(saved / name, change_header=lambda h: h.update({"ols.layout_version": "0"}))
    reseal(saved)
    with pytest.raises(LutError, match="layout version 0"):
        lut_gen.load(saved)


def test_files_of_different_bakes_are_refused(saved, tmp_path):
    other = lut_gen.bake(lut_gen.AtmosphereParams(aerosol_density=2.0), resolution=(8, 16, 8, 4), orders=2)
    lut_gen.save(other, tmp_path / "other")
    os.replace(tmp_path / "other" / FILES["higher"], saved / FILES["higher"])
    with pytest.raises(LutError, match="higher_order_scattering.exr is damaged or comes from another bake"):
        lut_gen.load(saved)
    reseal(saved)
    with pytest.raises(LutError, match="mixes files of different bakes"):
        lut_gen.load(saved)
    # The add-on verifies with verify_bake (no OpenEXR in Blender): each file's header key too.
    with pytest.raises(LutError, match="higher_order_scattering.exr comes from another bake.*mixes files"):
        lut_gen.store.exr_read.verify_bake(saved)
    assert not lut_gen.store.exr_read.is_intact(saved, json.loads((saved / manifest.MANIFEST).read_text())["bake_key"])


def test_a_hostile_header_is_an_error_not_a_crash(saved):
    """100 000 nested brackets in ols.params gave a RecursionError."""
    for name in FILES.values():
        rewrite(saved / name, change_header=lambda h: h.update({"ols.params": "[" * 100_000}))
    reseal(saved)
    with pytest.raises(LutError, match="invalid header|not a readable EXR file"):
        lut_gen.load(saved)
    with pytest.raises(LutError, match="invalid header|not a readable EXR file"):
        lut_gen.store.exr_header.read_header_params(saved)


def test_damaged_pixels_fail_the_content_hash(saved):
    def damage(pixels):
        pixels[0, 0, 0] += 1.0
    rewrite(saved / FILES["multiple"], change_pixels=damage)
    reseal(saved)
    with pytest.raises(LutError, match="content hash"):
        lut_gen.load(saved)


def test_expected_params_mismatch(saved):
    with pytest.raises(LutError, match="aerosol_density"):
        lut_gen.load(saved, params=lut_gen.AtmosphereParams(aerosol_density=3.0))
    assert lut_gen.load(saved, params=lut_gen.AtmosphereParams()).dims == (8, 16, 8, 4)


def test_save_refuses_to_replace_a_different_bake(saved):
    before = {p.name: p.read_bytes() for p in saved.iterdir()}
    other = lut_gen.bake(lut_gen.AtmosphereParams(aerosol_absorption=0.3), resolution=(8, 16, 8, 4), orders=2)
    with pytest.raises(LutError, match="holds a different bake"):
        lut_gen.save(other, saved)
    assert {p.name: p.read_bytes() for p in saved.iterdir()} == before
    lut_gen.save(other, saved, overwrite=True)
    assert lut_gen.load(saved).params.aerosol_absorption == 0.3


def test_unwritable_output(small_luts, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(LutError, match="cannot create output directory"):
        lut_gen.save(small_luts, blocker / "luts")


def test_cached_bake_hits_the_second_time(tmp_path):
    luts, directory, hit = lut_gen.cached_bake(resolution=(8, 16, 8, 4), orders=2, directory=tmp_path / "c")
    assert not hit
    again, _, hit = lut_gen.cached_bake(resolution=(8, 16, 8, 4), orders=2, directory=tmp_path / "c")
    assert hit
    np.testing.assert_array_equal(again.multiple, luts.multiple)


def test_builtin_writer_and_header_reader_agree_with_openexr(small_luts, tmp_path, monkeypatch):
    """Inside Blender there is no OpenEXR package: lut_gen writes uncompressed EXRs itself.
    OpenEXR must read them bit-exactly, and the pure header reader must match OpenEXR's."""
    from lut_gen.store import exr_min, exr_write
    monkeypatch.setattr(exr_write, "_openexr_or_none", lambda: None)
    lut_gen.save(small_luts, tmp_path / "plain")
    monkeypatch.undo()
    loaded = lut_gen.load(tmp_path / "plain")                 # pixels read by OpenEXR
    np.testing.assert_array_equal(loaded.multiple, small_luts.multiple)
    np.testing.assert_array_equal(loaded.optical_depth, small_luts.optical_depth)
    lut_gen.save(small_luts, tmp_path / "zip")
    for name in FILES.values():
        with OpenEXR.File(str(tmp_path / "zip" / name)) as exr:
            want = {k: v for k, v in dict(exr.header()).items() if k.startswith("ols.")}
        for folder in ("zip", "plain"):
            got = exr_min.read_string_attributes(tmp_path / folder / name)
            assert {k: v for k, v in got.items() if k.startswith("ols.")} == want


def _previous_layout(small_luts, directory, monkeypatch):
    """A bake as baker version 6 wrote it (before fog: the six files, no fog tables, its key)."""
    with monkeypatch.context() as patch:
        patch.setattr(lut_gen.store.exr_header, "BAKER_VERSION", 6)
        lut_gen.save(small_luts, directory)
    assert not any(directory.glob("*fog*"))
    return {p.name: p.read_bytes() for p in directory.iterdir()}


def test_a_bake_of_the_previous_layout_is_refused_clearly_and_kept(small_luts, tmp_path, monkeypatch):
    old = tmp_path / "old"
    before = _previous_layout(small_luts, old, monkeypatch)
    with pytest.raises(LutError, match=r"baker version 6 \(the layout before fog: no fog tables\); this version "
                                       rf"reads baker {lut_gen.store.exr_header.BAKER_VERSION}: re-bake it"):
        lut_gen.load(old)
    fog = lut_gen.bake(lut_gen.AtmosphereParams(fog_visibility=1000.0), resolution=(8, 16, 8, 4), orders=2)
    with pytest.raises(LutError, match="baker version 6 .*pass --overwrite to replace them"):
        lut_gen.save(fog, old)
    assert {p.name: p.read_bytes() for p in old.iterdir()} == before
    # The cache never hits it (its key names baker 6) and never writes into it.
    with pytest.raises(LutError, match="baker version 6"):
        lut_gen.cached_bake(fog.params, resolution=(8, 16, 8, 4), orders=2, directory=old)
    assert {p.name: p.read_bytes() for p in old.iterdir()} == before
    lut_gen.save(fog, old, overwrite=True)
    assert lut_gen.load(old).single_fog is not None
