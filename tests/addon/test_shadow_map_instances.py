"""The shadow maps gather instanced geometry (a geometry-nodes Instance on Points forest): every
instance's triangles at its own place, the same triangles as the realized mesh."""
import numpy as np
import pytest

from extension import extension_module
from instanced_forest import forest, realize

bpy = pytest.importorskip("bpy")


def _sorted(triangles):
    corners = np.round(np.sort(triangles.reshape(len(triangles), -1), axis=0), 4)
    return corners[np.lexsort(corners.T[::-1])]


@pytest.mark.parametrize("as_geometry", [False, True], ids=["object instances", "geometry instances"])
def test_instanced_trees_cast_the_same_triangles_as_realized_ones(addon_package, as_geometry):
    shadow_maps = extension_module("addon.scene.frame.shadow_maps")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    obj, _ = forest(scene, count=16, spacing=10.0, origin=(5.0, -3.0), as_geometry=as_geometry)
    instanced = shadow_maps.scene_triangles(bpy.context.evaluated_depsgraph_get())
    realize(obj)
    bpy.context.view_layer.update()
    realized = shadow_maps.scene_triangles(bpy.context.evaluated_depsgraph_get())
    assert len(instanced) >= 16 * 8 and len(instanced) == len(realized)
    np.testing.assert_allclose(_sorted(instanced), _sorted(realized), atol=2e-3)
    # Every tree is there, at its point of the 4 x 4 grid around the origin given.
    centres = instanced.mean(axis=1)[:, :2]
    grid = np.stack(np.meshgrid([-15.0, -5.0, 5.0, 15.0], [-15.0, -5.0, 5.0, 15.0]), -1).reshape(-1, 2) + [5.0, -3.0]
    nearest = np.linalg.norm(centres[:, None] - grid[None], axis=-1).argmin(axis=1)
    assert np.linalg.norm(centres - grid[nearest], axis=1).max() < 3.0
    assert (np.bincount(nearest, minlength=16) == len(instanced) // 16).all()


def test_instances_placed_on_threads_equal_the_serial_placing(addon_package):
    """scene_triangles(threads=N) splits each geometry's instances between threads (the frame
    update places on every core): the same triangles bit for bit, in the same order."""
    shadow_maps = extension_module("addon.scene.frame.shadow_maps")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    forest(bpy.context.scene, count=900, spacing=6.0)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    serial = shadow_maps.scene_triangles(depsgraph)
    threaded = shadow_maps.scene_triangles(depsgraph, threads=3)
    assert len(serial) >= 900 * 8 and np.ptp(serial[..., 0]) > 100.0
    np.testing.assert_array_equal(threaded, serial)
    for obj in bpy.context.scene.objects:
        obj.visible_shadow = False                          # nothing casts: no threads to start
    assert shadow_maps.scene_triangles(bpy.context.evaluated_depsgraph_get(), threads=3).shape == (0, 3, 3)
