"""Small Cycles renders for comparing node groups with their numpy twins."""
import math
from pathlib import Path

import numpy as np


def empty_scene(engine="CYCLES", width=128, height=64, samples=16):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = engine
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "BOX"      # pixel = plain average: easy to twin in numpy
    scene.cycles.filter_width = 1.0
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    return scene


def world_of_group(scene, group_tree, name="OLS Test World"):
    """A new world for ``scene`` whose background is the shader group ``group_tree``'s
    "Background" output; returns the group node (to set its inputs)."""
    import bpy
    world = bpy.data.worlds.new(name)
    scene.world = world
    world.use_nodes = True
    tree = world.node_tree
    tree.nodes.clear()
    group = tree.nodes.new("ShaderNodeGroup")
    group.node_tree = group_tree
    output = tree.nodes.new("ShaderNodeOutputWorld")
    tree.links.new(group.outputs["Background"], output.inputs["Surface"])
    return group


def panorama_camera(scene):
    """Equirectangular camera looking along +Y: pixel (row from top y, column x) sees
    longitude ((x + 0.5) / W - 0.5) 2 pi (toward +X) and latitude (0.5 - (y + 0.5) / H) pi."""
    import bpy
    data = bpy.data.cameras.new("OLS Test Pano")
    data.type = "PANO"
    data.panorama_type = "EQUIRECTANGULAR"
    camera = bpy.data.objects.new("OLS Test Pano", data)
    scene.collection.objects.link(camera)
    camera.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = camera
    return camera


def panorama_directions(width, height, supersample=4):
    """(height, width, s*s, 3) view directions of a box-filtered pixel's sub-samples."""
    offsets = (np.arange(supersample) + 0.5) / supersample
    x = (np.arange(width)[:, None] + offsets[None, :]).reshape(-1) / width
    y = (np.arange(height)[:, None] + offsets[None, :]).reshape(-1) / height
    lon = (x - 0.5) * 2 * math.pi
    lat = (0.5 - y) * math.pi
    lat, lon = np.meshgrid(lat, lon, indexing="ij")
    d = np.stack([np.sin(lon) * np.cos(lat), np.cos(lon) * np.cos(lat), np.sin(lat)], axis=-1)
    d = d.reshape(height, supersample, width, supersample, 3).transpose(0, 2, 1, 3, 4)
    return d.reshape(height, width, supersample * supersample, 3)


def render_rgb(scene, path: Path, composite: bool = False) -> np.ndarray:
    """Render the still and return its (height, width, 3) linear RGB, row 0 at the top.
    ``composite``: run the scene's compositor (the tone-mapping pass) on it."""
    import bpy
    import OpenEXR
    scene.render.use_compositing = composite
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    with OpenEXR.File(str(path)) as exr:
        channels = exr.channels()
        pixels = channels["RGBA"].pixels if "RGBA" in channels else channels["RGB"].pixels
    return np.asarray(pixels[..., :3], dtype=np.float64)


def save_png(path: Path, rgb: np.ndarray, exposure: float):
    """Tone-mapped PNG of a linear image, for looking at test renders."""
    import sys
    root = Path(__file__).resolve().parent.parent
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    from lut_gen.store.png import to_srgb8, write_png
    write_png(path, to_srgb8(1 - np.exp(-rgb * exposure)))
