"""The analytic model's node groups (addon/nodes/analytic.py) rendered by Cycles vs their numpy
twins in lut_gen.model.analytic: the sky on a panorama, the aerial perspective on the sample's
terrain. No tables are baked."""
import math

import numpy as np
import pytest

from render_util import empty_scene, panorama_camera, panorama_directions, render_rgb, save_png, world_of_group
from scenes import compositor_output, depth_image, refuse_tables, sample_scene
from extension import extension_module

bpy = pytest.importorskip("bpy")

STRENGTH, SCALE = 10.0, 0.5
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@pytest.mark.parametrize("sun_elevation, camera_height", [(40.0, 2.0), (6.0, 500.0), (2.0, 2.0)])
def test_analytic_sky_matches_its_twin(addon_package, tmp_path, sun_elevation, camera_height):
    pkg = addon_package
    params = pkg.lut_gen.AtmosphereParams()
    scene = empty_scene(width=64, height=32, samples=4)
    panorama_camera(scene)
    el, az = math.radians(sun_elevation), math.radians(30.0)
    sun = (math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el))
    group = world_of_group(scene, extension_module("addon.nodes").build_analytic_sky_group(params))
    for name, value in (("Sun Direction", sun), ("Camera Height", camera_height), ("Sun Strength", STRENGTH),
                        ("Scattering Scale", SCALE), ("Sun Angle", math.radians(0.545))):
        group.inputs[name].default_value = value
    rendered = render_rgb(scene, tmp_path / "sky.exr")

    analytic = pkg.lut_gen.model.analytic
    d = panorama_directions(64, 32, supersample=4)
    air, ground = analytic.sky_parts(analytic.media(params), camera_height, d, np.array(sun))
    twin = ((air * SCALE + ground) * STRENGTH).mean(axis=2)
    save_png(tmp_path / "sky.png", rendered, exposure=1.0 / max(np.percentile(twin, 90), 1e-9))
    near_sun = ((d @ np.array(sun)) > math.cos(math.radians(3.0))).any(axis=2)     # the disc: not in the twin
    # not a black sky: the twin's is lit, and so is the render
    assert (twin @ LUMINANCE).mean() > 1e-3 and np.isfinite(rendered).all()
    assert (rendered @ LUMINANCE).mean() > 0.5 * (twin @ LUMINANCE).mean()
    err = np.abs(rendered - twin) / np.maximum(twin, 1e-6)
    print(f"analytic sky {sun_elevation} deg, {camera_height} m: median {np.median(err[~near_sun]):.2e}, "
          f"p99 {np.percentile(err[~near_sun], 99):.2e}")
    assert np.median(err[~near_sun]) <= 0.02
    assert np.percentile(err[~near_sun], 90) <= 0.05
    top = rendered[: 32 // 4].reshape(-1, 3).mean(axis=0)
    if sun_elevation > 30:
        assert top[2] > top[1] > top[0]                                      # blue overhead
    else:
        # E_sun is the sun's extinction at the camera, for every point of the sky (the seed's
        # model): a low sun reddens the whole sky, the zenith too (docs/analytic.md)
        assert top[0] > top[2]
    if camera_height > 100:                                                  # the lit ground below
        assert (rendered[-4:] @ LUMINANCE).mean() > 0.05 * (rendered[:4] @ LUMINANCE).mean()


def test_analytic_aerial_perspective_matches_its_twin(addon_package, tmp_path):
    pkg = addon_package
    scene = sample_scene(pkg)
    scene.view_layers[0].use_pass_position = True
    scene.view_layers[0].use_pass_z = True
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    scene.cycles.samples = 4
    scene.cycles.seed = 3
    params = pkg.lut_gen.AtmosphereParams(aerosol_density=2.0)
    aerial_group = extension_module("addon.nodes").build_analytic_aerial_group(params)
    sun_mod = extension_module("addon.scene.sun")
    camera = np.array(scene.camera.matrix_world.translation)
    sun = sun_mod.direction_to_sun(sun_mod.find_sun(scene))

    raw = render_rgb(scene, tmp_path / "raw.exr")
    compositor_output(scene, lambda tree, layers: layers.outputs["Position"])
    position = render_rgb(scene, tmp_path / "position.exr", composite=True)
    compositor_output(scene, depth_image)
    depth = render_rgb(scene, tmp_path / "depth.exr", composite=True)[..., 0]

    def aerial(tree, layers):
        node = tree.nodes.new("CompositorNodeGroup")
        node.node_tree = aerial_group
        for name in ("Image", "Position", "Depth"):
            tree.links.new(layers.outputs[name], node.inputs[name])
        node.inputs["Camera Position"].default_value = camera
        node.inputs["Sun Direction"].default_value = sun
        node.inputs["Sun Strength"].default_value = STRENGTH
        node.inputs["Scattering Scale"].default_value = SCALE
        return node.outputs["Image"]
    compositor_output(scene, aerial)
    seen = render_rgb(scene, tmp_path / "aerial.exr", composite=True)
    save_png(tmp_path / "aerial.png", seen, exposure=1.0 / max(np.percentile(seen, 90), 1e-9))

    geometry = depth < 1e9
    assert geometry.mean() > 0.3 and (~geometry).mean() > 0.1
    analytic = pkg.lut_gen.model.analytic
    twin, transmittance, inscatter = analytic.aerial_perspective(analytic.media(params), camera, position[geometry],
                                                     raw[geometry], sun, STRENGTH, SCALE)
    err = np.abs(seen[geometry] - twin) / np.maximum(twin, 1e-6)
    print(f"analytic aerial: median {np.median(err):.2e}, p99 {np.percentile(err, 99):.2e}")
    # Measured: median 4e-8, p99 9e-7 (closed forms, float32 against float64). Tight, as for the
    # precomputed pass: a 2% bound would let a wrong density or phase through.
    assert np.median(err) <= 1e-4
    assert np.percentile(err, 99) <= 1e-3
    np.testing.assert_array_equal(seen[~geometry], raw[~geometry])          # the sky passes through
    far = geometry & (depth > np.percentile(depth[geometry], 75))
    assert (seen[far] - raw[far]).mean() > 0.02 * raw[far].mean()          # distant terrain gains air light
    far_t = transmittance[far[geometry]]
    assert (far_t[:, 0] > far_t[:, 2]).all() and far_t[:, 2].mean() < 0.95   # and blue fades first


def _add_plane(name, size, location, rotation=(0.0, 0.0, 0.0)):
    bpy.ops.mesh.primitive_plane_add(size=size, location=location, rotation=rotation)
    obj = bpy.context.active_object
    obj.name = name
    material = bpy.data.materials.new(name + " base")
    material.use_nodes = True
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.5, 0.4, 0.3, 1.0)
    obj.data.materials.append(material)
    return obj


