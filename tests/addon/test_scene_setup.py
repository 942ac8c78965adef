"""Operators and scene wiring: Set Up Scene on the sample, bad input leaving the scene as it was."""
import math

import numpy as np
import pytest

from render_util import empty_scene, render_rgb, save_png
from extension import extension_module, names, sample_builder

bpy = pytest.importorskip("bpy")


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("ols_cache")


@pytest.fixture
def addon(addon_package, cache_dir, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(cache_dir))
    return addon_package



def test_setup_scene_on_the_sample(addon, tmp_path):
    build = sample_builder()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    objects = build.build_sample_scene(bpy.context.scene, elevation_deg=15.0, azimuth_deg=35.0, resolution=64)
    scene = bpy.context.scene
    previous_world = scene.world
    for obj in scene.objects:
        obj.select_set(obj == objects["terrain"])
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    wiring = extension_module("addon.scene.setup.wiring")
    assert scene.world.name == names.WORLD and scene[names.PREVIOUS_WORLD] == previous_world.name
    assert objects["terrain"].active_material.name.startswith(names.TERRAIN_MATERIAL)
    # Its emission (the ambient term) is no lamp: sampled as one, each change cost a re-render
    # 0.5 s more on this terrain (bench/bench_rerender.py).
    assert objects["terrain"].active_material.cycles.emission_sampling == "NONE"
    drivers = scene.world.node_tree.animation_data.drivers
    # 7 for the sky (sun, strength, angle, height, scale) and 11 for the clouds (on, light shafts,
    # camera x, y, coverage, base, thickness, density, scale, offset x, y).
    assert len(drivers) == 18 and all(d.driver.is_valid for d in drivers)
    colour = np.array(objects["sun"].data.color)
    assert colour[0] > colour[1] > colour[2] > 0            # low sun: reddened by the atmosphere
    # Rotating the sun re-colours it (depsgraph handler) and moves the sky's sun input.
    extension_module("addon.scene.sun").set_sun_angles(objects["sun"], 60.0, 35.0)
    bpy.context.view_layer.update()
    assert np.array(objects["sun"].data.color)[2] > colour[2] * 1.5
    sky = scene.world.node_tree.nodes["OLS Sky"]
    assert sky.inputs["Sun Direction"].default_value[2] == pytest.approx(math.sin(math.radians(60.0)), abs=1e-4)
    # The sky leaves the air's single scattering under the clouds to the shafts pass only while
    # that pass runs: light scattering and light shafts both on.
    for scattering, shafts, want in ((True, True, 1.0), (False, True, 0.0), (True, False, 0.0)):
        scene.ols.enable_light_scattering, scene.ols.enable_light_shafts = scattering, shafts
        bpy.context.view_layer.update()
        assert sky.inputs["Light Shafts"].default_value == want, (scattering, shafts)
    scene.ols.enable_light_scattering = scene.ols.enable_light_shafts = True

    scene.render.resolution_x, scene.render.resolution_y = 96, 54
    scene.cycles.samples = 8
    scene.view_settings.view_transform = "Standard"
    rendered = render_rgb(scene, tmp_path / "sample.exr")
    save_png(tmp_path / "sample.png", rendered, exposure=3.0)
    assert np.isfinite(rendered).all() and rendered.min() >= 0
    sky_rows, ground_rows = rendered[:8].reshape(-1, 3), rendered[-10:].reshape(-1, 3)
    assert sky_rows.mean(axis=0)[2] > sky_rows.mean(axis=0)[0]           # blue sky
    assert ground_rows.mean() > 0.01                                       # lit terrain, not black

    wiring.unwire_scene(scene)
    assert scene.world == previous_world
    assert objects["terrain"].active_material.name == "OLS Terrain Base"


def test_setup_without_camera_changes_nothing(addon):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    worlds, lights = len(bpy.data.worlds), len(bpy.data.lights)
    with pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.ols.setup_scene(resolution="draft")
    assert scene.world is None and len(bpy.data.worlds) == worlds and len(bpy.data.lights) == lights


