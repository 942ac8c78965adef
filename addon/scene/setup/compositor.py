"""The scattering passes (aerial perspective, light shafts) and the tone mapping in the scene's
compositor, inserted without destroying a tree the user already has. The atmosphere is part of
the scene's light, so it goes right after the render (between the Render Layers image and the
user's first nodes: glare, grading); the tone mapping goes last, onto the link that feeds the
tree's output. ``unwire_compositor`` puts every link back. With one of
the sample's operators the view transform is set to Standard (so nothing tone maps twice); with
"Blender View Transform", and on unwire, the user's own is restored.

Renders saved as OpenEXR get the image before the tone mapping (scene-linear radiance) unless
"Tone Map EXR" is on: the tone-mapping group's "Linear Output" follows the output format.

Settings reach the groups' inputs here (sync_settings); per-frame values (camera, sun, shadow
cascades) go through images, see frame_update."""
from __future__ import annotations

import json
import os
from pathlib import Path

import bpy
import numpy as np

from ... import nodes
from ...settings import Sanitized
from ....lut_gen.passes import frame_values, tone_mapping
from ..frame import adaptation
from ..tables import luts
from ..file_outputs import new_file_output, park
from .. import names

LAYERS_SUFFIX = "_atmosphere_"
LAYER_NAMES = ("Beauty", "Surface", "Transmittance", "Inscattering", "Shafts")
EXR_FORMATS = {"OPEN_EXR", "OPEN_EXR_MULTILAYER"}


def _output_node(tree):
    return next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"), None)


def check_compositor(scene):
    """ValueError when the user's compositor tree has nowhere to insert the pass."""
    tree = scene.compositing_node_group
    if tree is None or tree.nodes.get(names.TONE_NODE) is not None:
        return
    output = _output_node(tree)
    if output is None or not output.inputs or not output.inputs[0].is_linked:
        raise ValueError(f"the compositor tree {tree.name!r} has no connected Group Output to insert "
                         "the tone mapping before; connect one or clear the scene's compositor")


def wire_compositor(scene):
    group = nodes.build_tone_mapping_group()
    nodes.builder.lay_out(group)
    tree = scene.compositing_node_group
    if tree is None:
        tree = bpy.data.node_groups.get(names.COMPOSITOR_TREE) or bpy.data.node_groups.new(names.COMPOSITOR_TREE, "CompositorNodeTree")
        tree.nodes.clear()
        if not tree.interface.items_tree:
            tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        layers = tree.nodes.new("CompositorNodeRLayers")
        output = tree.nodes.new("NodeGroupOutput")
        output.location = (600, 0)
        tree.links.new(layers.outputs["Image"], output.inputs[0])
        scene.compositing_node_group = tree
        scene[names.CREATED_TREE] = True
    node = tree.nodes.get(names.TONE_NODE)
    if node is None:
        check_compositor(scene)
        output = _output_node(tree)
        link = output.inputs[0].links[0]
        source, index = link.from_node, list(link.from_node.outputs).index(link.from_socket)
        node = tree.nodes.new("CompositorNodeGroup")
        node.node_tree = group
        node.name = names.TONE_NODE
        node.location = (output.location.x - 200, output.location.y)
        node[names.SOURCE] = source.name
        node[names.SOURCE_OUTPUT] = index
        tree.links.remove(link)
        tree.links.new(source.outputs[index], node.inputs["Image"])
        tree.links.new(node.outputs["Image"], output.inputs[0])
    node.node_tree = group
    adaptation.ensure_output_node(tree, node)     # light adaptation reads each frame's luminance back
    _insert_aerial(scene, tree, node)
    sync_settings(scene)
    scene.render.use_compositing = True
    return node


def sync_view_transform(scene, operator):
    """Standard under the sample's operators, the user's own view transform under
    BLENDER_VIEW. Only a change of operator family touches the setting, so a view transform the
    user picks while "Blender View Transform" is on stays theirs."""
    view = scene.view_settings
    if operator in tone_mapping.VIEW_TRANSFORM_OPERATORS:
        if scene.get(names.VIEW_MODE) == "SAMPLE":
            if names.PREVIOUS_VIEW in scene:
                view.view_transform = scene[names.PREVIOUS_VIEW]
                del scene[names.PREVIOUS_VIEW]
            del scene[names.VIEW_MODE]
    elif scene.get(names.VIEW_MODE) != "SAMPLE":
        if view.view_transform != "Standard":
            scene[names.PREVIOUS_VIEW] = view.view_transform
            view.view_transform = "Standard"
        scene[names.VIEW_MODE] = "SAMPLE"


