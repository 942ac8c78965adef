"""python -m lut_gen: bake with progress and cache hits, one-line errors, sample preview."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from extension import ROOT
from lut_gen.store.exr_header import BAKER_VERSION

SMALL = ["--resolution", "8x16x8x4", "--orders", "2"]


def run(*args, env_extra=None):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.update(env_extra or {})
    return subprocess.run([sys.executable, "-m", "lut_gen", *args], capture_output=True, text=True,
                          cwd=ROOT, env=env, timeout=300)


def test_bake_then_cache_hit(tmp_path):
    first = run("bake", "--out", str(tmp_path / "luts"), *SMALL)
    assert first.returncode == 0, first.stderr
    assert "baked" in first.stdout and "single scattering" in first.stderr       # progress shown
    assert len(list((tmp_path / "luts").glob("*.exr"))) == 6
    second = run("bake", "--out", str(tmp_path / "luts"), *SMALL)
    assert second.returncode == 0 and "cache hit" in second.stdout


def test_every_param_has_an_option(tmp_path):
    result = run("bake", "--out", str(tmp_path / "l"), *SMALL, "--aerosol-density", "2",
                 "--aerosol-absorption", "0.3", "--ozone", "--mie-g", "0.7",
                 "--rayleigh-scattering", "6e-6", "1.4e-5", "3.3e-5", "--quiet")
    assert result.returncode == 0, result.stderr
    import lut_gen
    params = lut_gen.load(tmp_path / "l").params
    assert params.ozone and params.aerosol_density == 2 and params.aerosol_absorption == 0.3
    assert params.mie_g == 0.7 and params.rayleigh_scattering == (6e-6, 1.4e-5, 3.3e-5)


@pytest.mark.parametrize("args, message", [
    (["--aerosol-density", "-1"], "aerosol_density must be between 0 and 1000"),
    (["--mie-scale-height", "nan"], "mie_scale_height must be between 1 and 1e+06"),
    (["--ground-albedo", "-0.2"], "ground_albedo must be between 0 and 1"),
    (["--ground-albedo", "nan"], "ground_albedo must be between 0 and 1"),
    (["--ozone-column", "-5"], "ozone_column must be between 0 and 2000"),
    (["--ozone-column", "nan"], "ozone_column must be between 0 and 2000"),
    (["--preset", "sample-2012"], "unknown preset 'sample-2012'; choose one of clear-sky, sample-2013"),
    # Huge finite values: all-NaN tables or negative optical depths before.
    (["--aerosol-density", "1e30"], "aerosol_density must be between 0 and 1000"),
    (["--aerosol-absorption", "1e308"], "aerosol_absorption must be between 0 and 1000"),
    (["--mie-scattering", "1e-5", "1e-5", "1e308"], "mie_scattering.b must be between 0 and 0.01"),
    (["--rayleigh-scattering", "1e308", "1e-5", "1e-5"], "rayleigh_scattering.r must be between 0 and 0.01"),
    (["--ozone-absorption", "1e-6", "1e308", "1e-6"], "ozone_absorption.g must be between 0 and 0.01"),
    (["--earth-radius", "1e20"], "earth_radius must be between 100000 and 1e+08"),
    (["--earth-radius=1e308"], "earth_radius must be between 100000 and 1e+08"),
    (["--aerosol-density", "900", "--aerosol-absorption", "900"], "aerosol extinction"),
])
def test_bad_params_give_one_line_errors(tmp_path, args, message):
    result = run("bake", "--out", str(tmp_path / "l"), *SMALL, *args)
    assert result.returncode == 1
    assert result.stderr.strip().count("\n") == 0 and message in result.stderr
    assert not (tmp_path / "l").exists()


def test_unwritable_out(tmp_path):
    (tmp_path / "file").write_text("x")
    result = run("bake", "--out", str(tmp_path / "file" / "luts"), *SMALL)
    assert result.returncode == 1 and "cannot create output directory" in result.stderr


def test_other_bake_in_out_dir_is_kept(tmp_path):
    assert run("bake", "--out", str(tmp_path / "l"), *SMALL, "--quiet").returncode == 0
    before = {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()}
    result = run("bake", "--out", str(tmp_path / "l"), *SMALL, "--aerosol-density", "3")
    assert result.returncode == 1 and "holds a different bake" in result.stderr
    assert result.stderr.strip().count("\n") == 0
    assert {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()} == before


def test_corrupt_bake_dir_is_reported(tmp_path):
    assert run("bake", "--out", str(tmp_path / "l"), *SMALL, "--quiet").returncode == 0
    path = tmp_path / "l" / "multiple_scattering.exr"
    path.write_bytes(path.read_bytes()[:1000])
    result = run("sample", "--luts", str(tmp_path / "l"), "--out", str(tmp_path / "s.png"), *SMALL, "--quiet")
    # A damaged copy of the same bake is not a cache hit: it is baked again, and said so.
    assert result.returncode == 0 and "baked: " in result.stdout, result.stderr
    import lut_gen
    lut_gen.load(tmp_path / "l")
    # Damage that hides whose bake it was (the manifest gone too) is refused without --overwrite.
    (tmp_path / "l" / "bake_manifest.json").unlink()
    for name in ("multiple_scattering.exr", "single_scattering.exr", "single_mie_scattering.exr", "higher_order_scattering.exr",
                 "optical_depth.exr", "ambient_skylight.exr"):
        (tmp_path / "l" / name).write_bytes((tmp_path / "l" / name).read_bytes()[:1000])
    before = {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()}
    result = run("bake", "--out", str(tmp_path / "l"), *SMALL, "--aerosol-density", "2", "--quiet")
    assert result.returncode == 1 and "--overwrite" in result.stderr
    assert {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()} == before


def test_a_resolution_too_large_for_memory_is_refused_before_baking(tmp_path):
    result = run("bake", "--out", str(tmp_path / "l"), "--resolution", "99998x99998x99998x99998")
    assert result.returncode == 1 and "GiB" in result.stderr and "choose smaller tables" in result.stderr
    assert result.stderr.strip().count("\n") == 0 and not (tmp_path / "l").exists()


def test_bad_resolution_is_a_usage_error(tmp_path):
    result = run("bake", "--out", str(tmp_path / "l"), "--resolution", "huge")
    assert result.returncode == 2 and "resolution must be" in result.stderr


def test_sample_writes_a_sky_preview(tmp_path):
    out = tmp_path / "sample.png"
    result = run("sample", "--out", str(out), "--resolution", "draft", "--quiet",
                 env_extra={"OLS_CACHE_DIR": str(tmp_path / "cache")})
    assert result.returncode == 0, result.stderr
    data = out.read_bytes()
    assert data.startswith(b"\x89PNG")
    import zlib, struct
    width, height = struct.unpack(">II", data[16:24])
    idat = data[data.index(b"IDAT") + 4:data.index(b"IEND") - 8]
    rows = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, 1 + width * 3)[:, 1:]
    rgb = rows.reshape(height, width, 3).astype(int)
    sky = rgb[:100]                                         # the midday panorama
    assert sky.mean() > 60                                  # not black
    assert (sky[..., 2] > sky[..., 0]).mean() > 0.9         # blue sky


def test_sample_preset_bakes_the_samples_media(tmp_path):
    result = run("bake", "--out", str(tmp_path / "l"), *SMALL, "--preset", "sample-2013", "--quiet")
    assert result.returncode == 0, result.stderr
    import lut_gen
    params = lut_gen.load(tmp_path / "l").params
    assert params == lut_gen.preset("sample-2013")
    assert params.mie_scattering == (2e-5, 2e-5, 2e-5) and params.mie_g == 0.76
    assert (not params.spectral and not params.ozone and params.ground_albedo == 0.0)


def test_old_layout_directory_is_refused_and_kept(tmp_path):
    """A directory baked by an older version (layout 1) is named as such; nothing is changed."""
    assert run("bake", "--out", str(tmp_path / "l"), *SMALL, "--quiet").returncode == 0
    from lut_gen.store import exr_header
    path = tmp_path / "l" / exr_header.FILES["multiple"]
    data = path.read_bytes()
    marker = f'{exr_header.PREFIX}layout_version'.encode()
    start = data.index(marker)
    # The attribute's value follows its name, type and size: rewrite "2" as "1" in place.
    value_at = data.index(str(exr_header.LAYOUT_VERSION).encode(), start + len(marker) + 12)
    path.write_bytes(data[:value_at] + b"1" + data[value_at + 1:])
    before = {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()}
    result = run("bake", "--out", str(tmp_path / "l"), *SMALL, "--aerosol-density", "2", "--quiet")
    assert result.returncode == 1
    assert "layout version 1" in result.stderr and "re-bake" in result.stderr
    assert {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()} == before


def test_sample_never_replaces_a_file_it_did_not_write(tmp_path):
    """The default is build/sky_preview.png (not the main command's build/sample.png); a file
    that is not one of its previews is kept, with a message; its own previews are refreshed."""
    env = {"OLS_CACHE_DIR": str(tmp_path / "cache")}
    foreign = tmp_path / "render.png"
    foreign.write_bytes(b"\x89PNG\r\n\x1a\nsomeone else's render")
    result = run("sample", "--out", str(foreign), "--resolution", "draft", "--quiet", env_extra=env)
    assert result.returncode == 1 and "not written by python -m lut_gen sample" in result.stderr
    assert foreign.read_bytes() == b"\x89PNG\r\n\x1a\nsomeone else's render"
    own = tmp_path / "preview.png"
    for _ in range(2):
        result = run("sample", "--out", str(own), "--resolution", "draft", "--quiet", env_extra=env)
        assert result.returncode == 0, result.stderr
    from lut_gen import cli
    assert cli.build_parser().parse_args(["sample"]).out == Path("build/sky_preview.png")


def test_sample_into_another_bakes_folder_says_what_sample_can_do(tmp_path):
    """sample suggested --overwrite, which it does not have, and only after
    the whole bake. Now it refuses before baking, in its own words, and changes nothing."""
    assert run("bake", "--out", str(tmp_path / "l"), *SMALL, "--quiet").returncode == 0
    before = {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()}
    result = run("sample", "--luts", str(tmp_path / "l"), "--out", str(tmp_path / "s.png"), *SMALL,
                 "--aerosol-density", "2")
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "holds a different bake" in lines[0], lines
    assert "--overwrite" not in lines[0] and "--luts" in lines[0]
    assert "single scattering" not in result.stderr                # refused before any stage
    assert {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()} == before
    assert not (tmp_path / "s.png").exists()


def test_an_empty_out_is_a_usage_error_and_writes_nothing(tmp_path):
    """--out "" baked into the current directory."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    result = subprocess.run([sys.executable, "-m", "lut_gen", "bake", "--out", "", *SMALL], capture_output=True,
                            text=True, cwd=tmp_path, env=env, timeout=300)
    assert result.returncode == 2 and "--out" in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_overwrite_into_a_damaged_copy_of_the_same_bake_bakes_it_again(tmp_path):
    """With a damaged file, bake said "cache hit ... nothing to do", even with
    --overwrite. Now it is baked again, and said so."""
    assert run("bake", "--out", str(tmp_path / "l"), *SMALL, "--quiet").returncode == 0
    path = tmp_path / "l" / "higher_order_scattering.exr"
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x10
    path.write_bytes(bytes(data))
    for extra in (["--overwrite"], []):
        result = run("bake", "--out", str(tmp_path / "l"), *SMALL, "--quiet", *extra)
        assert result.returncode == 0, result.stderr
        assert "cache hit" not in result.stdout and "baked" in result.stdout, (extra, result.stdout)
        import lut_gen
        lut_gen.load(tmp_path / "l")                               # whole again
        path.write_bytes(bytes(data))


