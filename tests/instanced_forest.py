"""A forest of instanced trees made by a geometry-nodes Instance on Points: the case the
shadow maps must gather fast (10 000 trees, each an instance). Used by the tests and by
bench/bench_shadow_maps.py."""
import math


def tree_object(name="Forest Tree", height=8.0, radius=2.0, vertices=12):
    """A cone on a trunk: 4 * vertices triangles, its base at the origin."""
    import bpy
    import bmesh
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cone(bm, cap_ends=True, segments=vertices, radius1=radius, radius2=0.0, depth=height * 0.7,
                          matrix=_translation(0.0, 0.0, height * 0.65))
    bmesh.ops.create_cone(bm, cap_ends=True, segments=vertices, radius1=radius * 0.15, radius2=radius * 0.15,
                          depth=height * 0.3, matrix=_translation(0.0, 0.0, height * 0.15))
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.to_mesh(mesh)
    bm.free()
    # In no scene: the forest's Object Info pulls it into the depsgraph, only its instances show.
    return bpy.data.objects.new(name, mesh)


def _translation(x, y, z):
    from mathutils import Matrix
    return Matrix.Translation((x, y, z))


def forest(scene, count=10_000, spacing=12.0, origin=(0.0, 0.0), tree=None, as_geometry=False):
    """An object whose geometry nodes put ``count`` trees (about sqrt(count) per side, ``spacing``
    metres apart, centred on ``origin``) on a grid, as instances of ``tree`` (made if None) or,
    with ``as_geometry``, of a cone made in the node tree. Returns (forest object, tree object)."""
    import bpy
    side = max(int(round(math.sqrt(count))), 1)
    tree = tree if tree is not None or as_geometry else tree_object()
    mesh = bpy.data.meshes.new("Forest Points")
    obj = bpy.data.objects.new("Forest", mesh)
    scene.collection.objects.link(obj)
    obj.location = (origin[0], origin[1], 0.0)
    nodes = bpy.data.node_groups.new("Forest", "GeometryNodeTree")
    nodes.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    nodes.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    out = nodes.nodes.new("NodeGroupOutput")
    grid = nodes.nodes.new("GeometryNodeMeshGrid")
    grid.inputs["Size X"].default_value = grid.inputs["Size Y"].default_value = spacing * (side - 1)
    grid.inputs["Vertices X"].default_value = grid.inputs["Vertices Y"].default_value = side
    on_points = nodes.nodes.new("GeometryNodeInstanceOnPoints")
    nodes.links.new(grid.outputs["Mesh"], on_points.inputs["Points"])
    if as_geometry:
        cone = nodes.nodes.new("GeometryNodeMeshCone")
        cone.inputs["Radius Bottom"].default_value = 2.0
        cone.inputs["Depth"].default_value = 8.0
        nodes.links.new(cone.outputs["Mesh"], on_points.inputs["Instance"])
    else:
        info = nodes.nodes.new("GeometryNodeObjectInfo")
        info.inputs["Object"].default_value = tree
        nodes.links.new(info.outputs["Geometry"], on_points.inputs["Instance"])
    nodes.links.new(on_points.outputs["Instances"], out.inputs["Geometry"])
    modifier = obj.modifiers.new("Forest", "NODES")
    modifier.node_group = nodes
    return obj, tree


def realize(obj):
    """Append a Realize Instances to the forest's node tree: the same trees as one mesh."""
    nodes = obj.modifiers["Forest"].node_group
    out = next(n for n in nodes.nodes if n.bl_idname == "NodeGroupOutput")
    source = out.inputs["Geometry"].links[0].from_socket
    realize_node = nodes.nodes.new("GeometryNodeRealizeInstances")
    nodes.links.new(source, realize_node.inputs["Geometry"])
    nodes.links.new(realize_node.outputs["Geometry"], out.inputs["Geometry"])
