"""The tone-mapping pass in the scene's compositor, inserted without destroying a tree the
user already has: our group node goes onto the link that feeds the tree's output, and
``unwire_compositor`` puts that link back. The view transform is set to Standard (so nothing
tone maps twice) and restored on unwire."""
from __future__ import annotations

import bpy

from .. import nodes
from ..post import tone_mapping

TREE_NAME = "OLS Compositing"
NODE_NAME = "OLS Tone Mapping"
CREATED_TREE = "ols_created_compositor"
PREVIOUS_VIEW = "ols_previous_view_transform"
SOURCE = "ols_source"                 # on our node: the node it was inserted after ...
SOURCE_OUTPUT = "ols_source_output"   # ... and that node's output index


def _output_node(tree):
    return next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"), None)


def check_compositor(scene):
    """ValueError when the user's compositor tree has nowhere to insert the pass."""
    tree = scene.compositing_node_group
    if tree is None or tree.nodes.get(NODE_NAME) is not None:
        return
    output = _output_node(tree)
    if output is None or not output.inputs or not output.inputs[0].is_linked:
        raise ValueError(f"the compositor tree {tree.name!r} has no connected Group Output to insert "
                         "the tone mapping before; connect one or clear the scene's compositor")


def wire_compositor(scene):
    group = nodes.build_tone_mapping_group()
    tree = scene.compositing_node_group
    if tree is None:
        tree = bpy.data.node_groups.get(TREE_NAME) or bpy.data.node_groups.new(TREE_NAME, "CompositorNodeTree")
        tree.nodes.clear()
        if not tree.interface.items_tree:
            tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        layers = tree.nodes.new("CompositorNodeRLayers")
        output = tree.nodes.new("NodeGroupOutput")
        output.location = (600, 0)
        tree.links.new(layers.outputs["Image"], output.inputs[0])
        scene.compositing_node_group = tree
        scene[CREATED_TREE] = True
    node = tree.nodes.get(NODE_NAME)
    if node is None:
        check_compositor(scene)
        output = _output_node(tree)
        link = output.inputs[0].links[0]
        source, index = link.from_node, list(link.from_node.outputs).index(link.from_socket)
        node = tree.nodes.new("CompositorNodeGroup")
        node.node_tree = group
        node.name = NODE_NAME
        node.location = (output.location.x - 200, output.location.y)
        node[SOURCE] = source.name
        node[SOURCE_OUTPUT] = index
        tree.links.remove(link)
        tree.links.new(source.outputs[index], node.inputs["Image"])
        tree.links.new(node.outputs["Image"], output.inputs[0])
    node.node_tree = group
    sync_settings(scene)
    if scene.view_settings.view_transform != "Standard":
        scene[PREVIOUS_VIEW] = scene.view_settings.view_transform
        scene.view_settings.view_transform = "Standard"
    scene.render.use_compositing = True
    return node


def unwire_compositor(scene):
    tree = scene.compositing_node_group
    if tree is not None:
        node = tree.nodes.get(NODE_NAME)
        if scene.get(CREATED_TREE):
            scene.compositing_node_group = None
            bpy.data.node_groups.remove(tree)
        elif node is not None:
            source_name, index = node.get(SOURCE), node.get(SOURCE_OUTPUT, 0)
            output = _output_node(tree)
            tree.nodes.remove(node)
            source = tree.nodes.get(source_name) if source_name else None
            if source is not None and output is not None:
                tree.links.new(source.outputs[index], output.inputs[0])
    if PREVIOUS_VIEW in scene:
        scene.view_settings.view_transform = scene[PREVIOUS_VIEW]
        del scene[PREVIOUS_VIEW]
    if CREATED_TREE in scene:
        del scene[CREATED_TREE]


def sync_settings(scene):
    """Copy the tone-mapping controls of scene.ols onto our compositor node. (Drivers on a
    compositor tree do not reach the render, so the settings' update callbacks call this.)"""
    tree = scene.compositing_node_group
    node = tree.nodes.get(NODE_NAME) if tree is not None else None
    if node is None or node.node_tree is None:
        return
    settings = scene.ols
    values = {"Middle Gray": settings.middle_gray, "White Point": settings.white_point,
              "Luminance Saturation": settings.luminance_saturation,
              "Auto Exposure": float(settings.auto_exposure),
              "Operator": float(tone_mapping.OPERATORS.index(settings.tone_mapping_operator))}
    for socket, value in values.items():
        node.inputs[socket].default_value = value
