"""``python -m lut_gen pass`` refuses render passes that do not belong to the saved inputs (another
size, NaN or infinite values) with one line before any work, and never writes negative light."""
import numpy as np
import OpenEXR
import pytest

from lut_gen import cli
from lut_gen.store import exr_header, exr_write
from lut_gen.passes import scattering_pass
from occluders import CAMERA, Scene, pillars, sun_at


@pytest.fixture(scope="module")
def luts_dir(draft_luts, tmp_path_factory):
    return exr_write.save(draft_luts, tmp_path_factory.mktemp("luts") / "draft")


def write_passes(path, image, position, depth):
    """A Blender-style multilayer EXR ("ViewLayer.<pass>.<channel>", rows top to bottom)."""
    channels = {}
    for name, array, components in (("Combined", image, "RGB"), ("Position", position, "XYZ"),
                                    ("Depth", depth[..., None], "Z")):
        for i, component in enumerate(components):
            channels[f"ViewLayer.{name}.{component}"] = np.ascontiguousarray(array[::-1, :, i], dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as exr:
        exr.write(str(path))
    return path


def scene_files(tmp_path, width, height, saved=None, sun=(6.0, 5.0)):
    scene = Scene(pillars(), CAMERA, sun_at(*sun), width, height)
    settings = scattering_pass.PassSettings(scattering_technique="EPIPOLAR_SAMPLING", num_integration_steps=8,
                                            epipolar_slices=64, samples_per_slice=32)
    inputs = scattering_pass.save_inputs(tmp_path / "inputs.npz", scene.camera, scene.sun, scene.cascades, settings,
                                         saved or (width, height))
    return scene, inputs


def run_pass(luts_dir, passes, inputs, out):
    return cli.main(["pass", "--luts", str(luts_dir), "--passes", str(passes), "--inputs", str(inputs),
                     "--out", str(out)])


def test_passes_of_another_size_are_refused(luts_dir, tmp_path, capsys):
    scene, inputs = scene_files(tmp_path, 32, 18, saved=(64, 36))
    passes = write_passes(tmp_path / "passes.exr", scene.image, scene.position, scene.depth)
    assert run_pass(luts_dir, passes, inputs, tmp_path / "out.exr") == 1
    err = capsys.readouterr().err
    assert "is 32x18 but" in err and "64x36" in err
    assert not (tmp_path / "out.exr").exists()


@pytest.mark.parametrize("bad", [np.inf, -np.inf, np.nan])
def test_non_finite_positions_are_refused(luts_dir, tmp_path, capsys, bad):
    scene, inputs = scene_files(tmp_path, 32, 18)
    position = scene.position.copy()
    position[3, 4, 1] = bad
    passes = write_passes(tmp_path / "passes.exr", scene.image, position, scene.depth)
    assert run_pass(luts_dir, passes, inputs, tmp_path / "out.exr") == 1
    assert "Position pass holds NaN or infinite values" in capsys.readouterr().err
    assert not (tmp_path / "out.exr").exists()


@pytest.mark.parametrize("size", [(1, 1), (16, 9)])
def test_tiny_crops_give_finite_non_negative_light(luts_dir, tmp_path, size):
    """Sky pixels darker than the air computed in front of them (a black sky): the shafts take
    out at most all of it (without the floor at 0: -0.1 at 16 x 9)."""
    scene, inputs = scene_files(tmp_path, *size, sun=(12.0, 0.0))
    dark_sky = np.where(scene.geometry[..., None], scene.image, 0.0)
    passes = write_passes(tmp_path / "passes.exr", dark_sky, scene.position, scene.depth)
    for technique in ("epipolar", "brute-force"):
        out = tmp_path / f"{technique}.exr"
        assert cli.main(["pass", "--luts", str(luts_dir), "--passes", str(passes), "--inputs", str(inputs),
                         "--technique", technique, "--out", str(out)]) == 0
        with OpenEXR.File(str(out)) as exr:
            pixels = np.asarray(next(iter(exr.parts[0].channels.values())).pixels)
        assert np.isfinite(pixels).all() and pixels.min() >= 0.0, technique


def test_a_depth_pass_of_another_size_is_refused(luts_dir, tmp_path, capsys):
    """A Depth part of another size gave a numpy broadcast error."""
    scene, inputs = scene_files(tmp_path, 32, 18)
    passes = write_passes(tmp_path / "passes.exr", scene.image, scene.position, scene.depth)
    with OpenEXR.File(str(passes), separate_channels=True) as exr:
        channels = {name: np.asarray(c.pixels) for part in exr.parts for name, c in part.channels.items()}
    channels["ViewLayer.Depth.Z"] = np.ascontiguousarray(channels["ViewLayer.Depth.Z"][:9, :16])
    mixed = tmp_path / "mixed.exr"
    display = ((0, 0), (31, 17))                                # every part shows the same window
    parts = [OpenEXR.Part({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
                           "displayWindow": display,
                           "dataWindow": ((0, 0), (15, 8)) if layer == "Depth" else display},
                          {name: value for name, value in channels.items() if f".{layer}." in name}, name=layer)
             for layer in ("Combined", "Position", "Depth")]
    with OpenEXR.File(parts) as exr:
        exr.write(str(mixed))
    assert run_pass(luts_dir, mixed, inputs, tmp_path / "out.exr") == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "passes differ in size" in err[0], err
    assert "depth 16x9" in err[0] and not (tmp_path / "out.exr").exists()


@pytest.mark.parametrize("field", ["centers", "halves", "far_depths", "frame", "camera_position", "clip_end"])
def test_non_finite_inputs_are_refused(luts_dir, tmp_path, capsys, field):
    """A NaN camera position gave an IndexError; every array of the inputs is
    checked (the cascades' rectangles too), with one line naming it."""
    scene, inputs = scene_files(tmp_path, 32, 18)
    passes = write_passes(tmp_path / "passes.exr", scene.image, scene.position, scene.depth)
    with np.load(inputs) as data:
        arrays = {name: np.array(data[name]) for name in data.files}
    arrays[field] = np.where(np.ones_like(arrays[field], dtype=bool), np.nan, arrays[field])
    bad = tmp_path / "bad_inputs.npz"
    np.savez(bad, **arrays)
    assert run_pass(luts_dir, passes, bad, tmp_path / "out.exr") == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "export the inputs again" in err[0], err
    assert not (tmp_path / "out.exr").exists()


def test_pass_steps_out_of_range_are_refused_before_any_work(luts_dir, tmp_path, capsys):
    """--steps 1000000 ran out of memory (W x H x steps)."""
    scene, inputs = scene_files(tmp_path, 32, 18)
    passes = write_passes(tmp_path / "passes.exr", scene.image, scene.position, scene.depth)
    assert cli.main(["pass", "--luts", str(luts_dir), "--passes", str(passes), "--inputs", str(inputs),
                     "--steps", "1000000", "--out", str(tmp_path / "out.exr")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--steps" in err[0] and "256" in err[0], err
    assert not (tmp_path / "out.exr").exists()


def test_pass_with_tables_of_a_hostile_header_is_one_error_line(luts_dir, tmp_path, capsys):
    """100 000 nested brackets in ols.params gave a RecursionError from pass."""
    import shutil
    from test_exr_io import reseal, rewrite
    hostile = tmp_path / "hostile"
    shutil.copytree(luts_dir, hostile)
    for name in exr_header.FILES.values():
        rewrite(hostile / name, change_header=lambda h: h.update({"ols.params": "[" * 100_000}))
    reseal(hostile)
    scene, inputs = scene_files(tmp_path, 32, 18)
    passes = write_passes(tmp_path / "passes.exr", scene.image, scene.position, scene.depth)
    assert run_pass(hostile, passes, inputs, tmp_path / "out.exr") == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert "Traceback" not in "\n".join(err) and not (tmp_path / "out.exr").exists()


def test_an_unwritable_out_is_named_before_any_work(luts_dir, tmp_path, capsys):
    """--out errors named the temporary file, after the whole pass."""
    scene, inputs = scene_files(tmp_path, 32, 18)
    passes = write_passes(tmp_path / "passes.exr", scene.image, scene.position, scene.depth)
    (tmp_path / "file").write_text("x")
    out = tmp_path / "file" / "out.exr"                   # its folder is a file
    assert run_pass(luts_dir, passes, inputs, out) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(out) in err[0] and ".tmp" not in err[0], err
