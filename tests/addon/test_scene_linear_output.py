"""Pipeline output: renders saved as OpenEXR hold scene-linear radiance with the
atmosphere applied, display formats the chosen tone mapping; the "Blender View Transform"
operator leaves the curve to the scene's own view transform."""

import numpy as np
import pytest

from render_util import render_rgb
from scenes import Twin, render_passes, sample_scene
from extension import extension_module

bpy = pytest.importorskip("bpy")


@pytest.fixture
def wired(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    scene = sample_scene(addon_package)
    scene.view_settings.view_transform = "AgX"
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    scene.render.resolution_x, scene.render.resolution_y = 40, 24
    scene.cycles.samples = 2
    scene.cycles.seed = 7
    return scene


def render_png16(scene, path):
    """Render a 16-bit PNG (through the view transform, as Blender saves it) and return its
    encoded values in 0-1, row 0 at the top."""
    settings = scene.render.image_settings
    settings.file_format, settings.color_mode, settings.color_depth = "PNG", "RGB", "16"
    scene.render.use_compositing = True
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    image.colorspace_settings.name = "Non-Color"           # the stored values, not linearised
    width, height = image.size
    pixels = np.array(image.pixels[:], dtype=np.float64).reshape(height, width, 4)[::-1, :, :3]
    bpy.data.images.remove(image)
    return pixels


def tone_node(scene):
    return scene.compositing_node_group.nodes["OLS Tone Mapping"]


def test_exr_is_scene_linear_and_png_is_tone_mapped(addon_package, wired, tmp_path):
    twin = extension_module("lut_gen.passes.tone_mapping")
    scene = wired
    linear = render_rgb(scene, tmp_path / "beauty.exr", composite=True)
    assert tone_node(scene).inputs["Linear Output"].default_value == 1.0
    # The same composite with the tone mapping taken out of the tree: identical.
    tone_node(scene).mute = True
    bypassed = render_rgb(scene, tmp_path / "bypassed.exr", composite=True)
    tone_node(scene).mute = False
    np.testing.assert_allclose(linear, bypassed, rtol=1e-6, atol=1e-9)
    assert linear.max() > 1.0                      # radiance, not display values: the sun-lit sky
    # The display format of the same frame shows the panel's operator.
    png = render_png16(scene, tmp_path / "beauty.png")
    assert tone_node(scene).inputs["Linear Output"].default_value == 0.0
    want = twin.srgb_encode(twin.tone_map(linear, "UNCHARTED2", average_luminance=twin.log_average_luminance(linear)))
    assert np.abs(png - want).max() <= 2e-3
    assert 0.05 < png.mean() < 0.95
    # Tone Map EXR bakes the look into EXR too.
    scene.ols.tone_map_exr = True
    mapped = render_rgb(scene, tmp_path / "mapped.exr", composite=True)
    assert np.abs(twin.srgb_encode(mapped) - png).max() <= 2e-3
    # The linear EXR is the numpy twins' composite of the same render passes (the bar:
    # median relative error <= 1e-3).
    passes = render_passes(addon_package, scene, tmp_path)
    expected = Twin(addon_package, scene, passes)()
    error = np.abs(linear[::-1] - expected).sum(-1) / np.maximum(expected.sum(-1), 1e-4)   # rows bottom to top
    print("EXR vs twin composite: median", np.median(error), "max", error.max())
    assert np.median(error) <= 1e-3


def test_blender_view_transform_operator(addon_package, wired, tmp_path):
    twin = extension_module("lut_gen.passes.tone_mapping")
    wiring = extension_module("addon.scene.setup.wiring")
    scene = wired
    assert scene.view_settings.view_transform == "Standard"        # the sample's operators
    scene.ols.tone_mapping_operator = "BLENDER_VIEW"
    assert scene.view_settings.view_transform == "AgX"             # the user's own is back
    scene.ols.auto_exposure = False
    ours = render_png16(scene, tmp_path / "ours.png")
    tone_node(scene).mute = True                                    # the scene without our tone mapping
    plain = render_png16(scene, tmp_path / "plain.png")
    tone_node(scene).mute = False
    assert np.abs(ours - plain).max() <= 1e-3
    assert 0.05 < ours.mean() < 0.95
    # Auto exposure still sets the exposure: middle gray over the frame's log-average luminance.
    # A middle gray far from the frame's own average, so that the exposure cannot be ~1 by chance
    # of the scene.
    scene.ols.auto_exposure = True
    scene.ols.middle_gray = 0.05
    scene.ols.tone_map_exr = True
    exposed = render_rgb(scene, tmp_path / "exposed.exr", composite=True)
    scene.ols.tone_map_exr = False
    scene.render.image_settings.media_type = "IMAGE"
    linear = render_rgb(scene, tmp_path / "linear.exr", composite=True)
    average = twin.log_average_luminance(linear)
    assert abs(0.05 / average - 1.0) > 0.2, average
    want = twin.tone_map(linear, "BLENDER_VIEW", middle_gray=0.05, average_luminance=average)
    np.testing.assert_allclose(exposed, want, rtol=2e-3, atol=1e-6)
    assert not np.allclose(exposed, linear, rtol=0.05)
    # A view transform the user picks meanwhile stays; the sample's operators set Standard again
    # and unwiring restores the user's choice.
    scene.view_settings.view_transform = "Filmic"
    scene.ols.middle_gray = 0.2
    assert scene.view_settings.view_transform == "Filmic"
    scene.ols.tone_mapping_operator = "REINHARD"
    assert scene.view_settings.view_transform == "Standard"
    wiring.unwire_scene(scene)
    assert scene.view_settings.view_transform == "Filmic"


def read_layers(path):
    """{layer: (h, w, 3)} of a multilayer (multi-part) EXR."""
    import OpenEXR
    layers = {}
    with OpenEXR.File(str(path)) as exr:
        for part in exr.parts:
            for name, channel in part.channels.items():
                pixels = np.asarray(channel.pixels, dtype=np.float64)
                if pixels.ndim == 3:
                    layers[name] = pixels[..., :3]
    return layers


@pytest.mark.parametrize("technique", ["EPIPOLAR_SAMPLING", "BRUTE_FORCE"])
def test_multilayer_exr_carries_the_atmosphere_layers(addon_package, wired, tmp_path, technique):
    """beauty = surface x transmittance + inscattering + shafts, beside a multilayer EXR render,
    for either light-shaft technique."""
    scene = wired
    scene.ols.scattering_technique = technique
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"     # Blender 5.0: before the format
    scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    scene.render.image_settings.color_depth = "32"
    scene.render.use_compositing = True
    scene.render.filepath = str(tmp_path / "shot.exr")
    bpy.ops.render.render(write_still=True)
    # render_pre rebuilt the groups for the technique
    assert scene.compositing_node_group.nodes["OLS Light Shafts"].node_tree["ols_layout"].find(technique) >= 0
    written = sorted(tmp_path.glob("shot_atmosphere_*.exr"))
    assert len(written) == 1, sorted(p.name for p in tmp_path.iterdir())
    layers = read_layers(written[0])
    assert set(layers) >= {"Beauty", "Surface", "Transmittance", "Inscattering", "Shafts"}, set(layers)
    beauty = layers["Beauty"]
    rebuilt = layers["Surface"] * layers["Transmittance"] + layers["Inscattering"] + layers["Shafts"]
    np.testing.assert_allclose(rebuilt, beauty, rtol=1e-4, atol=1e-6)
    assert layers["Inscattering"].max() > 1e-3 and layers["Transmittance"].min() < 0.99   # the air shows
    assert np.abs(layers["Shafts"]).max() > 0                                           # shafts on
    # The beauty layer is the scene-linear image the EXR itself holds.
    scene.render.image_settings.media_type = "IMAGE"
    linear = render_rgb(scene, tmp_path / "linear.exr", composite=True)
    np.testing.assert_allclose(beauty, linear, rtol=1e-5, atol=1e-7)
    # Parked after the render: muted and holding no folder.
    node = scene.compositing_node_group.nodes["OLS Atmosphere Layers"]
    assert node.mute and node.directory == ""
