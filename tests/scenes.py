"""Scenes and harnesses the add-on, twin and system tests share: the sample scene built fresh, a
compositor tree around one group fed an HDR ramp, and the light-shaft pass's numpy twin fed a
render's passes. Everything here needs bpy: a test module that imports this is skipped where
bpy is missing."""
import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from extension import extension_module, sample_builder
from render_util import empty_scene, render_rgb

bpy = pytest.importorskip("bpy")
RAMP_WIDTH, RAMP_HEIGHT = 64, 4


def shaft_layout(tree) -> dict:
    """The ShaftLayout an "OLS Light Shafts" group was built for, by field name (its key is the
    fields' values in order)."""
    import ast
    fields = dataclasses.fields(extension_module("addon.nodes.light_shafts").ShaftLayout)
    return dict(zip((field.name for field in fields), ast.literal_eval(tree["ols_layout"])))


def refuse_tables(monkeypatch, tmp_path):
    """An empty, read-only cache directory (OLS_CACHE_DIR) and every way to the tables refused:
    what a scene under the analytic model must render with. Returns the directory."""
    cache = tmp_path / "cache"
    cache.mkdir()
    cache.chmod(0o555)
    monkeypatch.setenv("OLS_CACHE_DIR", str(cache))

    def refuse(*args, **kwargs):
        raise AssertionError("the analytic model touched the tables")
    monkeypatch.setattr(extension_module("lut_gen.store.cache"), "bake_validated", refuse)
    monkeypatch.setattr(extension_module("addon.scene.tables.luts"), "load_images", refuse)
    monkeypatch.setattr(extension_module("addon.baking"), "bake_if_needed", refuse)
    monkeypatch.setattr(extension_module("lut_gen.store.exr_header"), "read_header_params", refuse)
    return cache


def hdr_ramp():
    """Luminance from 1e-3 to 1e2 left to right; rows of different chroma."""
    lum = np.logspace(-3, 2, RAMP_WIDTH)
    tints = np.array([[1.0, 1.0, 1.0], [1.0, 0.5, 0.2], [0.2, 0.5, 1.0], [0.9, 1.0, 0.3]])
    return lum[None, :, None] * tints[:, None, :]          # (RAMP_HEIGHT, RAMP_WIDTH, 3), row 0 at the top


def composite(pkg, tmp_path, rgb, **inputs):
    nodes = extension_module("addon.nodes")
    scene = empty_scene(width=RAMP_WIDTH, height=RAMP_HEIGHT, samples=1)
    camera = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    image = bpy.data.images.new("ramp", RAMP_WIDTH, RAMP_HEIGHT, alpha=True, float_buffer=True)
    image.colorspace_settings.is_data = True               # before filling: it regenerates the buffer
    rgba = np.ones((RAMP_HEIGHT, RAMP_WIDTH, 4), np.float32)
    rgba[..., :3] = rgb[::-1]                               # image rows bottom to top
    image.pixels.foreach_set(rgba.ravel())
    group = nodes.build_tone_mapping_group()
    tree = bpy.data.node_groups.new("test compositing", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    source = tree.nodes.new("CompositorNodeImage")
    source.image = image
    node = tree.nodes.new("CompositorNodeGroup")
    node.node_tree = group
    output = tree.nodes.new("NodeGroupOutput")
    tree.links.new(source.outputs["Image"], node.inputs["Image"])
    tree.links.new(node.outputs["Image"], output.inputs[0])
    for name, value in inputs.items():
        node.inputs[name].default_value = value
    scene.compositing_node_group = tree
    scene.render.use_compositing = True
    return render_rgb(scene, tmp_path / "tone.exr", composite=True)


def sample_scene(pkg, resolution=32):
    builder = sample_builder()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    objects = builder.build_sample_scene(bpy.context.scene, elevation_deg=15.0, azimuth_deg=35.0, resolution=resolution)
    for obj in bpy.context.scene.objects:
        obj.select_set(obj == objects["terrain"])
    return bpy.context.scene


def render_passes(pkg, scene, tmp_path):
    """Raw image, position and depth of the render, saved as OpenEXR MultiLayer and read back
    with the twin's loader (rows bottom to top)."""
    settings = scene.render.image_settings
    scene.render.use_compositing = False
    settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    scene.render.filepath = str(tmp_path / "passes.exr")
    try:
        bpy.ops.render.render(write_still=True)
    finally:
        settings.media_type = "IMAGE"
    passes = pkg.lut_gen.passes.scattering_pass.load_render_passes(tmp_path / "passes.exr")
    return passes["image"], passes["position"], passes["depth"]


class Twin:
    """lut_gen.passes.scattering_pass with the scene's camera, sun, tables and shadow cascades."""

    def __init__(self, pkg, scene, passes):
        self.pkg, self.scene, self.passes = pkg, scene, passes
        params = extension_module("addon.settings").atmosphere_params(scene.ols)      # the scene's own (fog too)
        self.luts = pkg.lut_gen.load(extension_module("addon.baking").bake_if_needed(params, "draft"))
        self.shadow_maps = extension_module("addon.scene.frame.shadow_maps")
        self.frame_state = extension_module("addon.scene.frame.frame_state")
        sun_mod = extension_module("addon.scene.sun")
        self.sun = sun_mod.direction_to_sun(sun_mod.find_sun(scene))
        self.camera = self.frame_state.camera_model(scene)

    def cascades(self):
        depsgraph = bpy.context.evaluated_depsgraph_get()
        return self.shadow_maps.render(self.frame_state.read(self.scene, depsgraph), depsgraph)

    def __call__(self, **overrides):
        frame_update = extension_module("addon.scene.frame.frame_update")
        settings = dataclasses.replace(frame_update.pass_settings(self.scene, 10.0), **overrides)
        return self.pkg.lut_gen.passes.scattering_pass.scattering_pass(
            self.luts, *self.passes, self.camera, self.sun, self.cascades(), settings)


@pytest.fixture(scope="module")
def egl():
    """Skips the test where EEVEE cannot render (no EGL: Debian libegl1, libegl-mesa0,
    libgl1-mesa-dri); EEVEE aborts the process there, so the probe is a subprocess."""
    probe = ("import bpy; s=bpy.context.scene; s.render.engine='BLENDER_EEVEE'; "
             "s.render.resolution_x=s.render.resolution_y=8; bpy.ops.render.render()")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    if result.returncode != 0:
        pytest.skip(f"EEVEE cannot render here (no EGL?): exit {result.returncode}")


def compositor_output(scene, build):
    """Point the scene's compositor at a fresh tree whose output is build(tree, render_layers)."""
    tree = bpy.data.node_groups.new("test output", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    layers = tree.nodes.new("CompositorNodeRLayers")
    output = tree.nodes.new("NodeGroupOutput")
    tree.links.new(build(tree, layers), output.inputs[0])
    scene.compositing_node_group = tree


def depth_image(tree, layers):
    """The Depth pass as a grey image (compositor_output builder)."""
    combine = tree.nodes.new("CompositorNodeCombineColor")
    for name in ("Red", "Green", "Blue"):
        tree.links.new(layers.outputs["Depth"], combine.inputs[name])
    return combine.outputs["Image"]