def linear_output(scene, settings) -> bool:
    """Whether renders now save scene-linear radiance (OpenEXR without Tone Map EXR)."""
    return scene.render.image_settings.file_format in EXR_FORMATS and not settings.tone_map_exr


def render_image_source(tree, socket):
    """The Render Layers "Image" output that the chain ending at ``socket`` starts from,
    following each node's first linked colour input upstream (Glare, Color Balance, a group of
    the user's...); None when the chain starts elsewhere (an Image node, a mask)."""
    seen = set()
    while socket.is_linked:
        link = socket.links[0]
        node = link.from_node
        if node.bl_idname == "CompositorNodeRLayers":
            return link.from_socket
        if node.as_pointer() in seen:
            return None
        seen.add(node.as_pointer())
        socket = next((s for s in node.inputs if s.is_linked and s.type == "RGBA"), None)
        if socket is None:
            return None
    return None


def atmosphere_targets(tree, aerial, tone):
    """The inputs the atmosphere feeds: what the render's image fed before Set Up Scene (stored
    on our aerial node), or the tone mapping's input in trees wired before that was stored."""
    stored = json.loads(aerial.get(names.ATMOSPHERE_TARGETS_KEY, "[]"))
    targets = [tree.nodes[name].inputs[index] for name, index in stored
               if name in tree.nodes and index < len(tree.nodes[name].inputs)]
    return targets or [tone.inputs["Image"]]


def _insert_aerial(scene, tree, tone_node):
    """Put the aerial-perspective group right after the render: between the Render Layers image
    the user's chain starts from and everything it fed (so glare, grading and the tone mapping
    see the scene's light with its atmosphere); fed by the Position and Depth passes of a Render
    Layers node of ours, so the user's nodes keep their links. A chain that does not start at a
    render gets the atmosphere just before the tone mapping."""
    aerial = tree.nodes.get(names.AERIAL_NODE)
    if aerial is None:
        source = render_image_source(tree, tone_node.inputs["Image"])
        if source is None:
            source = tone_node.inputs["Image"].links[0].from_socket
            targets = [tone_node.inputs["Image"]]
        else:
            targets = [link.to_socket for link in source.links]
        aerial = tree.nodes.new("CompositorNodeGroup")
        aerial.node_tree = bpy.data.node_groups[names.AERIAL_GROUP]
        aerial.name = names.AERIAL_NODE
        aerial.location = (source.node.location.x + 200, source.node.location.y - 250)
        aerial[names.ATMOSPHERE_TARGETS_KEY] = json.dumps(
            [[target.node.name, list(target.node.inputs).index(target)] for target in targets])
        for link in list(source.links):
            if link.to_socket in targets:
                tree.links.remove(link)
        tree.links.new(source, aerial.inputs["Image"])
        for target in targets:
            tree.links.new(aerial.outputs["Image"], target)
    layers = tree.nodes.get(names.LAYERS_NODE) or tree.nodes.new("CompositorNodeRLayers")
    layers.name = names.LAYERS_NODE
    layer = scene.view_layers[0]
    if names.PREVIOUS_PASSES not in scene:
        scene[names.PREVIOUS_PASSES] = [int(layer.use_pass_position), int(layer.use_pass_z)]
    layer.use_pass_position = layer.use_pass_z = True
    tree.links.new(layers.outputs["Position"], aerial.inputs["Position"])
    tree.links.new(layers.outputs["Depth"], aerial.inputs["Depth"])
    link_light_shafts(scene)


def link_light_shafts(scene):
    """Put the light-shaft group right after the aerial perspective, ahead of what that fed, and
    feed both from "OLS Frame Values" (again after a rebuild changed their sockets)."""
    tree = scene.compositing_node_group
    aerial, tone = tree.nodes.get(names.AERIAL_NODE), tree.nodes.get(names.TONE_NODE)
    layers = tree.nodes.get(names.LAYERS_NODE)
    group = bpy.data.node_groups.get(names.LIGHT_SHAFTS_GROUP)
    if aerial is None or tone is None or layers is None:
        return
    if group is None:
        # No shaft groups (a scene set up under the analytic model before it had shafts): the
        # frame values still feed the aerial perspective its camera and sun.
        _link_frame_values(tree, layers, (aerial,))
        return
    shafts = tree.nodes.get(names.SHAFTS_NODE)
    if shafts is None:
        shafts = tree.nodes.new("CompositorNodeGroup")
        shafts.name = names.SHAFTS_NODE
        shafts.location = (aerial.location.x + 200, aerial.location.y)
    shafts.node_tree = group
    tree.links.new(aerial.outputs["Image"], shafts.inputs["Image"])
    for target in atmosphere_targets(tree, aerial, tone):
        tree.links.new(shafts.outputs["Image"], target)
    tree.links.new(layers.outputs["Position"], shafts.inputs["Position"])
    tree.links.new(layers.outputs["Depth"], shafts.inputs["Depth"])
    veil = sync_cloud_veil(scene)
    surface = veil.outputs["Image"] if veil is not None else layers.outputs["Image"]
    if "Surface" in shafts.inputs:      # the epipolar layout makes the whole image from these
        tree.links.new(surface, shafts.inputs["Surface"])
        tree.links.new(aerial.outputs["Transmittance"], shafts.inputs["Transmittance"])
    _ensure_layers_output(tree, surface, aerial, shafts, tone)
    _link_frame_values(tree, layers, (aerial, shafts, veil))


