"""Clouds as density along view rays ("OLS Cloud Veil", twin lut_gen.clouds.veil): the sample under
a low cloud layer whose base lies below the peaks, composited by Cycles against the numpy twin of
the whole pass, with the light shafts off and with epipolar shafts; the peaks in the cloud are
veiled, coverage 0 changes nothing, and Clouds off takes the veil out of the compositor."""
import numpy as np
import pytest

from render_util import render_rgb, save_png
from scenes import Twin, render_passes
from extension import extension_module, names

bpy = pytest.importorskip("bpy")

from test_light_shafts_pass import low_sun_scene, relative_error  # noqa: E402


def low_cloud_scene(pkg, tmp_path, monkeypatch):
    scene = low_sun_scene(pkg, tmp_path, monkeypatch, steps=16)
    sun_mod = extension_module("addon.scene.sun")
    sun_mod.set_sun_angles(sun_mod.find_sun(scene), 25.0, 30.0)
    settings = scene.ols
    settings.clouds_enabled = True
    # The sample's peaks reach ~1.2 km: a layer from 600 m to 1.1 km takes their tops in.
    settings.cloud_coverage, settings.cloud_base, settings.cloud_thickness = 0.6, 600.0, 500.0
    settings.cloud_scale, settings.cloud_seed, settings.cloud_offset = 1500.0, 4, (0.0, 0.0)
    settings.enable_light_shafts = False
    return scene


def test_peaks_in_the_cloud_are_veiled_as_the_twin_says(addon_package, tmp_path, monkeypatch):
    scene = low_cloud_scene(addon_package, tmp_path, monkeypatch)
    passes = render_passes(addon_package, scene, tmp_path)
    twin = Twin(addon_package, scene, passes)
    tree = scene.compositing_node_group
    veil_node = tree.nodes[names.VEIL_NODE]
    assert tree.nodes[names.AERIAL_NODE].inputs["Image"].links[0].from_node == veil_node

    seen = render_rgb(scene, tmp_path / "veiled.exr", composite=True)[::-1]
    expected = twin()
    error = relative_error(seen, expected)
    print("aerial only: median", np.median(error), "p99", np.percentile(error, 99))
    assert np.median(error) <= 1e-3
    assert np.percentile(error, 99) <= 2e-2
    save_png(tmp_path / "veiled.png", seen[::-1], 1.0)

    # The veil is there: where the cloud hides most of a peak, the picture is the cloud's.
    image, position, depth = passes
    veil = extension_module("lut_gen.clouds.veil")
    shafts = extension_module("lut_gen.clouds.shafts")
    frame_update = extension_module("addon.scene.frame.frame_update")
    settings = frame_update.pass_settings(scene, 10.0)
    layer, cloud = shafts.of_settings(settings)
    through, _ = veil.veil(layer, cloud, veil.VeilLight.of(twin.luts, layer, twin.sun), twin.camera.position,
                           position, twin.sun)
    geometry = depth < 1e9
    hidden = geometry & (through < 0.2)
    print("surface pixels mostly hidden by the cloud:", hidden.sum(), "of", geometry.sum())
    assert hidden.sum() >= 20
    clear = twin(clouds_enabled=False)
    changed = relative_error(clear, expected)
    assert np.median(changed[hidden]) > 0.05

    # With epipolar shafts the whole image is made from the veiled surface too.
    scene.ols.enable_light_shafts = True
    scene.ols.scattering_technique = "EPIPOLAR_SAMPLING"
    # The world's sky changes with it (the shafts pass redoes the air's single scattering under
    # the clouds): the twin reads a render made with shafts on.
    twin = Twin(addon_package, scene, render_passes(addon_package, scene, tmp_path))
    seen = render_rgb(scene, tmp_path / "epipolar.exr", composite=True)[::-1]
    shafts_node = tree.nodes[names.SHAFTS_NODE]
    assert shafts_node.inputs["Surface"].links[0].from_node == tree.nodes[names.VEIL_NODE]
    error = relative_error(seen, twin(enable_light_shafts=True, scattering_technique="EPIPOLAR_SAMPLING"))
    print("epipolar: median", np.median(error), "p99", np.percentile(error, 99))
    assert np.median(error) <= 1e-3

    # Coverage 0: the veil is in the tree but lets everything through.
    scene.ols.enable_light_shafts = False
    scene.ols.cloud_coverage = 0.0
    without = render_rgb(scene, tmp_path / "coverage0.exr", composite=True)[::-1]
    scene.ols.clouds_enabled = False
    assert names.VEIL_NODE not in tree.nodes                     # Clouds off: out of the tree
    assert tree.nodes[names.AERIAL_NODE].inputs["Image"].links[0].from_node.bl_idname == "CompositorNodeRLayers"
    off = render_rgb(scene, tmp_path / "off.exr", composite=True)[::-1]
    surface = (depth < 1e9)[::-1]
    assert np.abs(without - off)[surface].max() <= 1e-4 * max(off.max(), 1.0)
