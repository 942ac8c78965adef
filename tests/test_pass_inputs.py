"""``python -m lut_gen pass`` refuses render passes that do not belong to the saved inputs (another
size, NaN or infinite values) with one line before any work, and never writes negative light
(issue 9, item 11)."""
import numpy as np
import OpenEXR
import pytest

from lut_gen import cli, exr_io, scattering_pass
from test_epipolar import CAMERA, Scene, pillars, sun_at


@pytest.fixture(scope="module")
def luts_dir(draft_luts, tmp_path_factory):
    return exr_io.save(draft_luts, tmp_path_factory.mktemp("luts") / "draft")


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