def _link_frame_values(tree, layers, targets):
    """The "OLS Frame Values" node (made when missing) feeding every input of ``targets`` (None
    skipped) that it has an output for."""
    frame = tree.nodes.get(names.FRAME_NODE)
    if frame is None:
        aerial = tree.nodes[names.AERIAL_NODE]
        frame = tree.nodes.new("CompositorNodeGroup")
        frame.name = names.FRAME_NODE
        frame.location = (aerial.location.x - 200, aerial.location.y - 300)
    if bpy.data.images.get(names.FRAME_IMAGE) is None:
        luts.write_data_image(names.FRAME_IMAGE, frame_values.pack({}))
    if not nodes.frame_values.is_current(frame.node_tree, bpy.data.images[names.FRAME_IMAGE]):
        frame.node_tree = nodes.build_frame_values_group(bpy.data.images[names.FRAME_IMAGE])
        nodes.builder.lay_out(frame.node_tree)
    tree.links.new(layers.outputs["Image"], frame.inputs["Image"])
    for target in targets:
        for output in frame.outputs if target is not None else ():
            if output.name in target.inputs:
                tree.links.new(output, target.inputs[output.name])


def sync_cloud_veil(scene):
    """Put "OLS Cloud Veil" between the render's image and the aerial perspective while Clouds
    is on (the peaks in the cloud veiled before the air hazes them), take it out while off (the
    tree is then as without clouds); returns the node or None. Its Position and Depth come from
    our Render Layers node, the layer's rows from "OLS Frame Values"."""
    tree = scene.compositing_node_group
    aerial = tree.nodes.get(names.AERIAL_NODE) if tree is not None else None
    group = bpy.data.node_groups.get(names.CLOUD_VEIL_GROUP)
    veil = tree.nodes.get(names.VEIL_NODE) if tree is not None else None
    wanted = aerial is not None and group is not None and bool(getattr(scene.ols, "clouds_enabled", False))
    if veil is not None and not wanted:
        remove_cloud_veil(tree)
        return None
    if not wanted:
        return None
    if veil is None:
        if not aerial.inputs["Image"].links:
            return None
        source = aerial.inputs["Image"].links[0].from_socket
        veil = tree.nodes.new("CompositorNodeGroup")
        veil.name = veil.label = names.VEIL_NODE
        veil.node_tree = group
        veil.location = (aerial.location.x - 200, aerial.location.y + 150)
        tree.links.new(source, veil.inputs["Image"])
        tree.links.new(veil.outputs["Image"], aerial.inputs["Image"])
        shafts = tree.nodes.get(names.SHAFTS_NODE)
        if shafts is not None and "Surface" in shafts.inputs:
            tree.links.new(veil.outputs["Image"], shafts.inputs["Surface"])
        atmosphere = tree.nodes.get(names.ATMOSPHERE_NODE)
        if atmosphere is not None and "Surface" in atmosphere.inputs:
            tree.links.new(veil.outputs["Image"], atmosphere.inputs["Surface"])
    elif veil.node_tree is not group:
        veil.node_tree = group
    layers, frame = tree.nodes.get(names.LAYERS_NODE), tree.nodes.get(names.FRAME_NODE)
    if layers is not None:
        tree.links.new(layers.outputs["Position"], veil.inputs["Position"])
        tree.links.new(layers.outputs["Depth"], veil.inputs["Depth"])
    for output in frame.outputs if frame is not None else ():
        if output.name in veil.inputs and not veil.inputs[output.name].links:
            tree.links.new(output, veil.inputs[output.name])
    return veil


