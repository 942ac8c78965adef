"""Our File Output nodes in the compositor (the adaptation read-back, the atmosphere layers):
made once, and parked outside the renders that need them."""
from __future__ import annotations


def new_file_output(tree, name: str, location, *, media_type: str, file_format: str, exr_codec: str,
                    items, color_mode=None):
    """A parked 32-bit EXR File Output node named ``name`` with ``items`` ((socket type, name), ...)."""
    node = tree.nodes.new("CompositorNodeOutputFile")
    node.name = node.label = name
    node.location = location
    node.format.media_type = media_type
    node.format.file_format = file_format
    node.format.color_depth = "32"
    node.format.exr_codec = exr_codec
    if color_mode is not None:
        node.format.color_mode = color_mode
    for socket_type, item_name in items:
        node.file_output_items.new(socket_type, item_name)
    park(node)
    return node


def park(node):
    """Muted and without a folder: a saved .blend carries no absolute temporary path, and rendered
    without the add-on the node writes nothing anywhere (the read-back wrote into the shared
    temporary folder, following any symlink planted there). Only what changed is assigned (this runs
    from render handlers, and every assignment tags the depsgraph)."""
    if not node.mute:
        node.mute = True
    if node.directory:
        node.directory = ""
