"""Compositor-only timing: render a frame once, save it as a multilayer EXR and feed the
compositor from it. With no live Render Layers node Blender skips the Cycles render and runs
only the handlers (render_pre: the shadow maps and tables) and the compositor, so a pass is
timed without Cycles' run-to-run noise. Used by bench_light_shafts and bench_shaft_pass."""
import tempfile
from pathlib import Path

NODE_NAME = "Bench Saved Render"


def save(scene):
    """Render the frame without compositing, save it as a 32-bit multilayer EXR, and add an
    Image node reading it to the scene's compositor. Returns that node."""
    import bpy
    scene.render.use_compositing = False
    bpy.ops.render.render(write_still=False)
    exr = Path(tempfile.mkdtemp(prefix="ols_bench_")) / "frame.exr"
    image_settings = scene.render.image_settings
    image_settings.media_type = "MULTI_LAYER_IMAGE"
    image_settings.color_depth = "32"
    bpy.data.images["Render Result"].save_render(str(exr), scene=scene)
    # Back to PNG: with OpenEXR MultiLayer output every timed render would also write the
    # atmosphere layers file (and evaluate the per-pixel in-scattering it holds).
    image_settings.media_type = "IMAGE"
    image_settings.file_format = "PNG"
    image_settings.color_depth = "8"
    saved = scene.compositing_node_group.nodes.new("CompositorNodeImage")
    saved.name = NODE_NAME
    saved.image = bpy.data.images.load(str(exr))
    scene.render.use_compositing = True
    return saved


def use(scene, saved):
    """Move every link out of a Render Layers node onto the saved image; mute those nodes.
    Call again after anything rebuilds the compositor's layout (it relinks Render Layers)."""
    tree = scene.compositing_node_group
    for node in tree.nodes:
        if node.bl_idname != "CompositorNodeRLayers":
            continue
        for output in node.outputs:
            for link in list(output.links):
                name = "Combined" if output.name == "Image" else output.name
                tree.links.new(saved.outputs[name], link.to_socket)   # replaces the link
        node.mute = True