def remove_cloud_veil(tree):
    """Take the veil out, its image source feeding what it fed."""
    veil = tree.nodes.get(names.VEIL_NODE) if tree is not None else None
    if veil is None:
        return
    source = veil.inputs["Image"].links[0].from_socket if veil.inputs["Image"].links else None
    targets = [link.to_socket for link in veil.outputs["Image"].links]
    tree.nodes.remove(veil)
    for target in targets if source is not None else ():
        tree.links.new(source, target)


def _ensure_layers_output(tree, surface, aerial, shafts, tone):
    """Our File Output node for the atmosphere layers (parked until a multilayer EXR render):
    beauty = surface x transmittance + inscattering + shafts, all before the tone mapping."""
    node = tree.nodes.get(names.ATMOSPHERE_NODE)
    if node is None:
        node = new_file_output(tree, names.ATMOSPHERE_NODE, (tone.location.x, tone.location.y - 400),
                               media_type="MULTI_LAYER_IMAGE", file_format="OPEN_EXR_MULTILAYER",
                               exr_codec="ZIP", items=[("RGBA", name) for name in LAYER_NAMES])
    difference = tree.nodes.get(names.SHAFTS_LAYER_NODE)
    if difference is None:
        difference = tree.nodes.new("ShaderNodeVectorMath")
        difference.name = difference.label = names.SHAFTS_LAYER_NODE
        difference.operation = "SUBTRACT"
        difference.location = (tone.location.x - 100, tone.location.y - 400)
    tree.links.new(shafts.outputs["Image"], difference.inputs[0])
    tree.links.new(aerial.outputs["Image"], difference.inputs[1])
    sources = {"Beauty": shafts.outputs["Image"], "Surface": surface,
               "Transmittance": aerial.outputs["Transmittance"], "Inscattering": aerial.outputs["Inscattering"],
               "Shafts": difference.outputs["Vector"]}
    for name, socket in sources.items():
        tree.links.new(socket, node.inputs[name])


def layers_path(scene):
    """(folder, file name prefix) of the atmosphere layers beside the render's own output."""
    output = Path(bpy.path.abspath(scene.render.filepath))
    folder, stem = (output, "") if scene.render.filepath.endswith(("/", "\\")) else (output.parent, output.name)
    stem = Path(stem).stem if Path(stem).suffix.lower() == ".exr" else stem
    return str(folder) + os.sep, stem.rstrip("#_") + LAYERS_SUFFIX


def sync_layers_output(scene, rendering: bool):
    """Unpark the layers node for a multilayer EXR render, park it otherwise."""
    tree = scene.compositing_node_group
    node = tree.nodes.get(names.ATMOSPHERE_NODE) if tree is not None else None
    if node is None:
        return
    if not (rendering and scene.render.image_settings.file_format == "OPEN_EXR_MULTILAYER"):
        park(node)
        return
    folder, name = layers_path(scene)
    if node.directory != folder:
        node.directory = folder
    if node.file_name != name:
        node.file_name = name
    if node.mute:
        node.mute = False


def unwire_compositor(scene):
    tree = scene.compositing_node_group
    remove_cloud_veil(tree)
    for name in (names.ATMOSPHERE_NODE, names.SHAFTS_LAYER_NODE):
        if tree is not None and tree.nodes.get(name) is not None:
            tree.nodes.remove(tree.nodes[name])
    if tree is not None and tree.nodes.get(names.FRAME_NODE) is not None:
        tree.nodes.remove(tree.nodes[names.FRAME_NODE])
    if tree is not None and tree.nodes.get(names.SHAFTS_NODE) is not None:
        tree.nodes.remove(tree.nodes[names.SHAFTS_NODE])
        aerial, tone = tree.nodes.get(names.AERIAL_NODE), tree.nodes.get(names.TONE_NODE)
        if aerial is not None and tone is not None:
            for target in atmosphere_targets(tree, aerial, tone):
                tree.links.new(aerial.outputs["Image"], target)
    if tree is not None and not scene.get(names.CREATED_TREE):
        aerial, tone = tree.nodes.get(names.AERIAL_NODE), tree.nodes.get(names.TONE_NODE)
        if aerial is not None:
            source = aerial.inputs["Image"].links[0].from_socket if aerial.inputs["Image"].links else None
            targets = atmosphere_targets(tree, aerial, tone) if tone is not None else []
            tree.nodes.remove(aerial)
            for target in targets if source is not None else ():
                tree.links.new(source, target)
        if tree.nodes.get(names.LAYERS_NODE) is not None:
            tree.nodes.remove(tree.nodes[names.LAYERS_NODE])
    if names.PREVIOUS_PASSES in scene:
        layer = scene.view_layers[0]
        layer.use_pass_position, layer.use_pass_z = (bool(v) for v in scene[names.PREVIOUS_PASSES])
        del scene[names.PREVIOUS_PASSES]
    adaptation.forget(scene)
    if tree is not None:
        adaptation.remove_output_node(tree)
        node = tree.nodes.get(names.TONE_NODE)
        if scene.get(names.CREATED_TREE):
            scene.compositing_node_group = None
            bpy.data.node_groups.remove(tree)
        elif node is not None:
            source_name, index = node.get(names.SOURCE), node.get(names.SOURCE_OUTPUT, 0)
            output = _output_node(tree)
            tree.nodes.remove(node)
            source = tree.nodes.get(source_name) if source_name else None
            if source is not None and output is not None:
                tree.links.new(source.outputs[index], output.inputs[0])
    if names.PREVIOUS_VIEW in scene:
        scene.view_settings.view_transform = scene[names.PREVIOUS_VIEW]
        del scene[names.PREVIOUS_VIEW]
    if names.VIEW_MODE in scene:
        del scene[names.VIEW_MODE]
    if names.CREATED_TREE in scene:
        del scene[names.CREATED_TREE]


