"""Small helpers that keep node-group builders readable: math on sockets, not on nodes.

Every helper takes sockets or plain numbers and returns the output socket of the node it adds,
so a builder reads like the formula it implements.
"""
from __future__ import annotations

import bpy

from ...lut_gen.tables.interpolation import ABSOLUTE_FLOOR, GEOMETRIC_FLOOR


class Graph:
    """Wraps a node tree; nodes are laid out left to right in creation order."""

    def __init__(self, tree: bpy.types.NodeTree):
        self.tree = tree
        self.nodes = tree.nodes
        self.links = tree.links
        self._image_sources = {}

    def node(self, kind: str, **props):
        # Every property set on a node updates the whole tree (0.45 ms at 800 nodes in bpy 5.0.1):
        # values the node already has are not set again, and the layout is set for all nodes at
        # once (lay_out) after the group is built. A re-bake rebuilds ~2700 nodes.
        node = self.nodes.new(kind)
        for name, value in props.items():
            if getattr(node, name) != value:
                setattr(node, name, value)
        return node

    def feed(self, socket, value):
        if isinstance(value, bpy.types.NodeSocket):
            self.links.new(value, socket)
        elif value is not None and not _holds(socket, value):
            socket.default_value = value

    # -- scalars -------------------------------------------------------------
    def math(self, operation: str, a, b=None, c=None, clamp: bool = False):
        node = self.node("ShaderNodeMath", operation=operation, use_clamp=clamp)
        for socket, value in zip(node.inputs, (a, b, c)):
            self.feed(socket, value)
        return node.outputs[0]

    def add(self, a, b):
        return self.math("ADD", a, b)

    def sub(self, a, b):
        return self.math("SUBTRACT", a, b)

    def mul(self, a, b):
        return self.math("MULTIPLY", a, b)

    def div(self, a, b):
        return self.math("DIVIDE", a, b)

    def mul_add(self, a, b, c):
        return self.math("MULTIPLY_ADD", a, b, c)

    def clamp(self, value, low, high):
        node = self.node("ShaderNodeClamp")
        self.feed(node.inputs["Value"], value)
        self.feed(node.inputs["Min"], low)
        self.feed(node.inputs["Max"], high)
        return node.outputs[0]

    def lerp(self, a, b, t):
        """a + (b - a) t for scalars."""
        return self.mul_add(self.sub(b, a), t, a)

    def select(self, a, b, flag):
        """a where ``flag`` is 0, b where it is 1, exactly: a (1 - flag) + b flag. Not lerp when a
        may be huge: in float32 (b - a) + a loses b entirely (a = 1e18: b = 900 comes out 0)."""
        return self.mul_add(b, flag, self.mul(a, self.sub(1.0, flag)))

    # -- vectors and colours ---------------------------------------------------
    def vmath(self, operation: str, a, b=None, c=None):
        node = self.node("ShaderNodeVectorMath", operation=operation)
        for socket, value in zip(node.inputs, (a, b, c)):
            self.feed(socket, value)
        return node.outputs["Value" if operation in {"DOT_PRODUCT", "LENGTH", "DISTANCE"} else "Vector"]

    def combine(self, x, y, z):
        node = self.node("ShaderNodeCombineXYZ")
        for socket, value in zip(node.inputs, (x, y, z)):
            self.feed(socket, value)
        return node.outputs[0]

    def separate(self, vector):
        node = self.node("ShaderNodeSeparateXYZ")
        self.feed(node.inputs[0], vector)
        return node.outputs[0], node.outputs[1], node.outputs[2]

    def vlerp(self, a, b, t):
        """Component-wise a + (b - a) t; t a scalar socket."""
        return self.vmath("MULTIPLY_ADD", self.vmath("SUBTRACT", b, a), self.combine(t, t, t), a)

    def vgeometric_lerp(self, a, b, t):
        """Component-wise a^(1-t) b^t with lut_gen.tables.interpolation.geometric_lerp's floor; t a
        scalar socket."""
        floor = self.vmath("MAXIMUM", self.vscale(self.vmath("MAXIMUM", a, b), float(GEOMETRIC_FLOOR)), (float(ABSOLUTE_FLOOR),) * 3)
        low, high = self.vmath("MAXIMUM", a, floor), self.vmath("MAXIMUM", b, floor)
        return self.vmath("MULTIPLY", low, self.vmath("POWER", self.vmath("DIVIDE", high, low), self.combine(t, t, t)))

    def vscale(self, vector, scale):
        node = self.node("ShaderNodeVectorMath", operation="SCALE")
        self.feed(node.inputs[0], vector)
        self.feed(node.inputs["Scale"], scale)
        return node.outputs["Vector"]

    def with_alpha_of(self, image, rgb):
        """A compositor colour: the channels of vector ``rgb`` with the alpha of ``image``."""
        split = self.node("CompositorNodeSeparateColor")
        self.links.new(image, split.inputs["Image"])
        merge = self.node("CompositorNodeCombineColor")
        for name, value in zip(("Red", "Green", "Blue"), self.separate(rgb)):
            self.feed(merge.inputs[name], value)
        self.links.new(split.outputs["Alpha"], merge.inputs["Alpha"])
        return merge.outputs["Image"]

    def group(self, tree, **inputs):
        """A node of the group ``tree`` (same kind of tree) with its inputs fed; returns its outputs."""
        node = self.node("CompositorNodeGroup" if self.tree.bl_idname == "CompositorNodeTree" else "ShaderNodeGroup")
        node.node_tree = tree
        for name, value in inputs.items():
            self.feed(node.inputs[name.replace("_", " ").title()], value)
        return node.outputs

    def image(self, image: bpy.types.Image, uv, interpolation: str = "Linear", repeat: bool = False):
        """Colour of ``image`` at texture coordinates ``uv`` (Linear or Closest filtering, edges
        extended, or wrapping with ``repeat``). Shader trees use an Image Texture node,
        compositor trees a Map UV node; the image's node is labelled with its name, so code
        that repairs a group can find it."""
        if self.tree.bl_idname == "CompositorNodeTree":
            source = self._image_sources.get(image.name)
            if source is None:
                source = self._image_sources[image.name] = self.node("CompositorNodeImage", image=image,
                                                                     label=image.name)
            node = self.node("CompositorNodeMapUV")
            self.links.new(source.outputs["Image"], node.inputs["Image"])
            node.inputs["Interpolation"].default_value = "Bilinear" if interpolation == "Linear" else "Nearest"
            node.inputs["Extension X"].default_value = "Repeat" if repeat else "Extend"
            node.inputs["Extension Y"].default_value = "Repeat" if repeat else "Extend"
            self.feed(node.inputs["UV"], uv)
            return node.outputs["Image"]
        node = self.node("ShaderNodeTexImage", image=image, interpolation=interpolation,
                         extension="REPEAT" if repeat else "EXTEND", label=image.name)
        self.feed(node.inputs["Vector"], uv)
        return node.outputs["Color"]

    def image_rgba(self, image: bpy.types.Image, uv):
        """(colour, alpha) of a channel-packed data ``image`` at ``uv``, Linear filtering with
        extended edges: four numbers a texel (shader trees only)."""
        if self.tree.bl_idname == "CompositorNodeTree":
            raise ValueError("image_rgba is for shader trees")
        if image.alpha_mode != "CHANNEL_PACKED":
            raise ValueError(f"{image.name} must be channel-packed: its alpha would scale its colour")
        node = self.node("ShaderNodeTexImage", image=image, interpolation="Linear", extension="EXTEND",
                         label=image.name)
        self.feed(node.inputs["Vector"], uv)
        return node.outputs["Color"], node.outputs["Alpha"]