def test_analytic_terrain_matches_its_twin_with_no_tables(addon_package, tmp_path, monkeypatch):
    """Wired by wire_scene under the analytic model, with an empty read-only cache: the terrain
    against analytic.terrain_radiance, and no table file read or written."""
    cache = refuse_tables(monkeypatch, tmp_path)
    scene = empty_scene(width=96, height=48, samples=32)
    flat = _add_plane("flat", 200.0, (-150.0, 0.0, 0.0))
    tilted = _add_plane("tilted", 200.0, (150.0, 0.0, 80.0), rotation=(math.radians(-40.0), 0.0, 0.0))
    cam_data = bpy.data.cameras.new("top")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 600.0
    camera = bpy.data.objects.new("top", cam_data)
    camera.location = (0.0, 0.0, 1000.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun_mod = extension_module("addon.scene.sun")
    sun = sun_mod.create_sun(scene, elevation_deg=30.0, azimuth_deg=0.0)
    scene.ols.atmosphere_model = "ANALYTIC"
    extension_module("addon.scene.setup.wiring").wire_scene(scene, None, [flat, tilted], sun)
    rendered = render_rgb(scene, tmp_path / "terrain.exr")
    save_png(tmp_path / "terrain.png", rendered, exposure=2.0)
    assert list(cache.iterdir()) == []
    assert not [image.name for image in bpy.data.images if image.filepath.endswith(".exr")]

    analytic = addon_package.lut_gen.model.analytic
    media = analytic.media(addon_package.lut_gen.AtmosphereParams())
    to_sun = sun_mod.direction_to_sun(sun)
    np.testing.assert_allclose(sun.data.color, analytic.sun_transmittance(media, to_sun[2]), rtol=1e-3)

    def region(x_centre, half=40.0):
        cols = slice(int((x_centre - half + 300) / 600 * 96), int((x_centre + half + 300) / 600 * 96))
        rows = slice(int((150 - half) / 300 * 48), int((150 + half) / 300 * 48))
        return rendered[rows, cols].reshape(-1, 3)

    albedo = np.array([0.5, 0.4, 0.3])
    tilted_normal = np.array(tilted.matrix_world.to_3x3().col[2])
    for pixels, position, normal in ((region(-150.0), [-150.0, 0, 0], [0.0, 0, 1]),
                                     (region(150.0), [150.0, 0, 80.0], tilted_normal)):
        want = analytic.terrain_radiance(media, np.array(position), np.array(normal), to_sun, sun.data.energy, albedo)
        err = np.abs(pixels - want) / want
        print(f"analytic terrain at {position}: median {np.median(err):.2e}")
        assert np.median(err) <= 0.02, (np.median(pixels, axis=0), want)
    assert region(150.0).mean() > region(-150.0).mean() > 0.05       # lit, and the tilted plane faces the sun
