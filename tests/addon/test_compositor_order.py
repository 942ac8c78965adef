"""Where Set Up Scene puts the atmosphere in a compositor tree the user already has: right
after the render's passes, ahead of the user's own nodes (a Glare and a Color Balance), with the
tone mapping last; and unwiring gives the user's tree back exactly."""
import pytest

from scenes import sample_scene

bpy = pytest.importorskip("bpy")


def tree_state(tree):
    """Nodes (name, type) and links (from node, socket, to node, socket) of ``tree``."""
    nodes = sorted((node.name, node.bl_idname) for node in tree.nodes)
    links = sorted((link.from_node.name, link.from_socket.identifier, link.to_node.name, link.to_socket.identifier)
                   for link in tree.links)
    return nodes, links


def upstream(socket):
    """Names of the nodes feeding ``socket``, nearest first, along each node's Image input."""
    chain = []
    while socket.is_linked:
        node = socket.links[0].from_node
        chain.append(node.name)
        socket = node.inputs.get("Image")
        if socket is None:
            break
    return chain


def users_tree():
    tree = bpy.data.node_groups.new("My Grading", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    layers = tree.nodes.new("CompositorNodeRLayers")
    layers.name = "My Render"
    glare = tree.nodes.new("CompositorNodeGlare")
    glare.name = "My Glare"
    balance = tree.nodes.new("CompositorNodeColorBalance")
    balance.name = "My Grade"
    output = tree.nodes.new("NodeGroupOutput")
    output.name = "My Output"
    tree.links.new(layers.outputs["Image"], glare.inputs["Image"])
    tree.links.new(glare.outputs["Image"], balance.inputs["Image"])
    tree.links.new(balance.outputs["Image"], output.inputs[0])
    return tree


def test_the_atmosphere_comes_right_after_the_render_and_unwiring_restores_the_tree(addon_package, tmp_path,
                                                                                    monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    scene = sample_scene(addon_package)
    tree = users_tree()
    scene.compositing_node_group = tree
    before = tree_state(tree)

    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    output = tree.nodes["My Output"]
    assert upstream(output.inputs[0]) == ["OLS Tone Mapping", "My Grade", "My Glare", "OLS Light Shafts",
                                          "OLS Aerial Perspective", "My Render"]
    # Set Up Scene again (and a light-shaft layout rebuild) keeps the order.
    scene.ols.num_integration_steps = 12
    addon_package.addon.scene.setup.wiring.match_light_shaft_layout(scene)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    assert upstream(output.inputs[0])[:5] == ["OLS Tone Mapping", "My Grade", "My Glare", "OLS Light Shafts",
                                              "OLS Aerial Perspective"]
    # With the shafts off the muted shaft node passes the aerial perspective through, still first.
    scene.ols.enable_light_shafts = False
    assert upstream(tree.nodes["My Glare"].inputs["Image"])[:2] == ["OLS Light Shafts", "OLS Aerial Perspective"]

    addon_package.addon.scene.setup.wiring.unwire_scene(scene)
    assert tree_state(tree) == before
    assert scene.compositing_node_group == tree


def test_a_render_image_feeding_two_nodes_gets_the_atmosphere_in_both(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    scene = sample_scene(addon_package)
    tree = users_tree()
    viewer = tree.nodes.new("CompositorNodeViewer")
    tree.links.new(tree.nodes["My Render"].outputs["Image"], viewer.inputs["Image"])
    scene.compositing_node_group = tree
    before = tree_state(tree)
    assert bpy.ops.ols.setup_scene(resolution="draft") == {"FINISHED"}
    assert viewer.inputs["Image"].links[0].from_node.name == "OLS Light Shafts"
    assert tree.nodes["My Glare"].inputs["Image"].links[0].from_node.name == "OLS Light Shafts"
    addon_package.addon.scene.setup.wiring.unwire_scene(scene)
    assert tree_state(tree) == before
