"""The cloud layer's images and settings in the .blend: the cloud map (from the seed) and the
higher-orders table, both packed into the file so that every farm worker renders the same
clouds (the numpy code reads them through frame/cloud_map.py)."""
from __future__ import annotations

import bpy
import numpy as np

from ...lut_gen.clouds import field, slab
from ...lut_gen.clouds.layer import RANGES
from . import names
from . import sun as sun_lamps
from .setup import drivers

# Cloud-group input <- scene.ols control, shared by the sky group (as "Cloud <input>") and the
# shadow layer's group (which has no Base: its plane sits at the layer's height). The offset's
# two components are driven one by one.
CLOUD_CONTROLS = {"Coverage": "cloud_coverage", "Base": "cloud_base", "Thickness": "cloud_thickness",
                  "Density": "cloud_density", "Scale": "cloud_scale"}



def _float_image(name, width, height):
    image = bpy.data.images.get(name)
    if image is None or tuple(image.size) != (width, height) or not image.is_float:
        if image is not None:
            bpy.data.images.remove(image)
        image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
        image.colorspace_settings.is_data = True
    return image


def _fill(image, rgba):
    image.pixels.foreach_set(np.ascontiguousarray(rgba, dtype=np.float32).ravel())
    image.update()
    image.pack()


def _map_intact(image, seed) -> bool:
    return (image.get(names.CLOUD_SEED_KEY) == int(seed) and image.packed_file is not None and image.has_data
            and tuple(image.size) == (field.MAP_SIZE, field.MAP_SIZE))


def ensure_map_image(seed: int):
    """The "OLS Cloud Map" image for ``seed``: generated (0.36 s) only when the seed changed or
    the image is missing or damaged (the seed makes the same map again), and every cloud group
    pointed at it."""
    image = _float_image(names.CLOUD_MAP_IMAGE, field.MAP_SIZE, field.MAP_SIZE)
    if not _map_intact(image, seed):
        ranks = field.cloud_map(int(seed))
        rgba = np.ones(ranks.shape + (4,), dtype=np.float32)
        rgba[..., :3] = ranks[..., None]
        _fill(image, rgba)
        image[names.CLOUD_SEED_KEY] = int(seed)
    _point_groups_at(image)
    return image


def _point_groups_at(image):
    """Image nodes of the cloud groups that lost the map (deleted, replaced) read it again."""
    for group_name in (names.CLOUDS_GROUP, names.CLOUD_SHADOW_GROUP, names.SHADOW_TEST_GROUP,
                       names.CLOUD_VEIL_STEP_GROUP):
        tree = bpy.data.node_groups.get(group_name)
        if tree is None:
            continue
        for node in tree.nodes:
            if (node.bl_idname in ("ShaderNodeTexImage", "CompositorNodeImage") and node.label == names.CLOUD_MAP_IMAGE
                    and node.image != image):
                node.image = image


def ensure_table_image():
    pixels = slab.table_pixels()
    image = _float_image(names.CLOUD_TABLE_IMAGE, pixels.shape[1], pixels.shape[0])
    image.alpha_mode = "CHANNEL_PACKED"     # the alpha is the log series' fourth term
    _fill(image, pixels)
    return image



def seed_of(scene) -> int:
    settings = getattr(scene, "ols", None)
    return 0 if settings is None else int(settings.cloud_seed)


def drive_sky_inputs(group, scene):
    """Drivers from scene.ols onto the sky group's cloud inputs, clamped as the controls are:
    keyframed controls (the offset, for wind) then animate the clouds in every render, farm
    chunks included."""
    drivers.drive_switch(group.inputs["Clouds"], scene, "clouds_enabled")
    # The shafts pass runs (and redoes the air's single scattering) only with light scattering on.
    drivers.drive_expression(group.inputs["Light Shafts"], "default_value", None,
                             {"scattering": (scene, "SCENE", "ols.enable_light_scattering"),
                              "shafts": (scene, "SCENE", "ols.enable_light_shafts")},
                             "1.0 if scattering and shafts else 0.0")
    for axis in range(2):
        drivers.drive_camera_axis(group.inputs["Camera XY"], axis, scene)
    _drive_cloud_controls(group, scene, "Cloud ")


def _drive_cloud_controls(group, scene, prefix: str):
    """Drivers from the cloud controls onto those of ``group``'s inputs named prefix + input."""
    for socket, name in CLOUD_CONTROLS.items():
        if prefix + socket in group.inputs:
            drivers.drive_scene_setting(group.inputs[prefix + socket], scene, name)
    for axis in range(2):
        drivers.drive_vector_setting(group.inputs[prefix + "Offset"], axis, scene, "cloud_offset")


