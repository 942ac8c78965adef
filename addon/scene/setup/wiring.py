"""Wire a scene: the LUT images, the three node groups, the world, terrain materials, drivers.

``check_scene`` validates everything first and ``wire_scene`` only then changes the scene, so
a failure leaves it as it was. The previous world and material slots are remembered on the
scene/objects so ``unwire_scene`` restores them.
"""
from __future__ import annotations

from pathlib import Path

import bpy

from .... import lut_gen
from ... import nodes
from ...settings import Sanitized, analytic_params
from ....lut_gen.model import analytic
from ....lut_gen.tables.lookup import TABLES_WITH_MIE
from . import compositor, drivers
from ..frame import cloud_map, epipolar_tables, frame_update, shadow_maps, skylight
from ..tables import luts, wired_bake
from .. import sun as sun_lamps
from .. import clouds, names


class SetupError(Exception):
    """What is wrong with the scene and how to fix it."""


def check_scene(scene):
    if scene.camera is None:
        raise SetupError("the scene has no camera: add one (Add > Camera) and make it the scene camera")
    try:
        compositor.check_compositor(scene)
    except ValueError as exc:
        raise SetupError(str(exc)) from None


def build_groups(bake_dir, engine="CYCLES"):
    """Load the bake's images and (re)build the node groups for the render engine; returns
    (images, atmosphere params)."""
    images = luts.load_images(bake_dir)
    params, dims = lut_gen.store.exr_header.read_header_params(bake_dir)
    lookup = nodes.build_lookup_group(images["multiple"], dims, params, nodes.lookup.filtering_for_engine(engine),
                                      mie_image=images["single_mie"], fog_image=images.get("single_fog"))
    cloud_tree = nodes.build_cloud_group(clouds.ensure_map_image(clouds.seed_of(bpy.context.scene)),
                                         clouds.ensure_table_image(), skylight.ensure_cloud_air_image(), params)
    nodes.build_sky_group(images["optical_depth"], params, skylight.ensure_image(), images["ambient"],
                          skylight.ensure_ground_image(), clouds_tree=cloud_tree,
                          sky_view_image=skylight.ensure_sky_view_image())
    nodes.build_cloud_shadow_group(bpy.data.images[names.CLOUD_MAP_IMAGE])
    nodes.build_cloud_veil_group(bpy.data.images[names.CLOUD_MAP_IMAGE])
    nodes.build_terrain_group(images["optical_depth"], images["ambient"], params)
    for table in nodes.COMPOSITOR_TABLES:
        nodes.build_lookup_group(images[table], dims, params, compositor=True, name=nodes.lookup_group_name(table),
                                 mie_image=images["single_mie"] if table in TABLES_WITH_MIE else None,
                                 fog_image=images.get("single_fog") if table in TABLES_WITH_MIE else None)
    nodes.build_segment_transmittance_group(images["optical_depth"], params)
    for table in nodes.COMPOSITOR_TABLES:
        nodes.build_section_group(table, params)
    nodes.build_aerial_group(images["optical_depth"], params)
    nodes.builder.lay_out_groups()
    return images, params


def wants_analytic(scene) -> bool:
    """Whether the scene asks for the analytic model (Hoffman & Preetham): no tables."""
    ols = getattr(scene, "ols", None)
    return ols is not None and ols.atmosphere_model == "ANALYTIC"


def build_analytic_groups(scene):
    """The analytic model's sky, terrain and aerial perspective under the precomputed groups'
    names (nodes/analytic.py), and the cloud groups, which read only the cloud map; when they
    are built already, only their media. No table is read or written. Returns the params."""
    params = analytic_params(scene.ols)
    if nodes.analytic.update_media(params):         # a slider change: the numbers only
        return params
    if not nodes.analytic.restore_formula_groups(params):
        nodes.build_analytic_sky_group(params)
        nodes.build_analytic_terrain_group(params)
        nodes.build_analytic_aerial_group(params)
        nodes.builder.lay_out_groups()
        nodes.analytic.keep_formula_groups()
    cloud_map = clouds.ensure_map_image(clouds.seed_of(scene))
    if not _cloud_groups_read(cloud_map):       # both models build the same ones: kept on a switch
        nodes.build_cloud_shadow_group(cloud_map)
        nodes.build_cloud_veil_group(cloud_map)
    nodes.builder.lay_out_groups()
    return params


