"""What the per-frame work reads of the scene, found once before each frame: the camera as
lut_gen's model, the sun's direction and strength (as evaluated for the frame), the settings as
the render reads them and the render size. ``update_frame`` builds one ``FrameState`` and hands
it to the shadow maps, the epipolar tables and the frame values.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....lut_gen.clouds.layer import CloudLayer
from ....lut_gen.passes import render_detail, shadow_map
from ...settings import Sanitized
from .. import sun as sun_lamps


class ShadowMapError(ValueError):
    """The scene cannot have shadow maps (says what to change)."""


def camera_model(scene, depsgraph=None) -> shadow_map.Camera:
    """The scene camera as lut_gen's Camera (position, rotation, tangents of the half field of
    view for the render's aspect), as evaluated in ``depsgraph`` when given."""
    camera = scene.camera
    if camera is None:
        raise ShadowMapError("the scene has no camera: add one and make it the scene camera")
    if depsgraph is not None:
        camera = camera.evaluated_get(depsgraph)
    if camera.data.type != "PERSP":
        raise ShadowMapError(f"light shafts need a perspective camera; {camera.name!r} is {camera.data.type.lower()}")
    matrix = camera.matrix_world
    rotation = np.array(matrix.to_3x3().normalized())
    frame = camera.data.view_frame(scene=scene)
    corners = np.array([tuple(v) for v in frame])
    depth = abs(corners[0, 2])
    tan_half = (float(np.abs(corners[:, 0]).max() / depth), float(np.abs(corners[:, 1]).max() / depth))
    return shadow_map.Camera(np.array(matrix.translation), rotation, tan_half, camera.data.clip_end)


def sun_state(scene, depsgraph=None):
    """(unit direction toward the sun, lamp strength), as evaluated in ``depsgraph`` when given."""
    sun = sun_lamps.find_sun(scene)
    if sun is None:
        raise ShadowMapError("the scene has no Sun lamp: run Set Up Scene or add a Sun lamp")
    if depsgraph is None:
        return sun_lamps.direction_to_sun(sun), sun.data.energy
    evaluated = sun.evaluated_get(depsgraph)
    direction = np.array(evaluated.matrix_world.to_3x3().col[2], dtype=np.float64)
    return direction / np.linalg.norm(direction), evaluated.data.energy


@dataclass(frozen=True)
class FrameState:
    camera: shadow_map.Camera
    sun_direction: np.ndarray       # unit vector toward the sun
    sun_strength: float             # the lamp's strength (W/m^2)
    settings: Sanitized
    render_size: tuple              # (width, height) in pixels
    clip_start: float
    clouds: CloudLayer | None = None    # the cloud layer as evaluated for the frame, while Clouds is on

    def key(self) -> tuple:
        """Hashable: equal for frames whose camera and sun are the same."""
        camera = self.camera
        return (tuple(camera.position), tuple(map(tuple, camera.rotation)), tuple(camera.tan_half_fov),
                camera.clip_end, self.clip_start, tuple(self.sun_direction), self.sun_strength, self.render_size,
                self.clouds)


def read(scene, depsgraph=None) -> FrameState:
    """The frame's state as evaluated in ``depsgraph`` (the scene's own values without one).
    Raises ShadowMapError, which says what to change, without a perspective camera or a sun."""
    camera = camera_model(scene, depsgraph)
    sun_direction, sun_strength = sun_state(scene, depsgraph)
    render = scene.render
    size = render_detail.render_size(render.resolution_x, render.resolution_y, render.resolution_percentage)
    # The clouds as the frame evaluates them: a keyframed offset (wind) moves the shafts with
    # the clouds the world shows, whose drivers read the evaluated scene too.
    evaluated = depsgraph.scene_eval if depsgraph is not None else scene
    clouds = CloudLayer.enabled_in(Sanitized(getattr(evaluated, "ols", scene.ols)))
    return FrameState(camera, sun_direction, float(sun_strength), Sanitized(scene.ols), tuple(size),
                      float(scene.camera.data.clip_start), clouds)