def _holds(socket, value) -> bool:
    """Whether ``socket`` already has ``value`` (then setting it, a tree update, is skipped)."""
    current = getattr(socket, "default_value", None)
    if isinstance(value, (int, float)) and isinstance(current, (int, float)):
        return current == value
    if isinstance(value, (tuple, list)) and hasattr(current, "__len__") and len(current) == len(value):
        return tuple(current) == tuple(value)
    return False


def lay_out(tree):
    """Spread a group's nodes left to right in creation order, in one call (a location set per
    node costs a tree update each)."""
    count = len(tree.nodes)
    locations = [value for i in range(count) for value in (i * 40.0, -(i % 12) * 60.0)]
    tree.nodes.foreach_set("location", locations)


def lay_out_groups():
    """lay_out every node group of the add-on that is still stacked at the origin (just built)."""
    for tree in bpy.data.node_groups:
        if tree.name.startswith("OLS ") and len(tree.nodes) > 1 and not any(node.location.x for node in tree.nodes):
            lay_out(tree)


def new_group(name: str, tree_type: str = "ShaderNodeTree"):
    """The node group ``name``, emptied for a rebuild. An existing group is reused in place, so
    the group nodes, links and drivers that point at it survive a rebuild (e.g. a re-bake)."""
    tree = bpy.data.node_groups.get(name)
    if tree is None:
        return bpy.data.node_groups.new(name, tree_type)
    if tree.animation_data is not None:
        tree.animation_data_clear()
    tree.nodes.clear()
    return tree


def group_io(tree, inputs, outputs):
    """Interface sockets (lists of (name, socket_type, default or None)) and the group's input
    and output nodes. An interface that already matches is kept as it is."""
    wanted = [(name, "INPUT", kind) for name, kind, _ in inputs] + [(name, "OUTPUT", kind) for name, kind, _ in outputs]
    current = [(item.name, item.in_out, item.socket_type) for item in tree.interface.items_tree
               if item.item_type == "SOCKET"]
    if sorted(current) != sorted(wanted):
        tree.interface.clear()
        for name, kind, default in inputs:
            socket = tree.interface.new_socket(name, in_out="INPUT", socket_type=kind)
            if default is not None:
                socket.default_value = default
        for name, kind, _ in outputs:
            tree.interface.new_socket(name, in_out="OUTPUT", socket_type=kind)
    graph = Graph(tree)
    group_in = graph.node("NodeGroupInput")
    group_out = graph.node("NodeGroupOutput")
    return graph, group_in, group_out
