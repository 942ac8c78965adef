"""The sky group with the cloud layer ("OLS Clouds") rendered by Cycles vs its numpy twin
(lut_gen.clouds.sky): the same cloud map and table images, the same composite."""
import math

import numpy as np
import pytest

from render_util import empty_scene, panorama_camera, panorama_directions, render_rgb, save_png, world_of_group
from extension import extension_module

bpy = pytest.importorskip("bpy")

STRENGTH, SCALE = 10.0, 0.5
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@pytest.fixture(scope="module")
def bake_dir(tmp_path_factory):
    import lut_gen
    directory = tmp_path_factory.mktemp("luts")
    lut_gen.save(lut_gen.bake(resolution="draft"), directory)
    return directory


def build_cloudy_world(pkg, bake_dir, sun, camera_height, layer, clouds_on=1.0, light_shafts=0.0):
    images = extension_module("addon.scene.tables.luts").load_images(bake_dir)
    luts = pkg.lut_gen.load(bake_dir)
    nodes = extension_module("addon.nodes")
    clouds = extension_module("addon.scene.clouds")
    skylight = extension_module("addon.scene.frame.skylight")
    nodes.build_lookup_group(images["multiple"], luts.dims, luts.params, mie_image=images["single_mie"])
    map_image = clouds.ensure_map_image(layer.seed)
    # The air map as the add-on writes it each frame (scene/frame/skylight.py).
    atlas = pkg.lut_gen.clouds.air_map.compute(luts, layer, camera_height, np.array(sun))
    air_image = skylight.ensure_cloud_air_image()
    air_image.pixels.foreach_set(np.concatenate([atlas, np.ones(atlas.shape[:2] + (1,), np.float32)], -1).ravel())
    cloud_tree = nodes.build_cloud_group(map_image, clouds.ensure_table_image(), air_image, luts.params)
    sky = nodes.build_sky_group(images["optical_depth"], luts.params, skylight.ensure_image(), images["ambient"],
                                skylight.ensure_ground_image(), clouds_tree=cloud_tree,
                                sky_view_image=skylight.ensure_sky_view_image())
    group = world_of_group(bpy.context.scene, sky)
    values = {"Sun Direction": sun, "Camera Height": camera_height, "Sun Strength": STRENGTH,
              "Scattering Scale": SCALE, "Sun Angle": math.radians(0.545), "Clouds": clouds_on,
              "Light Shafts": light_shafts,
              "Cloud Coverage": layer.coverage, "Cloud Base": layer.base, "Cloud Thickness": layer.thickness,
              "Cloud Density": layer.density, "Cloud Scale": layer.scale,
              "Cloud Offset": (layer.offset[0], layer.offset[1], 0.0)}
    for name, value in values.items():
        group.inputs[name].default_value = value
    view = skylight.write_sky_view(luts, camera_height, sun[2])
    return luts, extension_module("addon.scene.frame.cloud_map").map_ranks(map_image), (atlas, view)


def twin_sky(pkg, luts, ranks, layer, sun, camera_height, directions, atlas, light_shafts=False):
    cloud_sky = pkg.lut_gen.clouds.sky
    cos_sun_view = directions @ np.array(sun)
    atlas, sky_view = atlas
    clear = pkg.lut_gen.passes.sky_view.camera_sky(luts, sky_view, directions[..., 2], cos_sun_view) * SCALE * STRENGTH
    ground = luts.ground_radiance(camera_height, directions[..., 2], sun[2], cos_sun_view) * STRENGTH
    view = cloud_sky.view(luts, layer, ranks, camera_height, directions, np.array(sun),
                          air=pkg.lut_gen.clouds.air_map.lookup(atlas))
    return cloud_sky.composite(clear, SCALE, STRENGTH, view, ground, light_shafts).mean(axis=2), view


def sun_at(elevation, azimuth=30.0):
    el, az = math.radians(elevation), math.radians(azimuth)
    return (math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el))


# With light shafts on, camera rays leave the air's single scattering to the shafts pass.
@pytest.mark.parametrize("sun_elevation, coverage, light_shafts", [(35.0, 0.5, False), (4.0, 0.7, True)])
def test_cloudy_sky_render_matches_numpy_twin(addon_package, bake_dir, tmp_path, sun_elevation, coverage,
                                              light_shafts):
    layer = addon_package.lut_gen.clouds.layer.CloudLayer(coverage=coverage, scale=4000.0, seed=11,
                                                           offset=(300.0, -700.0))
    scene = empty_scene(width=128, height=64, samples=32)
    panorama_camera(scene)
    sun = sun_at(sun_elevation)
    luts, ranks, atlas = build_cloudy_world(addon_package, bake_dir, sun, 2.0, layer, light_shafts=float(light_shafts))
    rendered = render_rgb(scene, tmp_path / "clouds.exr")
    directions = panorama_directions(128, 64, supersample=4)
    twin, view = twin_sky(addon_package, luts, ranks, layer, sun, 2.0, directions, atlas, light_shafts)
    save_png(tmp_path / "clouds.png", rendered, exposure=1.0 / max(np.percentile(twin, 90), 1e-9))

    near_sun = (directions @ np.array(sun) > math.cos(math.radians(3.0))).any(axis=2)
    clouded = view.alpha.mean(axis=2) > 0.5
    assert 0.1 < clouded[:32].mean() < 0.95, clouded[:32].mean()       # clouds and gaps overhead
    assert np.isfinite(rendered).all() and (rendered @ LUMINANCE).mean() > 0
    err = np.abs(rendered @ LUMINANCE - twin @ LUMINANCE) / np.maximum(twin @ LUMINANCE, 1e-12)
    assert np.median(err[~near_sun]) <= 0.02, np.median(err[~near_sun])
    assert np.median(err[clouded & ~near_sun]) <= 0.03, np.median(err[clouded & ~near_sun])
    # The clouds change the picture: the twin without them is far off where they are.
    clear_layer = layer.__class__(coverage=0.0)
    clear_atlas = addon_package.lut_gen.clouds.air_map.compute(luts, clear_layer, 2.0, np.array(sun))
    clear, _ = twin_sky(addon_package, luts, ranks, clear_layer, sun, 2.0, directions, (clear_atlas, atlas[1]))
    assert np.median(np.abs(clear @ LUMINANCE - twin @ LUMINANCE)[clouded] / (twin @ LUMINANCE)[clouded]) > 0.1


def test_coverage_zero_equals_clouds_off(addon_package, bake_dir, tmp_path):
    layer = addon_package.lut_gen.clouds.layer.CloudLayer(coverage=0.0)
    scene = empty_scene(width=64, height=32, samples=4)
    panorama_camera(scene)
    sun = sun_at(20.0)
    build_cloudy_world(addon_package, bake_dir, sun, 2.0, layer, clouds_on=1.0)
    on = render_rgb(scene, tmp_path / "on.exr")
    build_cloudy_world(addon_package, bake_dir, sun, 2.0, layer, clouds_on=0.0)
    off = render_rgb(scene, tmp_path / "off.exr")
    assert off.mean() > 0
    np.testing.assert_allclose(on, off, rtol=1e-4, atol=1e-7)
