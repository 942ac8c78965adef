"""Bake directories that are damaged, mixed, half-written, foreign or shared: every one is either
repaired or refused with one clear line, and nothing that is not ours is touched."""
import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import lut_gen
from lut_gen.store import cache, exr_read, exr_write, manifest
from lut_gen.store.exr_header import FILES, LutError
from extension import ROOT

SMALL = dict(resolution=(8, 16, 8, 4), orders=2)


def bake_into(directory, **params):
    return cache.bake_into(lut_gen.AtmosphereParams(**params), directory=directory, **SMALL)


@pytest.fixture
def baked(tmp_path):
    directory, luts = bake_into(tmp_path / "l")
    assert luts is not None
    return directory


def snapshot(directory):
    return {p.name: p.read_bytes() for p in Path(directory).iterdir() if p.is_file()}


def test_a_fresh_bake_verifies_and_is_a_hit(baked):
    key = exr_read.verify_bake(baked)
    assert json.loads((baked / manifest.MANIFEST).read_text())["bake_key"] == key
    assert bake_into(baked)[1] is None                      # hit: nothing baked


@pytest.mark.parametrize("damage", ["truncate", "flip a bit", "empty", "delete"])
@pytest.mark.parametrize("table", ["optical_depth", "single_mie", "multiple"])
def test_a_damaged_file_is_named_and_then_repaired(baked, table, damage):
    key = exr_read.verify_bake(baked)
    path = baked / FILES[table]
    data = bytearray(path.read_bytes())
    if damage == "truncate":
        path.write_bytes(data[:len(data) // 3])
    elif damage == "flip a bit":
        data[len(data) * 2 // 3] ^= 0x10
        path.write_bytes(bytes(data))
    elif damage == "empty":
        path.write_bytes(b"")
    else:
        path.unlink()
    with pytest.raises(LutError, match=FILES[table]):
        lut_gen.load(baked)
    assert not exr_read.is_intact(baked, key)
    # Not a cache hit: the same bake is made again, in place, and then verifies.
    directory, luts = bake_into(baked)
    assert luts is not None and directory == baked
    lut_gen.load(baked)


def test_a_table_copied_from_another_bake_is_refused(tmp_path, baked):
    other, _ = bake_into(tmp_path / "other", aerosol_density=2.0)
    for table in ("single", "higher"):
        (baked / FILES[table]).write_bytes((other / FILES[table]).read_bytes())
    with pytest.raises(LutError, match="single_scattering.exr|higher_order_scattering.exr"):
        lut_gen.load(baked)
    # Swapping two tables of one bake is caught as well.
    good, _ = bake_into(tmp_path / "swap")
    single, higher = (good / FILES["single"]).read_bytes(), (good / FILES["higher"]).read_bytes()
    (good / FILES["single"]).write_bytes(higher)
    (good / FILES["higher"]).write_bytes(single)
    with pytest.raises(LutError, match="damaged or comes from another bake"):
        exr_read.verify_bake(good)


def test_a_bake_killed_between_renames_is_not_a_bake(baked, monkeypatch):
    """save withdraws the manifest before its first rename and writes it after its last."""
    real_replace, calls = os.replace, []

    def dying_replace(src, dst):
        calls.append(dst)
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        return real_replace(src, dst)

    luts = lut_gen.bake(lut_gen.AtmosphereParams(aerosol_density=3.0), **SMALL)
    monkeypatch.setattr(os, "replace", dying_replace)
    with pytest.raises(LutError, match="No space left"):
        exr_write.save(luts, baked, overwrite=True)
    monkeypatch.setattr(os, "replace", real_replace)
    assert not (baked / manifest.MANIFEST).exists()
    with pytest.raises(LutError, match="no bake manifest"):
        lut_gen.load(baked)
    assert not list(baked.glob(".*.tmp"))                     # its temporary files are gone


def test_a_full_disk_while_writing_keeps_the_old_bake(baked, monkeypatch, capsys):
    """A full disk while the new tables are written (OpenEXR raises a bare
    RuntimeError) is one error line and exit 1 from the CLI; the old bake is left as it was,
    byte for byte, and still verifies; no temporary file stays."""
    from lut_gen import cli
    before = snapshot(baked)
    real_write, calls = exr_write._write_rgb, []

    def filling_disk(OpenEXR, path, pixels, strings):
        calls.append(path)
        if len(calls) == 2:                       # the second table no longer fits
            Path(path).write_bytes(b"\0" * 100)
            raise RuntimeError(f"Error writing {path}: No space left on device")
        return real_write(OpenEXR, path, pixels, strings)

    monkeypatch.setattr(exr_write, "_write_rgb", filling_disk)
    assert cli.main(["bake", "--out", str(baked), "--resolution", "8x16x8x4", "--orders", "2", "--quiet",
                     "--aerosol-density", "3", "--overwrite"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "No space left on device" in err[0], err
    assert snapshot(baked) == before
    exr_read.verify_bake(baked)
    assert not list(baked.glob(".*.tmp"))


def test_saving_a_bake_over_an_intact_copy_of_itself_rewrites_nothing(baked):
    """Farm workers sharing a cold cache each bake the same tables: the one that saves last must
    not rewrite (and so withdraw the manifest of) a folder another worker renders from."""
    stamps = {p.name: p.stat().st_mtime_ns for p in baked.iterdir()}
    luts = lut_gen.bake(lut_gen.AtmosphereParams(), **SMALL)
    exr_write.save(luts, baked, overwrite=True)
    assert {p.name: p.stat().st_mtime_ns for p in baked.iterdir()} == stamps
    exr_read.verify_bake(baked)


def test_stale_temporaries_of_a_killed_bake_are_removed(baked):
    stale = baked / f".{FILES['single']}.abc123.tmp"
    stale.write_bytes(b"half a table")
    foreign = baked / ".my_notes.tmp"
    foreign.write_bytes(b"mine")
    luts = lut_gen.bake(lut_gen.AtmosphereParams(aerosol_density=3.0), **SMALL)
    exr_write.save(luts, baked, overwrite=True)
    assert not stale.exists() and foreign.read_bytes() == b"mine"


def test_a_users_file_named_like_a_table_is_never_replaced(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    mine = out / FILES["single"]
    mine.write_bytes(b"my own render, not a table")
    for overwrite in (False, True):
        with pytest.raises(LutError, match="was not written by lut_gen"):
            exr_write.save(lut_gen.bake(**SMALL), out, overwrite=overwrite)
    assert mine.read_bytes() == b"my own render, not a table"
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [FILES["single"]]


def test_a_failed_bake_leaves_no_directory(tmp_path, monkeypatch):
    out = tmp_path / "new" / "luts"

    def broken(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(exr_write, "_write_tables", broken)
    with pytest.raises(OSError):
        cache.bake_into(lut_gen.AtmosphereParams(), directory=out, **SMALL)
    assert not out.exists()


def test_concurrent_bakes_into_one_directory_never_mix(tmp_path):
    """Two bakes with different parameters into one folder: one wins whole, the other is told
    which bake is there and fails; the folder verifies as the winner's."""
    out = tmp_path / "shared"
    results = {}

    def run(name, density):
        try:
            cache.bake_into(lut_gen.AtmosphereParams(aerosol_density=density), directory=out, **SMALL)
            results[name] = "ok"
        except LutError as exc:
            results[name] = str(exc)

    threads = [threading.Thread(target=run, args=(n, d)) for n, d in (("a", 1.0), ("b", 2.0))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert list(results.values()).count("ok") == 1
    loser = [v for v in results.values() if v != "ok"]
    assert len(loser) == 1 and "holds a different bake" in loser[0]
    key = exr_read.verify_bake(out)
    assert loser[0].count(key) == 1                           # the message names the winner
    lut_gen.load(out)


def test_a_fifo_named_like_a_table_does_not_hang(baked):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this platform")
    path = baked / FILES["ambient"]
    path.unlink()
    os.mkfifo(path)
    code = ("import lut_gen, sys\n"
            "for step in (lambda: lut_gen.load(sys.argv[1]),\n"
            "             lambda: lut_gen.store.exr_read.verify_bake(sys.argv[1])):\n"
            "    try:\n        step()\n    except lut_gen.LutError as exc:\n        print('refused:', exc)\n")
    result = subprocess.run([sys.executable, "-c", code, str(baked)], capture_output=True, text=True, timeout=60,
                            cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert result.stdout.count("refused:") == 2 and "not a regular file" in result.stdout, result.stderr


@pytest.mark.parametrize("change", [dict(aerosol_density=1e30), dict(earth_radius=1e20),
                                    dict(mie_scattering=(1e-5, 1e-5, 1e308)), dict(aerosol_absorption=1e308),
                                    dict(rayleigh_scattering=(1e308, 1e-5, 1e-5)), dict(ozone_column=float("inf"))])
def test_huge_parameters_are_refused_with_their_range(change):
    with pytest.raises(ValueError, match="must be between"):
        lut_gen.bake(lut_gen.AtmosphereParams(**change), **SMALL)


def test_tables_with_nan_are_refused_on_load(baked, tmp_path):
    """Tables whose numbers went NaN (hand-made, or from another tool) never load, even with a
    manifest and hashes that match them."""
    luts = lut_gen.load(baked)
    luts.higher[0, 0, 0, 0, 1] = np.nan
    luts.multiple[0, 0, 0, 0, 1] = np.nan
    exr_write.save(luts, tmp_path / "nan")
    with pytest.raises(LutError, match="higher table holds non-finite values"):
        lut_gen.load(tmp_path / "nan")
