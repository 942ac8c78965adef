"""Cloud shadows: the shadow-only layer ("OLS Cloud Shadow") over a lit plain, rendered by
Cycles, against its twin (lut_gen.clouds.shadow) and against the coverage it should show."""
import math

import numpy as np
import pytest

from render_util import empty_scene, render_rgb, save_png
from extension import extension_module

bpy = pytest.importorskip("bpy")

SIZE, PIXELS, STRENGTH, ALBEDO = 4000.0, 96, 3.0, 0.8


def plain_under_clouds(scene, sun_elevation, coverage, seed=5, density=None):
    mesh = bpy.data.meshes.new("plain")
    h = SIZE / 2
    mesh.from_pydata([(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)], [], [(0, 1, 2, 3)])
    plain = bpy.data.objects.new("plain", mesh)
    material = bpy.data.materials.new("white")
    material.use_nodes = True
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (ALBEDO, ALBEDO, ALBEDO, 1.0)
    material.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 1.0
    mesh.materials.append(material)
    scene.collection.objects.link(plain)
    lamp = bpy.data.lights.new("sun", "SUN")
    lamp.energy, lamp.angle = STRENGTH, math.radians(0.545)
    sun = bpy.data.objects.new("sun", lamp)
    sun.rotation_euler = (math.pi / 2 - math.radians(sun_elevation), 0.0, math.radians(20.0))
    scene.collection.objects.link(sun)
    cam_data = bpy.data.cameras.new("top")
    cam_data.type, cam_data.ortho_scale = "ORTHO", SIZE
    camera = bpy.data.objects.new("top", cam_data)
    camera.location = (0.0, 0.0, 500.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.world = None
    settings = scene.ols
    settings.clouds_enabled, settings.cloud_coverage, settings.cloud_scale, settings.cloud_seed = True, coverage, 1000.0, seed
    if density is not None:
        settings.cloud_density = density
    clouds, nodes = extension_module("addon.scene.clouds"), extension_module("addon.nodes")
    map_image = clouds.ensure_map_image(seed)
    nodes.build_cloud_shadow_group(map_image)
    clouds.ensure_shadow_layer(scene, sun)
    bpy.context.view_layer.update()
    direction = np.array(sun.matrix_world.col[2][:3])
    return extension_module("lut_gen.clouds.layer").CloudLayer.of(settings), extension_module("addon.scene.frame.cloud_map").map_ranks(map_image), direction


def ground_points(supersample=4):
    offsets = (np.arange(supersample) + 0.5) / supersample
    coords = ((np.arange(PIXELS)[:, None] + offsets).reshape(-1) / PIXELS - 0.5) * SIZE
    y, x = np.meshgrid(-coords, coords, indexing="ij")               # row 0 at the top (+y)
    points = np.stack([x, y, np.zeros_like(x)], -1).reshape(PIXELS, supersample, PIXELS, supersample, 3)
    return points.transpose(0, 2, 1, 3, 4).reshape(PIXELS, PIXELS, -1, 3)


def test_cloud_shadows_on_a_plain_match_the_twin(addon_package, tmp_path):
    scene = empty_scene(width=PIXELS, height=PIXELS, samples=32)
    # A thin cloud (optical depth 1.2 through the layer) so that its shadow's depth is measurable.
    layer, ranks, sun = plain_under_clouds(scene, 60.0, 0.5, density=0.002)
    rendered = render_rgb(scene, tmp_path / "shadows.exr")[..., 1]
    unshadowed = ALBEDO * STRENGTH * sun[2] / math.pi
    save_png(tmp_path / "shadows.png", np.repeat(rendered[..., None], 3, -1), exposure=1.0 / unshadowed)
    twin = addon_package.lut_gen.clouds.shadow.ground_transmittance(layer, ranks, ground_points(), sun).mean(axis=2)
    seen = rendered / unshadowed
    error = np.abs(seen - twin)
    print("shadow error mean", error.mean(), "median", np.median(error), "p90", np.percentile(error, 90))
    assert error.mean() < 0.02 and np.median(error) < 0.01
    want = math.exp(-layer.density * layer.thickness / sun[2])
    # The coverage seen along the sun: the shadowed fraction of the ground within 0.1 of it.
    shadowed = seen < 0.5 * (1.0 + want)
    assert abs(shadowed.mean() - 0.5) < 0.1, shadowed.mean()
    # Under a full cloud the sun is dimmed by exp(-optical depth) along it, within 5%.
    full = twin < want * 1.01
    assert full.sum() > 50
    assert 0.1 < want < 0.5
    assert abs(np.median(seen[full]) / want - 1.0) < 0.05, (np.median(seen[full]), want)


def test_the_layer_is_invisible_and_leaves_with_unwiring(addon_package, tmp_path):
    scene = empty_scene(width=16, height=16, samples=1)
    plain_under_clouds(scene, 40.0, 1.0)
    layer = bpy.data.objects["OLS Cloud Shadows"]
    assert not layer.visible_camera and layer.visible_shadow
    extension_module("addon.scene.clouds").remove_shadow_layer()
    assert "OLS Cloud Shadows" not in bpy.data.objects


def test_a_deleted_cloud_map_comes_back_from_the_seed(addon_package, tmp_path):
    scene = empty_scene(width=16, height=16, samples=1)
    plain_under_clouds(scene, 40.0, 0.5, seed=9)
    clouds = extension_module("addon.scene.clouds")
    before = extension_module("addon.scene.frame.cloud_map").map_ranks(bpy.data.images["OLS Cloud Map"])
    bpy.data.images.remove(bpy.data.images["OLS Cloud Map"])
    clouds.ensure_map_image(9)
    image = bpy.data.images["OLS Cloud Map"]
    np.testing.assert_array_equal(extension_module("addon.scene.frame.cloud_map").map_ranks(image), before)
    shadow_tree = bpy.data.node_groups["OLS Cloud Shadow"]
    assert [n.image for n in shadow_tree.nodes if n.label == "OLS Cloud Map"] == [image]


def test_a_damaged_cloud_table_is_a_clear_error(addon_package, tmp_path, monkeypatch):
    slab = addon_package.lut_gen.clouds.slab
    broken = tmp_path / "higher_orders.json"
    broken.write_text('{"ratio": [1, 2')
    monkeypatch.setattr(slab, "TABLE_PATH", str(broken))
    slab.higher_order_series.cache_clear()
    try:
        with pytest.raises(ValueError, match="cloud table .* missing or damaged"):
            slab.table_pixels()
    finally:
        monkeypatch.undo()
        slab.higher_order_series.cache_clear()