def test_bake_does_not_hang_on_a_fifo_named_like_a_table(tmp_path):
    """A FIFO named like a table made bake hang forever."""
    assert run("bake", "--out", str(tmp_path / "l"), *SMALL, "--quiet").returncode == 0
    (tmp_path / "l" / "optical_depth.exr").unlink()
    os.mkfifo(tmp_path / "l" / "optical_depth.exr")
    before = sorted(p.name for p in (tmp_path / "l").iterdir())
    result = run("bake", "--out", str(tmp_path / "l"), *SMALL, "--quiet")       # run() times out at 300 s
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "optical_depth.exr" in lines[0] and "not written by lut_gen" in lines[0], lines
    assert sorted(p.name for p in (tmp_path / "l").iterdir()) == before
    assert (tmp_path / "l" / "optical_depth.exr").is_fifo()


def test_two_bake_processes_into_one_folder_never_mix(tmp_path):
    """Two bakes with different parameters into one --out both exited 0, one
    silently replacing the other. As two processes started together: one wins, the other exits
    1 naming the bake that is there, and the folder verifies as the winner's."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = tmp_path / "shared"
    runs = [subprocess.Popen([sys.executable, "-m", "lut_gen", "bake", "--out", str(out), *SMALL, "--quiet",
                              "--aerosol-density", density], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, cwd=ROOT, env=env) for density in ("1", "2")]
    results = [(run.wait(timeout=300), *run.communicate()) for run in runs]
    codes = sorted(code for code, _, _ in results)
    assert codes == [0, 1], results
    import lut_gen
    loaded = lut_gen.load(out)
    winner = lut_gen.store.exr_read.verify_bake(out)
    loser_err = next(err for code, _, err in results if code == 1)
    assert f"holds a different bake ({winner})" in loser_err and loser_err.strip().count("\n") == 0
    winner_density = next(d for (code, _, _), d in zip(results, (1.0, 2.0)) if code == 0)
    assert loaded.params.aerosol_density == winner_density


def test_sample_reads_a_read_only_folder_that_holds_its_bake(tmp_path, monkeypatch, capsys):
    """sample's early check of --luts must not refuse a shared, read-only folder holding the
    very bake it wants: that folder is only read. (The test runs as root here, for whom every
    folder is writable: the folder is made to read as unwritable.)"""
    from lut_gen import cli
    assert run("bake", "--out", str(tmp_path / "l"), *SMALL, "--quiet").returncode == 0
    monkeypatch.setattr(os, "access", lambda *args, **kwargs: False)
    assert cli.main(["sample", "--luts", str(tmp_path / "l"), "--out", str(tmp_path / "s.png"), *SMALL,
                     "--quiet"]) == 0, capsys.readouterr().err
    assert "cache hit" in capsys.readouterr().out and (tmp_path / "s.png").exists()


def test_an_unknown_fog_preset_is_named_and_nothing_is_written(tmp_path):
    result = run("bake", "--out", str(tmp_path / "l"), *SMALL, "--preset", "evening-fog")
    assert result.returncode == 1 and result.stderr.strip().count("\n") == 0
    assert ("unknown preset 'evening-fog'; choose one of clear-sky, sample-2013, hazy-summer-day, "
            "clean-mountain-air, light-haze, heavy-haze, morning-fog") in result.stderr
    assert not (tmp_path / "l").exists()


def test_the_morning_fog_preset_bakes_its_fog(tmp_path):
    result = run("bake", "--out", str(tmp_path / "l"), *SMALL, "--preset", "morning-fog", "--quiet")
    assert result.returncode == 0, result.stderr
    import lut_gen
    params = lut_gen.load(tmp_path / "l").params
    assert (params.fog_visibility, params.fog_height) == (300.0, 50.0)
    assert params.aerosol_density == lut_gen.AtmosphereParams().aerosol_density


def test_a_bake_of_the_previous_layout_is_refused_and_kept(tmp_path):
    """A directory baked by baker 6 (before fog, no fog tables) is refused by bake, sample and
    pass in one line each, and left as it was."""
    env = {"PYTHONPATH": str(ROOT)}
    script = ("import sys, lut_gen, lut_gen.store.exr_header as e; e.BAKER_VERSION = 6; "
              "lut_gen.save(lut_gen.bake(resolution=(8, 16, 8, 4), orders=2), sys.argv[1])")
    made = subprocess.run([sys.executable, "-c", script, str(tmp_path / "l")], capture_output=True, text=True,
                          env=dict(os.environ, **env), timeout=300)
    assert made.returncode == 0, made.stderr
    before = {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()}
    for args in (("bake", "--out", str(tmp_path / "l"), *SMALL, "--preset", "morning-fog"),
                 ("sample", "--luts", str(tmp_path / "l"), "--out", str(tmp_path / "s.png"), *SMALL)):
        result = run(*args)
        assert result.returncode == 1 and result.stderr.strip().count("\n") == 0, result.stderr
        assert ("baker version 6 (the layout before fog: no fog tables); this version reads baker "
                f"{BAKER_VERSION}") in result.stderr
        assert {p.name: p.read_bytes() for p in (tmp_path / "l").iterdir()} == before
    assert not (tmp_path / "s.png").exists()
