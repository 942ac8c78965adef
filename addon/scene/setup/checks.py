"""Scene problems the scattering passes cannot fix by themselves, as messages that say what to
change. The render still runs (no NaN comes out of these cases); the operators report the
messages and the render handlers print them."""
from __future__ import annotations

import bpy
from mathutils import Vector

from ...settings import Sanitized
from .. import names
from ..frame import epipolar_tables

PASSES = (("use_pass_position", "Position"), ("use_pass_z", "Depth"))


def missing_passes(scene) -> list:
    layer = scene.view_layers[0]
    return [label for attribute, label in PASSES if not getattr(layer, attribute)]


def ensure_passes(scene) -> list:
    """Turn the Position and Depth passes the pass reads back on; messages for what was off."""
    missing = missing_passes(scene)
    layer = scene.view_layers[0]
    for attribute, _ in PASSES:
        setattr(layer, attribute, True)
    if missing:
        return [f"the view layer {layer.name!r} had the {' and '.join(missing)} pass(es) off; the "
                "scattering pass needs them and they were turned back on"]
    return []


def camera_problems(scene, depsgraph) -> list:
    """A camera under the ground or inside geometry sees everything in shadow or from inside."""
    camera = scene.camera
    if camera is None:
        return ["the scene has no camera: add one and make it the scene camera"]
    position = camera.evaluated_get(depsgraph).matrix_world.translation
    problems = []
    if position.z < 0.0:
        problems.append(f"the camera {camera.name!r} is {-position.z:.1f} m below the ground level (z = 0), "
                        "where the atmosphere starts; the pass treats it as standing on the ground")
    hit, obj, normal = _surface_above(scene, depsgraph, position)
    if hit and normal.z > 0.0:
        problems.append(f"the camera {camera.name!r} is under the surface of {obj.name!r} (inside the terrain?); "
                        "move it above the surface, or the air it sees is all in shadow")
    return problems


def _surface_above(scene, depsgraph, position):
    """(hit, object, normal) of the first surface straight above ``position``, looking through the
    clouds' shadow-only layer (it is a partial occluder in the sky, not a roof)."""
    up = Vector((0.0, 0.0, 1.0))
    for _ in range(4):
        hit, location, normal, _index, obj, _matrix = scene.ray_cast(depsgraph, position, up)
        if not hit or obj.name != names.CLOUD_SHADOW_OBJECT:
            return hit, obj, normal
        position = location + up * 1e-3
    return False, None, None


def render_problems(scene, depsgraph=None) -> list:
    depsgraph = depsgraph or bpy.context.evaluated_depsgraph_get()
    problems = camera_problems(scene, depsgraph)
    missing = missing_passes(scene)
    if missing:
        problems.append(f"the view layer lacks the {' and '.join(missing)} pass(es) the scattering pass reads; "
                        "run Set Up Scene again or enable them in View Layer > Passes")
    fallback = epipolar_tables.too_large(Sanitized(scene.ols))
    if fallback:
        problems.append(fallback)
    return problems