def camera_and_sun_scene(addon):
    """An empty scene with a scene camera and a Sun lamp: enough for the Render operator."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    camera = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    extension_module("addon.scene.sun").create_sun(scene)
    return scene


def test_render_operator_reports_bad_paths(addon, tmp_path):
    camera_and_sun_scene(addon)
    (tmp_path / "file").write_text("x")
    with pytest.raises(RuntimeError, match="Cannot write"):
        bpy.ops.ols.render(filepath=str(tmp_path / "file" / "out.png"))


def test_animate_sun_follows_the_day(addon):
    animation = extension_module("addon.scene.frame.animation")
    noon = animation.sun_angles_for_frame(50, 0, 100)
    morning = animation.sun_angles_for_frame(10, 0, 100)
    evening = animation.sun_angles_for_frame(90, 0, 100)
    assert noon[0] == pytest.approx(45.0, abs=0.01) and abs(noon[1]) < 0.01
    assert morning[0] < noon[0] and evening[0] == pytest.approx(morning[0], abs=1e-6)
    assert morning[1] * evening[1] < 0                                       # east, then west


def test_rebake_swaps_new_tables_into_a_wired_scene(addon):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build = sample_builder()
    objects = build.build_sample_scene(bpy.context.scene, resolution=32)
    scene = bpy.context.scene
    for obj in scene.objects:
        obj.select_set(obj == objects["terrain"])
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    old_key = scene[names.WIRED_KEY]
    sky_node = scene.world.node_tree.nodes["OLS Sky"]
    scene.ols.aerosol_density = 3.0
    assert bpy.ops.ols.bake_luts(resolution="draft") == {"FINISHED"}
    new_key = scene[names.WIRED_KEY]
    assert new_key != old_key
    lookup = bpy.data.node_groups["OLS Scattering Lookup"]
    used = {n.image.name for n in lookup.nodes if n.type == "TEX_IMAGE"}
    assert used == {f"OLS multiple {new_key[:8]}", f"OLS single_mie {new_key[:8]}"}
    # The wiring survived the rebuild: same group, links and drivers.
    assert sky_node.node_tree == bpy.data.node_groups["OLS Sky"]
    assert sky_node.outputs["Background"].is_linked
    assert all(d.driver.is_valid for d in scene.world.node_tree.animation_data.drivers)
    terrain_node = objects["terrain"].active_material.node_tree.nodes["OLS Terrain"]
    assert terrain_node.node_tree == bpy.data.node_groups["OLS Terrain"] and terrain_node.outputs[0].is_linked
    assert not any(i.name.startswith(f"OLS multiple {old_key[:8]}") for i in bpy.data.images)


@pytest.mark.parametrize("facing", [(0.0, 1.0, 0.0), (0.0, -1.0, 0.0)])
def test_world_lighting_matches_the_sky_it_shows(addon, tmp_path, facing):
    """With "Light Scene" on, the world lights the scene through the panorama: a white
    diffuse plane receives the hemisphere integral of the twin's sky (sun lamp off)."""
    scene = empty_scene(width=32, height=32, samples=256)
    facing = np.array(facing)
    bpy.ops.mesh.primitive_plane_add(size=10.0, location=(0.0, 0.0, 5.0))
    plane = bpy.context.active_object
    plane.rotation_euler = (math.radians(-90.0) if facing[1] > 0 else math.radians(90.0), 0.0, 0.0)
    material = bpy.data.materials.new("white")
    material.use_nodes = True
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    plane.data.materials.append(material)
    cam_data = bpy.data.cameras.new("cam")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 4.0
    camera = bpy.data.objects.new("cam", cam_data)
    camera.location = tuple(np.array([0.0, 0.0, 5.0]) + facing * 20.0)        # in front, same height
    camera.rotation_euler = (math.radians(90.0), 0.0, math.radians(180.0) if facing[1] > 0 else 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun_mod = extension_module("addon.scene.sun")
    sun = sun_mod.create_sun(scene, elevation_deg=20.0, azimuth_deg=0.0)
    directory = extension_module("addon.baking").bake_if_needed(addon.lut_gen.AtmosphereParams(), "draft")
    extension_module("addon.scene.setup.wiring").wire_scene(scene, directory, [], sun)   # Light Scene = 1
    sun.hide_render = True                                                        # sky light only
    rendered = render_rgb(scene, tmp_path / "lit.exr")
    save_png(tmp_path / "lit.png", rendered, exposure=5.0)

    luts = addon.lut_gen.load(directory)
    n = 40_000
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5 ** 0.5) * k
    d = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=-1)
    to_sun = sun_mod.direction_to_sun(sun)
    sky = luts.sky_radiance(camera.location.z, d[:, 2], to_sun[2], d @ to_sun)   # panorama's height
    ground = luts.ground_radiance(camera.location.z, d[:, 2], to_sun[2], d @ to_sun)
    world = (sky * scene.ols.scattering_scale + ground) * sun.data.energy
    irradiance = (world * np.clip(d @ facing, 0, None)[:, None]).sum(axis=0) * 4 * np.pi / n
    want = irradiance / np.pi
    got = rendered[8:24, 8:24].reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(got, want, rtol=0.05)


