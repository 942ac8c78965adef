"""The scene's Sun lamp: the one source of truth for the sun direction (docs/design.md).

Its colour follows the atmosphere's extinction at the scene origin, recomputed when the lamp
turns (depsgraph / frame handlers), from the optical-depth image already in memory.
"""
from __future__ import annotations

import math

import bpy
import numpy as np

from ...lut_gen.model.atmosphere import AtmosphereParams
from . import names

EXTRATERRESTRIAL_STRENGTH = 10.0     # the sample's extraterrestrial sun intensity
SUN_ANGLE = math.radians(0.545)
COLOUR_TOLERANCE = 1e-4


def find_sun(scene):
    """The scene's Sun lamp: the active object if it is one, else the first one found."""
    active = bpy.context.view_layer.objects.active if bpy.context.view_layer else None
    if active is not None and active.type == "LIGHT" and active.data.type == "SUN" and active.name in scene.objects:
        return active
    for obj in scene.objects:
        if obj.type == "LIGHT" and obj.data.type == "SUN":
            return obj
    return None


# A scene without a Sun lamp gets an afternoon sun: high enough that the sky and the lit ground
# light a first test object (Blender's default cube) well; the sample scene sets its own 8 deg.
DEFAULT_ELEVATION_DEG = 35.0


def create_sun(scene, elevation_deg=DEFAULT_ELEVATION_DEG, azimuth_deg=0.0):
    data = bpy.data.lights.new(names.SUN_OBJECT, "SUN")
    data.energy = EXTRATERRESTRIAL_STRENGTH
    data.angle = SUN_ANGLE
    sun = bpy.data.objects.new(names.SUN_OBJECT, data)
    scene.collection.objects.link(sun)
    set_sun_angles(sun, elevation_deg, azimuth_deg)
    return sun


def set_sun_angles(sun, elevation_deg, azimuth_deg):
    """Point the lamp so the direction toward the sun has this elevation and azimuth (from +Y
    toward +X). The lamp shines along its local -Z, so local +Z points at the sun."""
    rotation = (math.radians(90.0 - elevation_deg), 0.0, math.radians(180.0 - azimuth_deg))
    # Called from depsgraph handlers (animate_sun): an unchanged rotation is not written back,
    # or every write would trigger the next update.
    if sun.rotation_mode != "XYZ" or not np.allclose(tuple(sun.rotation_euler), rotation, atol=1e-7):
        sun.rotation_mode = "XYZ"
        sun.rotation_euler = rotation


def direction_to_sun(sun) -> np.ndarray:
    """The lamp's local +Z in world space, from its current rotation: matrix_world lags behind
    a rotation set in a handler until the depsgraph is evaluated again."""
    matrix = sun.matrix_basis
    if sun.parent is not None:
        matrix = sun.parent.matrix_world @ sun.matrix_parent_inverse @ matrix
    direction = np.array(matrix.to_3x3().col[2], dtype=np.float64)
    norm = np.linalg.norm(direction)
    if not np.isfinite(norm) or norm < 1e-9:
        raise SunError(f"the Sun lamp {sun.name!r} has a zero scale or a non-finite rotation, so it points "
                       "nowhere: clear its rotation and scale (Object > Clear > Rotation, Scale) or set them again")
    return direction / norm


class SunError(ValueError):
    """A Sun lamp whose direction is undefined."""


class OriginTransmittance:
    """T(origin -> top) for a sun direction, from the optical-depth image (numpy, per bake)."""

    def __init__(self, image, params: AtmosphereParams, fog_image=None):
        """``fog_image``: the fog's optical-depth image for params with fog. At the origin a
        ray's lowest point is the origin itself, so its stored fog column (divided by the fog
        density there, 1) is the column."""
        self.ground_row = self._ground_row(image)[:, :3]
        if params.has_fog:
            self.ground_row = np.concatenate([self.ground_row, self._ground_row(fog_image)[:, :1]], axis=1)
        self.extinction = params.extinction_matrix()[:self.ground_row.shape[1]]

    @staticmethod
    def _ground_row(image) -> np.ndarray:
        width, height = image.size
        pixels = np.empty(width * height * 4, dtype=np.float32)
        image.pixels.foreach_get(pixels)
        # Image x = height axis, y = cos zenith axis (lut_gen.store.exr_write._images); row 0 at the bottom.
        return pixels.reshape(height, width, 4)[:, 0, :].astype(np.float64)

    def __call__(self, cos_sun_zenith: float) -> np.ndarray:
        n = len(self.ground_row)
        x = float(np.clip((cos_sun_zenith * 0.5 + 0.5) * n - 0.5, 0, n - 1))
        i0 = min(int(x), n - 2)
        net = self.ground_row[i0] * (1 - (x - i0)) + self.ground_row[i0 + 1] * (x - i0)
        return np.exp(-np.minimum(net @ self.extinction, 80.0))


def update_sun_colour(sun, transmittance: OriginTransmittance) -> bool:
    """Set the lamp colour to the extinction at the origin; True when it changed."""
    colour = transmittance(direction_to_sun(sun)[2])
    if np.abs(np.array(sun.data.color) - colour).max() <= COLOUR_TOLERANCE:
        return False
    sun.data.color = colour.tolist()
    return True