def _cloud_groups_read(cloud_map) -> bool:
    """Whether the cloud shadow and veil groups exist and every image they read (nested groups
    included) is ``cloud_map``."""
    def images(tree, seen):
        for node in tree.nodes:
            if getattr(node, "node_tree", None) is not None and node.node_tree.name not in seen:
                seen.add(node.node_tree.name)
                yield from images(node.node_tree, seen)
            elif hasattr(node, "image"):
                yield node.image
    groups = [bpy.data.node_groups.get(name) for name in (names.CLOUD_SHADOW_GROUP, names.CLOUD_VEIL_GROUP)]
    if any(group is None or len(group.nodes) < 3 for group in groups):
        return False
    read = [image for group in groups for image in images(group, set())]
    return bool(read) and all(image == cloud_map for image in read)


def _build_for_model(scene, bake_dir):
    """(images, params) of the groups wire_scene builds: the bake's, or none under the analytic
    model (bake_dir None)."""
    if bake_dir is None:
        return None, build_analytic_groups(scene)
    return build_groups(bake_dir, scene.render.engine)


def shaft_layout(settings, analytic_model: bool):
    """The ShaftLayout of ``settings`` (sanitized) for the tables or the analytic model."""
    return nodes.ShaftLayout.from_settings(settings, epipolar_tables.technique(settings), analytic_model)


def build_light_shafts(scene, optical_image, params, analytic_model: bool = False):
    """(Re)build the light-shaft groups for the scene's structural settings (ShaftLayout): the
    tables' (``optical_image`` their optical-depth image) or, ``analytic_model``, the analytic
    model's (``params`` its media, no image)."""
    settings = Sanitized(scene.ols)
    layout = shaft_layout(settings, analytic_model)
    atlas, table = None, None
    if layout.reads_shadow_maps:
        atlas, table = shadow_maps.ensure_images(int(settings.shadow_map_resolution), settings.num_cascades)
    elif not frame_update.rendering():
        # Nothing reads the atlas now (up to 512 MiB at 6 x 4096): drop it, but never under a
        # running render, whose copy of the compositor may still hold the old groups.
        shadow_maps.remove_images()
    else:
        shadow_maps.release_buffer()
    cloud_map = clouds.ensure_map_image(clouds.seed_of(scene)) if layout.clouds else None
    images = epipolar_tables.ensure_images(layout, settings)
    if layout.analytic:
        nodes.build_analytic_light_shaft_groups(atlas, table, params, layout, images)
    else:
        nodes.build_light_shaft_groups(optical_image, atlas, table, params, layout, images, cloud_map)
    nodes.builder.lay_out_groups()
    frame_update.forget()           # new groups may read new (empty) images: write them again


def match_light_shaft_layout(scene) -> bool:
    """Rebuild the light-shaft groups when steps, modes, cascades, PCF, cascade search or the
    shadow-map resolution changed; True when rebuilt. Not while the shafts are off: their node
    is muted and reads nothing, and a rebuild costs about a second, so it waits until they are
    turned on again."""
    group = bpy.data.node_groups.get(names.LIGHT_SHAFTS_GROUP)
    analytic_model = wired_bake.is_analytic(scene)
    info = None if analytic_model else wired_bake.bake_info(scene)
    if group is None or (info is None and not analytic_model):
        return False
    settings = Sanitized(scene.ols)
    if not (settings.enable_light_scattering and settings.enable_light_shafts):
        shadow_maps.release_buffer()
        epipolar_tables.release_buffers()
        return False
    if analytic_model and scene.get(names.PREVIEW_KEY):
        # The analytic stand-in for tables still baking: the tables' shafts wait (muted) for
        # their draft; building the analytic ones would cost 1-4 s of a preview meant to be at once.
        return False
    layout = shaft_layout(settings, analytic_model)
    if (group.get(names.LAYOUT_KEY) == layout.as_key()
            and (not layout.reads_shadow_maps
                 or shadow_maps.images_intact(bpy.data.node_groups.get(names.SHADOW_TEST_GROUP)))):
        if epipolar_tables.images_intact(layout, settings):
            return False
        if epipolar_tables.resize_images(layout, settings):   # new slices, samples or steps
            frame_update.forget()
            return False
    if analytic_model:
        build_light_shafts(scene, None, analytic_params(scene.ols), True)
    else:
        build_light_shafts(scene, bpy.data.images[luts.image_name("optical_depth", info.key)], info.params)
    compositor.link_light_shafts(scene)
    return True