def test_undo_restores_the_unwired_scene_in_one_step(addon):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build = sample_builder()
    build.build_sample_scene(bpy.context.scene, resolution=32)
    bpy.data.objects["OLS Terrain"].select_set(True)
    bpy.ops.ed.undo_push(message="before setup")
    worlds_before = sorted(w.name for w in bpy.data.worlds)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    bpy.ops.ed.undo_push(message="Set Up Scene")     # what the UI does for an UNDO operator
    scene = bpy.context.scene
    assert scene.world.name == "OLS World"
    bpy.ops.ed.undo()
    scene = bpy.context.scene
    assert scene.world.name != "OLS World" and sorted(w.name for w in bpy.data.worlds) == worlds_before
    assert "ols_bake_key" not in scene
    assert bpy.data.objects["OLS Terrain"].active_material.name == "OLS Terrain Base"
    assert not any(name in bpy.data.node_groups for name in ("OLS Sky", "OLS Terrain", "OLS Scattering Lookup"))
    bpy.ops.ed.redo()
    scene = bpy.context.scene
    assert scene.world.name == "OLS World" and scene["ols_bake_key"]
    extension_module("addon.scene.sun").set_sun_angles(bpy.data.objects["OLS Sun"], 30.0, 10.0)
    bpy.context.view_layer.update()                 # handlers run on the redone data without errors
    extension_module("addon.scene.setup.wiring").refresh(scene, force=True)


def scene_state(scene):
    """What Set Up Scene may change, to compare before and after a failed run."""
    tree = scene.compositing_node_group
    return {"world": scene.world.name if scene.world else None,
            "groups": sorted(g.name for g in bpy.data.node_groups),
            "images": sorted(i.name for i in bpy.data.images),
            "materials": sorted(m.name for m in bpy.data.materials),
            "view": scene.view_settings.view_transform,
            "compositor": (tree.name, sorted(n.name for n in tree.nodes)) if tree else None,
            "keys": sorted(k for k in scene.keys() if k.startswith("ols_"))}


@pytest.mark.parametrize("damage", ["zero scale", "NaN rotation"])
def test_a_broken_sun_fails_setup_with_its_name_and_changes_nothing(addon, damage, capfd):
    """A broken sun gave "cannot convert float NaN to integer" and a half-wired scene before."""
    bpy.ops.wm.read_factory_settings()                        # the default cube, camera and light
    scene = bpy.context.scene
    bpy.ops.object.light_add(type="SUN")
    sun = bpy.context.active_object
    sun.name = "Broken Sun"
    if damage == "zero scale":
        sun.scale = (0.0, 0.0, 0.0)
    else:
        sun.rotation_euler = (float("nan"), 0.0, 0.0)
    bpy.context.view_layer.update()
    before = scene_state(scene)
    with pytest.raises(RuntimeError, match="Sun lamp 'Broken Sun' has a zero scale or a non-finite rotation"):
        bpy.ops.ols.setup_scene(resolution="draft")
    assert scene_state(scene) == before
    scene.frame_set(2)                                        # handlers run: no traceback
    assert "Traceback" not in capfd.readouterr().err


def test_setup_scene_twice_adds_nothing(addon):
    bpy.ops.wm.read_factory_settings()
    scene = bpy.context.scene
    bpy.data.objects["Cube"].select_set(True)
    bpy.ops.ols.setup_scene(resolution="draft")
    once = scene_state(scene)
    bpy.ops.ols.setup_scene(resolution="draft")
    assert scene_state(scene) == once
    assert [m.name for m in bpy.data.materials if m.name.startswith("OLS Terrain")] == ["OLS Terrain Cube"]


def test_render_operator_paths(addon, tmp_path):
    """A folder is refused, not written as "DIR.png"; an unsaved file's "//" default goes to the
    system's temporary folder instead of failing after the render."""
    import tempfile
    camera_and_sun_scene(addon)
    for folder in (str(tmp_path) + "/", str(tmp_path)):
        with pytest.raises(RuntimeError, match="is a folder"):
            bpy.ops.ols.render(filepath=folder)
    assert not (tmp_path.parent / (tmp_path.name + ".png")).exists()
    render_path = extension_module("addon.ops").render_path
    assert not bpy.data.filepath
    assert render_path("//ols_render.png") == __import__("pathlib").Path(tempfile.gettempdir()) / "ols_render.png"


