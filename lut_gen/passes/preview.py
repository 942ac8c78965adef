"""Sky preview from baked tables: panoramas of the sky dome at several sun elevations.

Used by ``python -m lut_gen sample`` so a bake can be looked at without Blender.
"""
from __future__ import annotations

import numpy as np

from ..tables.lookup import Luts
from ..model.sun_disc import limb_profile
from . import sky_view

# The sample's extraterrestrial sun: intensity 10, scattering scale 0.5 (docs/lut_gen.md: Parameters).
SUN_INTENSITY = 10.0
SCATTERING_SCALE = 0.5
MIDDLE_GRAY = 0.18
SUN_ANGULAR_RADIUS = np.radians(0.545)   # drawn a little larger than the real 0.27 deg
DEFAULT_SUN_ELEVATIONS = (45.0, 12.0, 3.0, -3.0, -6.0)
RGB_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def sky_panorama(luts: Luts, sun_elevation_deg: float, width: int = 512, height: int = 128,
                 camera_height_m: float = 2.0) -> np.ndarray:
    """(height, width, 3) linear radiance of the sky and the lit ground below it: azimuth
    0..360 deg left to right (sun at 180 deg, the centre), elevation 90 deg (top) to -10 deg
    (bottom)."""
    az = (np.arange(width) + 0.5) / width * 2 * np.pi - np.pi           # 0 at the sun
    el = np.radians(90.0 - (np.arange(height) + 0.5) / height * 100.0)
    el, az = np.meshgrid(el, az, indexing="ij")
    cos_view = np.sin(el)
    sun_el = np.radians(sun_elevation_deg)
    cos_sun = np.sin(sun_el)
    cos_sun_view = np.sin(el) * np.sin(sun_el) + np.cos(el) * np.cos(sun_el) * np.cos(az)
    # The sky the world shows: the look-up and the camera's twilight correction.
    view = sky_view.compute(luts, camera_height_m, cos_sun)
    sky = sky_view.camera_sky(luts, view, cos_view, cos_sun_view) * (SUN_INTENSITY * SCATTERING_SCALE)
    sky += luts.ground_radiance(camera_height_m, cos_view, cos_sun, cos_sun_view) * SUN_INTENSITY
    # The disc is drawn twice the real sun's size (a pixel is 0.7 deg) and 50x dimmer than the sun
    # so the tone mapping keeps the sky; limb-darkened as the world shows it.
    disc = limb_profile(cos_sun_view, 2.0 * SUN_ANGULAR_RADIUS)
    sun = luts.transmittance_to_top(camera_height_m, cos_sun)[None, None, :] * SUN_INTENSITY * 50.0
    return sky + disc * sun


def tone_map(radiance: np.ndarray) -> np.ndarray:
    """The sample's "Exp" operator with auto exposure from the log-average luminance."""
    lum = np.maximum(radiance @ RGB_LUMINANCE, 1e-12)
    average = np.exp(np.mean(np.log(lum)))
    scaled = radiance * (MIDDLE_GRAY / average)
    return 1.0 - np.exp(-scaled)


def preview_image(luts: Luts, sun_elevations=DEFAULT_SUN_ELEVATIONS, width: int = 512, height: int = 128) -> np.ndarray:
    """Panoramas stacked top to bottom, each tone mapped on its own, 4-pixel gaps between."""
    rows = []
    for elevation in sun_elevations:
        rows.append(tone_map(sky_panorama(luts, elevation, width, height)))
        rows.append(np.zeros((4, width, 3)))
    return np.concatenate(rows[:-1], axis=0)