# The shadow layer's half size: it must hold the sun line of every point the camera sees
# shadowed, up to ~25 km away at a 4 deg sun under a 1.8 km layer, and beyond.
SHADOW_LAYER_HALF_SIZE = 100_000.0


def _shadow_mesh():
    mesh = bpy.data.meshes.get(names.CLOUD_SHADOW_OBJECT) or bpy.data.meshes.new(names.CLOUD_SHADOW_OBJECT)
    if len(mesh.vertices) != 4:
        h = SHADOW_LAYER_HALF_SIZE
        mesh.clear_geometry()
        mesh.from_pydata([(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)], [], [(0, 1, 2, 3)])
    return mesh


def _shadow_material(sun, scene):
    material = bpy.data.materials.get(names.CLOUD_SHADOW_MATERIAL) or bpy.data.materials.new(names.CLOUD_SHADOW_MATERIAL)
    material[names.GENERATED] = True
    material.use_nodes = True
    tree = material.node_tree
    drivers.remove_drivers(tree)
    tree.nodes.clear()
    group = tree.nodes.new("ShaderNodeGroup")
    group.node_tree = bpy.data.node_groups[names.CLOUD_SHADOW_GROUP]
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(group.outputs["Shader"], output.inputs["Surface"])
    drivers.drive_sun_direction(group.inputs["Sun Direction"], sun)
    _drive_cloud_controls(group, scene, "")
    # EEVEE: shadows through the material's transparency.
    if hasattr(material, "use_transparent_shadow"):
        material.use_transparent_shadow = True
    if hasattr(material, "surface_render_method"):
        material.surface_render_method = "DITHERED"
    return material


def ensure_shadow_layer(scene, sun):
    """The shadow-only plane at the clouds' middle height (driven from Base and Thickness)."""
    obj = bpy.data.objects.get(names.CLOUD_SHADOW_OBJECT)
    if obj is None:
        obj = bpy.data.objects.new(names.CLOUD_SHADOW_OBJECT, _shadow_mesh())
    if obj.name not in scene.collection.objects:
        scene.collection.objects.link(obj)
    obj[names.GENERATED] = True
    obj.data.materials.clear()
    obj.data.materials.append(_shadow_material(sun, scene))
    for ray in ("camera", "diffuse", "glossy", "transmission", "volume_scatter"):
        setattr(obj, f"visible_{ray}", False)
    obj.visible_shadow = True
    obj.hide_select = True
    obj.driver_remove("location", 2)
    (_, *base), (_, *thickness) = RANGES["base"], RANGES["thickness"]
    drivers.drive_expression(obj, "location", 2, {"b": (scene, "SCENE", "ols.cloud_base"),
                                                  "t": (scene, "SCENE", "ols.cloud_thickness")},
                             f"min(max(b, {base[0]!r}), {base[1]!r}) + 0.5 * min(max(t, {thickness[0]!r}), {thickness[1]!r})")
    return obj


def remove_shadow_layer():
    obj = bpy.data.objects.get(names.CLOUD_SHADOW_OBJECT)
    if obj is not None:
        mesh = obj.data
        bpy.data.objects.remove(obj)
        if mesh is not None and mesh.users == 0:
            bpy.data.meshes.remove(mesh)
    material = bpy.data.materials.get(names.CLOUD_SHADOW_MATERIAL)
    if material is not None and material.users == 0:
        bpy.data.materials.remove(material)


def wire(scene, sun):
    """Set Up Scene's part: the map for the seed, and the shadow layer while clouds are on."""
    ensure_map_image(seed_of(scene))
    if scene.ols.clouds_enabled and sun is not None:
        ensure_shadow_layer(scene, sun)
    else:
        remove_shadow_layer()


def sync(scene):
    """After Clouds or the seed changed on a set-up scene: the map for the seed, the shadow
    layer in or out (the groups read the image in place)."""
    if not scene.get(names.WIRED_KEY) or bpy.data.node_groups.get(names.CLOUD_SHADOW_GROUP) is None:
        return
    if scene.ols.clouds_enabled:
        wire(scene, sun_lamps.find_sun(scene))
    else:
        remove_shadow_layer()       # the map for a new seed is made when the clouds come on


def repair(scene):
    """Before the sky is updated (refresh): a set-up scene with clouds on gets its map back if it
    was deleted or damaged."""
    if scene.get(names.WIRED_KEY) and getattr(scene, "ols", None) is not None and scene.ols.clouds_enabled:
        ensure_map_image(seed_of(scene))
