"""Drivers that feed node-group inputs from the Sun lamp, the scene camera and scene.ols.

All are simple expressions (no Python evaluation needed, so they run without "Auto Run
Python Scripts"). Note: RNA paths index matrices column first: matrix_world[c][r].
"""
from __future__ import annotations


def _drive(socket, index, target_id, data_path, id_type=None, expression="v"):
    return drive_expression(socket, "default_value", index, {"v": (target_id, id_type, data_path)}, expression)


def drive_expression(owner, prop: str, index, variables, expression):
    """A scripted driver on ``owner.prop`` (component ``index``, or the whole property if None)
    with single-property ``variables``: {name: (target ID, its id_type or None, data path)}."""
    curve = owner.driver_add(prop, index) if index is not None else owner.driver_add(prop)
    driver = curve.driver
    driver.type = "SCRIPTED"
    for name, (target_id, id_type, data_path) in variables.items():
        variable = driver.variables.new()
        variable.name = name
        variable.type = "SINGLE_PROP"
        if id_type:
            variable.targets[0].id_type = id_type
        variable.targets[0].id = target_id
        variable.targets[0].data_path = data_path
    driver.expression = expression
    return curve


def drive_sun_direction(socket, sun):
    """Direction toward the sun = the lamp's local +Z axis in world space (column 2)."""
    for axis in range(3):
        _drive(socket, axis, sun, f"matrix_world[2][{axis}]")


def drive_from_lamp(socket, sun, lamp_path: str, index=None):
    _drive(socket, index, sun.data, lamp_path, id_type="LIGHT")


def drive_camera_height(socket, scene):
    """Height of whichever camera is the scene camera (translation z: matrix_world[3][2])."""
    _drive(socket, None, scene, "camera.matrix_world[3][2]", id_type="SCENE")


def drive_camera_axis(socket, axis: int, scene):
    """World x (0) or y (1) of the scene camera."""
    _drive(socket, axis, scene, f"camera.matrix_world[3][{axis}]", id_type="SCENE")


def drive_scene_setting(socket, scene, name: str):
    """The control's value as settings.safe_value reads it: NaN (v != v) gives the default, and a
    value past the control's range (an ID-property write) is clamped into it."""
    prop = scene.ols.bl_rna.properties[name]
    expression = f"min(max(v, {prop.hard_min!r}), {prop.hard_max!r}) if v == v else {prop.default!r}"
    _drive(socket, None, scene, f"ols.{name}", id_type="SCENE", expression=expression)


def drive_switch(socket, scene, name: str):
    """A boolean control as 1.0 / 0.0."""
    _drive(socket, None, scene, f"ols.{name}", id_type="SCENE", expression="1.0 if v else 0.0")


def drive_vector_setting(socket, index, scene, name: str):
    """One component of a vector control; a NaN component (v != v) reads as 0."""
    _drive(socket, index, scene, f"ols.{name}[{index}]", id_type="SCENE", expression="v if v == v else 0.0")


def remove_drivers(tree):
    if tree is not None and tree.animation_data is not None:
        for curve in list(tree.animation_data.drivers):
            tree.animation_data.drivers.remove(curve)

