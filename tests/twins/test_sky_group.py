"""The "OLS Sky" world group rendered by Cycles vs its numpy twin (lut_gen.passes.sky_view.camera_sky)."""
import math

import numpy as np
import pytest

from render_util import empty_scene, panorama_camera, panorama_directions, render_rgb, save_png, world_of_group
from extension import extension_module

bpy = pytest.importorskip("bpy")

STRENGTH, SCALE = 10.0, 0.5


@pytest.fixture(scope="module")
def bake_dir(tmp_path_factory):
    import lut_gen
    directory = tmp_path_factory.mktemp("luts")
    lut_gen.save(lut_gen.bake(resolution="draft"), directory)
    return directory


# A 1 km fog 50 m deep: the camera 2 m up inside it, 500 m up above it.
FOG = {"fog_visibility": 1000.0, "fog_height": 50.0}


@pytest.fixture(scope="module")
def fog_bake_dir(tmp_path_factory):
    import lut_gen
    directory = tmp_path_factory.mktemp("fog_luts")
    lut_gen.save(lut_gen.bake(lut_gen.AtmosphereParams(**FOG), resolution="draft"), directory)
    return directory


def build_world(pkg, bake_dir, sun_direction, camera_height, filtering="HARDWARE"):
    scene = bpy.context.scene
    images = extension_module("addon.scene.tables.luts").load_images(bake_dir)
    luts = pkg.lut_gen.load(bake_dir)
    nodes = extension_module("addon.nodes")
    nodes.build_lookup_group(images["multiple"], luts.dims, luts.params, filtering, mie_image=images["single_mie"],
                             fog_image=images.get("single_fog"))
    skylight = extension_module("addon.scene.frame.skylight")
    sky = nodes.build_sky_group(images["optical_depth"], luts.params, skylight.ensure_image(), images["ambient"],
                                skylight.ensure_ground_image(), sky_view_image=skylight.ensure_sky_view_image())
    group = world_of_group(scene, sky)
    group.inputs["Sun Direction"].default_value = sun_direction
    group.inputs["Camera Height"].default_value = camera_height
    group.inputs["Sun Strength"].default_value = STRENGTH
    group.inputs["Scattering Scale"].default_value = SCALE
    group.inputs["Sun Angle"].default_value = math.radians(0.545)
    return luts, skylight.write_sky_view(luts, camera_height, sun_direction[2])


# MANUAL: the GPU engines' filtering (texel centres blended in the tree), rendered by Cycles.
@pytest.mark.parametrize("sun_elevation, camera_height, fog, filtering", [
    (40.0, 2.0, False, "HARDWARE"), (6.0, 500.0, False, "HARDWARE"), (-4.0, 2.0, False, "HARDWARE"),
    (-4.0, 2.0, False, "MANUAL"), (20.0, 2.0, True, "HARDWARE"), (8.0, 500.0, True, "HARDWARE")])
def test_sky_render_matches_numpy_twin(addon_package, request, tmp_path, sun_elevation, camera_height, fog, filtering):
    bake_dir = request.getfixturevalue("fog_bake_dir" if fog else "bake_dir")
    scene = empty_scene(width=128, height=64, samples=16)
    panorama_camera(scene)
    el, az = math.radians(sun_elevation), math.radians(30.0)
    sun = (math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el))
    luts, view = build_world(addon_package, bake_dir, sun, camera_height, filtering)
    rendered = render_rgb(scene, tmp_path / "sky.exr")

    d = panorama_directions(128, 64, supersample=4)
    cos_sun_view = d @ np.array(sun)
    twin = (addon_package.lut_gen.passes.sky_view.camera_sky(luts, view, d[..., 2], cos_sun_view) * SCALE
            + luts.ground_radiance(camera_height, d[..., 2], sun[2], cos_sun_view)).mean(axis=2) * STRENGTH
    save_png(tmp_path / "sky.png", rendered, exposure=1.0 / max(np.percentile(twin, 90), 1e-9))

    near_sun = (cos_sun_view > math.cos(math.radians(3.0))).any(axis=2)   # disc pixels: twin has no disc
    lum = lambda rgb: rgb @ np.array([0.2126, 0.7152, 0.0722])
    assert lum(rendered).mean() > 0 and np.isfinite(rendered).all()
    err = np.abs(lum(rendered) - lum(twin)) / np.maximum(lum(twin), 1e-12)
    assert np.median(err[~near_sun]) <= 0.02
    channel_err = np.abs(rendered - twin) / np.maximum(twin, 1e-12)
    assert np.median(channel_err[~near_sun]) <= 0.02
    # Where the twilight correction matters, the render follows it (the group adds it).
    plain = (luts.sky_radiance(camera_height, d[..., 2], sun[2], cos_sun_view) * SCALE
             + luts.ground_radiance(camera_height, d[..., 2], sun[2], cos_sun_view)).mean(axis=2) * STRENGTH
    corrected = np.abs(lum(twin) - lum(plain)) > 0.03 * lum(twin)
    print("pixels corrected by over 3%:", corrected.sum())
    if sun_elevation < 0:
        assert corrected.sum() >= 20
    if corrected.sum() >= 20:
        off_plain = np.abs(lum(rendered) - lum(plain)) / lum(plain)
        assert np.median(err[corrected]) < 0.5 * np.median(off_plain[corrected])
    if sun_elevation > 0 and not (fog and camera_height < 50):       # blue sky overhead (white in the fog)
        top = rendered[: 64 // 4].reshape(-1, 3).mean(axis=0)
        assert top[2] > top[1] > top[0]


def test_sun_disc_is_attenuated_sunlight(addon_package, bake_dir, tmp_path):
    """The disc integrates to the lamp's strength times the transmittance to the top."""
    scene = empty_scene(width=64, height=64, samples=64)
    cam_data = bpy.data.cameras.new("narrow")
    cam_data.type = "ORTHO"
    camera = bpy.data.objects.new("narrow", cam_data)
    scene.collection.objects.link(camera)
    scene.camera = camera
    cam_data.type = "PERSP"
    cam_data.sensor_width = 36.0
    cam_data.lens = 36.0 / (2 * math.tan(math.radians(1.0)))     # 2 deg field of view
    el = math.radians(20.0)
    sun = (0.0, math.cos(el), math.sin(el))
    camera.rotation_euler = (math.pi / 2 + el, 0.0, 0.0)
    luts, view = build_world(addon_package, bake_dir, sun, 2.0)
    rendered = render_rgb(scene, tmp_path / "disc.exr")
    pixel_solid_angle = (2 * math.tan(math.radians(1.0)) / 64) ** 2
    sky = addon_package.lut_gen.passes.sky_view.camera_sky(luts, view, sun[2], 1.0) * STRENGTH * SCALE
    disc_irradiance = ((rendered - sky).clip(0) * pixel_solid_angle).sum(axis=(0, 1))
    want = luts.transmittance_to_top(2.0, sun[2]) * STRENGTH
    np.testing.assert_allclose(disc_irradiance, want, rtol=0.05)
