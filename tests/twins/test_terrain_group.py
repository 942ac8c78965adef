"""The "OLS Terrain" material group against its numpy twin (lut_gen.passes.terrain): a flat and
a tilted plane under a 30 deg sun, seen from above."""
import math

import numpy as np
import pytest

from extension import extension_module
from render_util import empty_scene, render_rgb, save_png

bpy = pytest.importorskip("bpy")


@pytest.fixture
def addon(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    return addon_package


def add_plane(name, size, location, rotation=(0.0, 0.0, 0.0)):
    bpy.ops.mesh.primitive_plane_add(size=size, location=location, rotation=rotation)
    obj = bpy.context.active_object
    obj.name = name
    material = bpy.data.materials.new(name + " base")
    material.use_nodes = True
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.5, 0.4, 0.3, 1.0)
    obj.data.materials.append(material)
    return obj


# Without fog, and in a 2 km fog of 200 m scale height (the flat plane at 0 m, the tilted one's
# centre 80 m up: the sun reaches them through different fog columns).
@pytest.mark.parametrize("fog", [{}, {"fog_visibility": 2000.0, "fog_height": 200.0}], ids=["clear", "fog"])
def test_terrain_group_matches_numpy_twin(addon, tmp_path, fog):
    scene = empty_scene(width=96, height=48, samples=64)
    flat = add_plane("flat", 200.0, (-150.0, 0.0, 0.0))
    tilted = add_plane("tilted", 200.0, (150.0, 0.0, 80.0), rotation=(math.radians(-40.0), 0.0, 0.0))
    cam_data = bpy.data.cameras.new("top")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 600.0
    camera = bpy.data.objects.new("top", cam_data)
    camera.location = (0.0, 0.0, 1000.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun_mod = extension_module("addon.scene.sun")
    sun = sun_mod.create_sun(scene, elevation_deg=30.0, azimuth_deg=0.0)
    params = addon.lut_gen.AtmosphereParams(**fog)
    directory = extension_module("addon.baking").bake_if_needed(params, "draft")
    extension_module("addon.scene.setup.wiring").wire_scene(scene, directory, [flat, tilted], sun)
    rendered = render_rgb(scene, tmp_path / "terrain.exr")
    save_png(tmp_path / "terrain.png", rendered, exposure=2.0)

    luts = addon.lut_gen.load(directory)
    to_sun = sun_mod.direction_to_sun(sun)
    strength, albedo = sun.data.energy, np.array([0.5, 0.4, 0.3])
    terrain_radiance = extension_module("lut_gen.passes.terrain").terrain_radiance

    def twin(position, normal):
        return terrain_radiance(luts, position, normal, to_sun, strength, albedo)

    # Pixel columns of each plane's centre region (ortho: 600 m over 96 px, centred at x = 0).
    def region(x_centre, half_width=40.0, half_height=40.0):
        cols = slice(int((x_centre - half_width + 300) / 600 * 96), int((x_centre + half_width + 300) / 600 * 96))
        rows = slice(int((300 / 2 - half_height) / 300 * 48), int((300 / 2 + half_height) / 300 * 48))
        return rendered[rows, cols].reshape(-1, 3)

    tilted_normal = np.array(tilted.matrix_world.to_3x3().col[2])
    for pixels, want in ((region(-150.0), twin(np.array([-150.0, 0, 0]), np.array([0.0, 0, 1]))),
                         (region(150.0), twin(np.array([150.0, 0, 80.0]), tilted_normal))):
        err = np.abs(pixels - want) / want
        assert np.median(err) <= 0.03, (np.median(pixels, axis=0), want)
    assert region(150.0).mean() > region(-150.0).mean()      # the tilted plane faces the sun