def test_terrain_keeps_a_textured_base_colour(addon):
    """The terrain's own colour network (here a noise texture into the Principled BSDF's Base
    Color) feeds the OLS Terrain group's Albedo; the user's material is left as it was."""
    bpy.ops.wm.read_factory_settings()
    scene = bpy.context.scene
    cube = bpy.data.objects["Cube"]
    mine = cube.active_material
    tree = mine.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    principled = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    tree.links.new(noise.outputs["Color"], principled.inputs["Base Color"])
    before = sorted(n.bl_idname for n in tree.nodes)
    cube.select_set(True)
    for _ in range(2):                                        # again: still one texture, still linked
        assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
        ours = cube.active_material
        group = ours.node_tree.nodes["OLS Terrain"]
        assert group.inputs["Albedo"].links[0].from_node.bl_idname == "ShaderNodeTexNoise"
        assert [n.bl_idname for n in ours.node_tree.nodes].count("ShaderNodeTexNoise") == 1
        assert not any(n.type == "BSDF_PRINCIPLED" for n in ours.node_tree.nodes)
    assert sorted(n.bl_idname for n in mine.node_tree.nodes) == before
    extension_module("addon.scene.setup.wiring").unwire_scene(scene)
    assert cube.active_material == mine


@pytest.mark.parametrize("elevation", [1.5, 30.0])
def test_terrain_gets_the_lamps_exact_colour_at_a_low_sun(addon, elevation):
    """At sun 1.5 deg the lamp's blue is 4.6e-5; drivers wrote it as 0 and the terrain, which
    divides by it, turned violet. The group must see the lamp's colour in every channel."""
    build = sample_builder()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    objects = build.build_sample_scene(bpy.context.scene, elevation_deg=15.0, azimuth_deg=35.0, resolution=32)
    scene = bpy.context.scene
    for obj in scene.objects:
        obj.select_set(obj == objects["terrain"])
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    extension_module("addon.scene.sun").set_sun_angles(objects["sun"], elevation, 20.0)
    bpy.context.view_layer.update()
    lamp = np.array(objects["sun"].data.color)
    assert lamp.min() > 0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    material = objects["terrain"].active_material.evaluated_get(depsgraph)
    seen = np.array(material.node_tree.nodes["OLS Terrain"].inputs["Origin Transmittance"].default_value[:3])
    np.testing.assert_allclose(seen, lamp, rtol=1e-5)


def test_light_shaft_groups_wait_while_the_shafts_are_off(addon):
    """A rebuild costs about a second: while the shafts are off, layout controls change no
    group; turning them on builds the groups for the settings of that moment."""
    bpy.ops.wm.read_factory_settings()
    scene = bpy.context.scene
    bpy.data.objects["Cube"].select_set(True)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    group = bpy.data.node_groups["OLS Light Shafts"]
    built = group["ols_layout"]
    scene.ols.enable_light_shafts = False
    scene.ols.num_cascades = 3
    scene.ols.smooth_shadows = False
    scene.frame_set(scene.frame_current)                      # the scene handlers run
    assert group["ols_layout"] == built
    assert scene.compositing_node_group.nodes["OLS Light Shafts"].mute
    scene.ols.enable_light_shafts = True
    scene.frame_set(scene.frame_current)
    layout = bpy.data.node_groups["OLS Light Shafts"]["ols_layout"]
    assert layout != built and ", 3, " in layout and "False" in layout
    assert not scene.compositing_node_group.nodes["OLS Light Shafts"].mute


def test_a_long_brute_force_march_keeps_every_tree_small(addon):
    """Blender's nodes.new and links.new cost grows with the tree: 100 unrolled steps in one
    tree (about 3 500 links) took 15-37 s a rebuild. The march is chained through chunk groups
    of CHUNK_STEPS steps instead (the node-vs-twin tests in test_light_shafts_pass cover its
    numbers, with a rest chunk)."""
    bpy.ops.wm.read_factory_settings()
    scene = bpy.context.scene
    bpy.data.objects["Cube"].select_set(True)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    scene.ols.enable_light_shafts = True
    scene.ols.scattering_technique = "BRUTE_FORCE"
    scene.ols.single_scattering_mode = "INTEGRATION"
    scene.ols.num_integration_steps = 95
    scene.frame_set(scene.frame_current)                      # the scene handlers rebuild
    main = bpy.data.node_groups["OLS Light Shafts"]
    assert main["ols_layout"].startswith("(95, ")
    chunks = [n.node_tree.name for n in main.nodes if n.bl_idname == "CompositorNodeGroup"
              and n.node_tree.name in (names.MARCH_CHUNK_GROUP, names.MARCH_REST_GROUP)]
    assert chunks == [names.MARCH_CHUNK_GROUP] * 9 + [names.MARCH_REST_GROUP]
    assert len(bpy.data.node_groups[names.MARCH_REST_GROUP].nodes) < len(
        bpy.data.node_groups[names.MARCH_CHUNK_GROUP].nodes)
    biggest = max(bpy.data.node_groups, key=lambda tree: len(tree.links))
    assert len(biggest.links) < 1000, (biggest.name, len(biggest.links))