def match_engine(scene) -> bool:
    """Rebuild the groups when the render engine wants the other look-up filtering (see
    nodes.lookup); True when something was rebuilt."""
    group = bpy.data.node_groups.get(names.LOOKUP_GROUP)
    if group is None or not scene.get(names.WIRED_KEY) or wired_bake.is_analytic(scene):
        return False
    if group.get(names.FILTERING_KEY) == nodes.lookup.filtering_for_engine(scene.render.engine):
        return False
    image = next((n.image for n in group.nodes if n.type == "TEX_IMAGE" and n.image), None)
    if image is None:
        return False
    build_groups(Path(bpy.path.abspath(image.filepath)).parent, scene.render.engine)
    return True


def _group_into_output(tree, group_name: str, output_type: str, group_socket: str):
    """Replace ``tree``'s nodes (and drivers) by the named group feeding an output node."""
    drivers.remove_drivers(tree)
    tree.nodes.clear()
    group = tree.nodes.new("ShaderNodeGroup")
    group.node_tree = bpy.data.node_groups[group_name]
    group.name = group_name
    output = tree.nodes.new(output_type)
    output.location = (300, 0)
    tree.links.new(group.outputs[group_socket], output.inputs["Surface"])
    return group


def _is_terrain_group(node) -> bool:
    return node.type == "GROUP" and node.node_tree is not None and node.node_tree.name == names.TERRAIN_GROUP