def sync_settings(scene):
    """Copy the controls of scene.ols, the camera position and the sun onto our compositor
    nodes. (Drivers on a compositor tree do not reach the render, so the settings' update
    callbacks and the scene handlers call this.)"""
    tree = scene.compositing_node_group
    node = tree.nodes.get(names.TONE_NODE) if tree is not None else None
    if node is None or node.node_tree is None:
        return
    settings = Sanitized(scene.ols)
    _set_inputs(node, {"Middle Gray": settings.middle_gray, "White Point": settings.white_point,
                       "Luminance Saturation": settings.luminance_saturation,
                       "Auto Exposure": float(settings.auto_exposure),
                       "Operator": float(tone_mapping.OPERATORS.index(settings.tone_mapping_operator)),
                       "Linear Output": float(linear_output(scene, settings))})
    sync_view_transform(scene, settings.tone_mapping_operator)
    aerial = tree.nodes.get(names.AERIAL_NODE)
    if aerial is None or aerial.node_tree is None:
        return
    veil = tree.nodes.get(names.VEIL_NODE)
    if (veil is None) == bool(settings.clouds_enabled):
        sync_cloud_veil(scene)
    _set_inputs(aerial, {"Enable": float(settings.enable_light_scattering),
                         "Lighting Only": float(settings.lighting_only), "Scattering Scale": settings.scattering_scale})
    shafts = tree.nodes.get(names.SHAFTS_NODE)
    if shafts is not None and shafts.node_tree is not None:
        # A group built for the other model (the analytic stand-in while tables bake keeps the
        # tables' one, baking.show_analytic_stand_in) stays muted: its air is not the aerial group's.
        model = "analytic" if scene.get(names.WIRED_KEY) == names.ANALYTIC_WIRED else "tables"
        active = (settings.enable_light_scattering and settings.enable_light_shafts
                  and shafts.node_tree.get(names.SHAFT_MODEL_KEY, "tables") == model)
        if shafts.mute == active:       # a muted group passes its image through and costs nothing
            shafts.mute = not active
        _set_inputs(shafts, {"Enable": float(settings.enable_light_scattering),
                             "Scattering Scale": settings.scattering_scale,
                             "First Cascade": float(settings.first_cascade_to_ray_march),
                             "Show Cascades": float(settings.show_cascades)})
        if "Show Sampling" in shafts.inputs:
            _set_inputs(shafts, {"Show Sampling": float(settings.show_sampling)})
        if "Jitter Steps" in shafts.inputs:
            _set_inputs(shafts, {"Jitter Steps": float(settings.jitter_steps)})


def _set_inputs(node, values: dict):
    """Assign only what changed: this runs from depsgraph handlers, and every assignment
    would trigger another depsgraph update."""
    for socket, value in values.items():
        current = node.inputs[socket].default_value     # stored as float32: compare with a tolerance
        if not np.allclose(np.atleast_1d(current), np.atleast_1d(value), rtol=1e-6, atol=1e-9):
            node.inputs[socket].default_value = value


def disable_light_shafts(scene):
    """Mute the light-shaft node (the next settings sync turns it back on)."""
    tree = scene.compositing_node_group
    shafts = tree.nodes.get(names.SHAFTS_NODE) if tree is not None else None
    if shafts is not None:
        shafts.mute = True