def _albedo_source(tree):
    """(linked socket or None, colour) that feeds the surface colour: our group's Albedo when the
    material is ours already, else the first Principled BSDF's Base Color."""
    for node in tree.nodes:
        if _is_terrain_group(node):
            socket = node.inputs["Albedo"]
            break
    else:
        socket = next((n.inputs["Base Color"] for n in tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
    if socket is None:
        return None, (0.2, 0.2, 0.2, 1.0)
    link = socket.links[0] if socket.is_linked else None
    return (link.from_socket if link else None), tuple(socket.default_value)


def _terrain_group_into(tree):
    """Our terrain group feeding the material output, fed by the tree's albedo (_albedo_source);
    shader and output nodes go, the nodes that make the colour stay."""
    source, colour = _albedo_source(tree)
    drivers.remove_drivers(tree)
    for node in list(tree.nodes):
        if _is_terrain_group(node) or node.type in {"OUTPUT_MATERIAL", "BSDF_PRINCIPLED"}:
            tree.nodes.remove(node)
    group = tree.nodes.new("ShaderNodeGroup")
    group.node_tree = bpy.data.node_groups[names.TERRAIN_GROUP]
    group.name = names.TERRAIN_GROUP
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    output.location = (300, 0)
    tree.links.new(group.outputs["Shader"], output.inputs["Surface"])
    group.inputs["Albedo"].default_value = colour
    if source is not None:
        tree.links.new(source, group.inputs["Albedo"])
    return group


def set_origin_transmittance(group, colour):
    """The terrain group's "Origin Transmittance" = the lamp's colour, written by the handlers
    with the colour itself. Not a driver: Blender 5.0 drivers write values under about 1e-4 as
    0 (the blue of a sun 1.5 deg up is 4.6e-5), and the terrain divided by that floor: its
    mountains turned violet at sunset."""
    socket = group.inputs["Origin Transmittance"]
    wanted = (*colour[:3], 1.0)
    if any(abs(a - b) > 1e-6 * max(abs(b), 1e-12) for a, b in zip(socket.default_value, wanted)):
        socket.default_value = wanted


def wire_world(scene, sun, light_scene: float):
    world = bpy.data.worlds.get(names.WORLD) or bpy.data.worlds.new(names.WORLD)
    if scene.world is not None and scene.world != world:
        scene[names.PREVIOUS_WORLD] = scene.world.name
    scene.world = world
    if world.node_tree is None:
        world.use_nodes = True
    group = _group_into_output(world.node_tree, names.SKY_GROUP, "ShaderNodeOutputWorld", "Background")
    group.inputs["Light Scene"].default_value = light_scene
    # When the world does not light the scene, Cycles need not sample it as a light at all. When
    # it does, its importance map is sized by hand: AUTOMATIC sizes it from the largest image in
    # the world, our 4D atlas, and evaluated the world shader for the whole map before every
    # render (1.5 s of the sample's 6.5 s at 480 x 270). Lighting rays read the panorama, so a
    # map of its width resolves all there is to sample (the sun is its own lamp).
    world.cycles.sampling_method = "MANUAL" if light_scene > 0 else "NONE"
    world.cycles.sample_map_resolution = skylight.SIZE[0]
    for ray in ("diffuse", "scatter", "transmission"):
        setattr(world.cycles_visibility, ray, light_scene > 0)
    drivers.drive_sun_direction(group.inputs["Sun Direction"], sun)
    drivers.drive_from_lamp(group.inputs["Sun Strength"], sun, "energy")
    drivers.drive_from_lamp(group.inputs["Sun Angle"], sun, "angle")
    drivers.drive_camera_height(group.inputs["Camera Height"], scene)
    drivers.drive_scene_setting(group.inputs["Scattering Scale"], scene, "scattering_scale")
    clouds.drive_sky_inputs(group, scene)
    return world


def wire_terrain(obj, sun):
    """Give ``obj`` an "OLS Terrain" material that keeps the albedo of its old material: a copy of
    it whose Principled BSDF is replaced by our group, fed by whatever fed its Base Color (a
    texture network stays as it is)."""
    previous = obj.active_material
    if previous is not None and previous.get(names.GENERATED):
        material = previous             # set up again: rebuild ours, no "OLS Terrain X.001"
    elif previous is not None and previous.node_tree is not None:
        material = previous.copy()
        material.name = f"{names.TERRAIN_MATERIAL} {obj.name}"
    else:
        material = bpy.data.materials.new(f"{names.TERRAIN_MATERIAL} {obj.name}")
    material.use_nodes = True
    # The emission is the terrain's own reflected skylight (the sample's ambient term), not a
    # lamp: Cycles need not sample it as a light. Left on, every sun or setting change made
    # Cycles re-estimate the emission of each terrain triangle, 0.5 s per render on the
    # 130 000-triangle sample (of 0.8 s). Rays that hit the terrain still see it.
    material.cycles.emission_sampling = "NONE"
    group = _terrain_group_into(material.node_tree)
    drivers.drive_sun_direction(group.inputs["Sun Direction"], sun)
    drivers.drive_from_lamp(group.inputs["Sun Strength"], sun, "energy")
    set_origin_transmittance(group, sun.data.color)
    material[names.GENERATED] = True
    if previous is not None and not previous.get(names.GENERATED):
        obj[names.PREVIOUS_MATERIAL] = previous.name
    if obj.material_slots:
        obj.material_slots[obj.active_material_index].material = material
    else:
        obj.data.materials.append(material)
    return material


def wire_scene(scene, bake_dir, terrain_objects=(), sun=None, resolution="default"):
    """Everything ``Set up scene`` does, for a bake directory that already holds the tables, or
    for the analytic model with ``bake_dir`` None. Returns the sun lamp used."""
    check_scene(scene)
    sun = sun or sun_lamps.find_sun(scene)
    if sun is not None:
        try:
            sun_lamps.direction_to_sun(sun)
        except sun_lamps.SunError as exc:
            raise SetupError(str(exc)) from None
    images, params = _build_for_model(scene, bake_dir)   # may raise: scene untouched so far
    was_wired = bool(scene.get(names.WIRED_KEY))
    try:
        return _wire_checked(scene, bake_dir, images, params, terrain_objects, sun, resolution)
    except Exception:
        # Nothing half-applied: put back what the scene had (world, materials, compositor, view).
        if not was_wired:
            unwire_scene(scene)
        luts.release_unused_images()
        raise


def _wire_checked(scene, bake_dir, images, params, terrain_objects, sun, resolution):
    sun = sun or sun_lamps.create_sun(scene)
    terrain_objects = [o for o in terrain_objects if o.type == "MESH"]
    # With terrain materials the sky lights the scene through their ambient term (the sample's
    # model); the world then lights only camera and glossy rays, so nothing counts twice.
    wire_world(scene, sun, light_scene=0.0 if terrain_objects else 1.0)
    for obj in terrain_objects:
        wire_terrain(obj, sun)
    clouds.wire(scene, sun)
    build_light_shafts(scene, None if images is None else images["optical_depth"], params, images is None)
    compositor.wire_compositor(scene)
    scene[names.WIRED_KEY] = (names.ANALYTIC_WIRED if bake_dir is None
                              else lut_gen.store.exr_read.verify_bake(bake_dir))     # verified by build_groups: cached
    scene[names.RESOLUTION_KEY] = resolution
    refresh(scene, force=True)
    luts.release_unused_images()
    return sun


def refresh(scene, force=False):
    """Bring what depends on the sun and camera up to date: the lamp's colour (extinction at
    the origin) and the lighting panorama."""
    info = wired_bake.bake_info(scene)
    sun = sun_lamps.find_sun(scene)
    if wired_bake.is_analytic(scene) and sun is not None:
        _refresh_analytic(scene, sun)
        return
    if info is None or sun is None:
        return
    _refresh_lamp_and_groups(scene, sun, info.origin_transmittance)
    position = scene.camera.matrix_world.translation if scene.camera else (0.0, 0.0, 0.0)
    skylight.update(info, sun_lamps.direction_to_sun(sun), position[2], force, clouds=cloud_map.numpy_layer(scene),
                    camera_xy=(position[0], position[1]))


def _refresh_analytic(scene, sun):
    """refresh under the analytic model: the lamp's colour is the model's sun extinction at the
    origin (Hoffman & Preetham Eq. 5); its groups read no panorama."""
    media = analytic.media(analytic_params(scene.ols))
    _refresh_lamp_and_groups(scene, sun, lambda cos_sun: analytic.sun_transmittance(media, cos_sun))


def _refresh_lamp_and_groups(scene, sun, origin_transmittance):
    """The lamp's colour from ``origin_transmittance`` (cos sun zenith -> RGB), the terrain
    materials' copy of it, the compositor's settings, the frame values and the cloud layer."""
    sun_lamps.update_sun_colour(sun, origin_transmittance)
    for material in bpy.data.materials:
        group = material.node_tree.nodes.get(names.TERRAIN_GROUP) if material.get(names.GENERATED) and material.node_tree else None
        if group is not None:
            set_origin_transmittance(group, sun.data.color)
    compositor.sync_settings(scene)
    frame_update.write_frame_values(scene)
    clouds.repair(scene)


def use_model(scene, bake_dir=None, shafts: bool = True):
    """Switch a wired scene between the models: to the analytic groups (``bake_dir`` None) or to
    the tables in ``bake_dir``, with the light-shaft groups of that model. ``shafts`` False (the
    analytic stand-in while tables bake, a few seconds): the shaft groups are left as they are,
    and a group of the other model stays muted (compositor.sync_settings)."""
    if bake_dir is None:
        params = build_analytic_groups(scene)
        scene[names.WIRED_KEY] = names.ANALYTIC_WIRED
        if names.PREVIEW_KEY in scene:
            del scene[names.PREVIEW_KEY]
        if shafts:
            _match_model_shafts(scene, None, params)
        refresh(scene, force=True)
        return
    images, params = build_groups(bake_dir, scene.render.engine)
    scene[names.WIRED_KEY] = lut_gen.store.exr_read.verify_bake(bake_dir)
    _match_model_shafts(scene, images["optical_depth"], params)
    refresh(scene, force=True)
    luts.release_unused_images()


def _match_model_shafts(scene, optical_image, params):
    """After a switch of model (or a media slider under the analytic model): the light-shaft
    groups of the model the scene is wired to. The shafts read the media through the media
    group, so a slider rebuilds nothing here; a switch rebuilds them (their air differs), even
    while the shafts are off, so no group of the other model is left in the compositor."""
    group = bpy.data.node_groups.get(names.LIGHT_SHAFTS_GROUP)
    layout = shaft_layout(Sanitized(scene.ols), optical_image is None)
    if group is not None and group.get(names.LAYOUT_KEY) == layout.as_key():
        return
    build_light_shafts(scene, optical_image, params, optical_image is None)
    compositor.link_light_shafts(scene)


def forget_caches():
    wired_bake.forget()
    frame_update.forget()
    skylight.forget()


def unwire_scene(scene):
    """Restore the world, materials and compositor the scene had before wiring."""
    compositor.unwire_compositor(scene)
    clouds.remove_shadow_layer()
    if not any(other.get(names.WIRED_KEY) for other in bpy.data.scenes if other != scene):
        shadow_maps.remove_images(names.FRAME_IMAGE, *epipolar_tables.ALL_IMAGES)
        epipolar_tables.release_buffers()
    previous = scene.get(names.PREVIOUS_WORLD)
    scene.world = bpy.data.worlds.get(previous) if previous else None
    for obj in scene.objects:
        name = obj.get(names.PREVIOUS_MATERIAL)
        if name and name in bpy.data.materials and obj.material_slots:
            obj.material_slots[obj.active_material_index].material = bpy.data.materials[name]
            del obj[names.PREVIOUS_MATERIAL]
    for key in (names.PREVIOUS_WORLD, names.WIRED_KEY, names.RESOLUTION_KEY, names.PREVIEW_KEY):
        if key in scene:
            del scene[key]
