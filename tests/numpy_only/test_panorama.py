"""lut_gen.passes.panorama: the world-lighting panoramas equal the per-pixel look-ups they replace
(Luts.sky_radiance and Luts.ground_radiance on every view direction)."""
import dataclasses

import numpy as np
import pytest

from lut_gen.passes import panorama

SIZE = (512, 256)               # the add-on's (addon/scene/frame/skylight.py)
SUN_ELEVATIONS_DEG = (60.0, 3.0, -5.0, 90.0)
CAMERA_HEIGHTS_M = (0.0, 500.0, 20_000.0)


def sun_direction(elevation_deg):
    e = np.radians(elevation_deg)
    return np.array([0.6 * np.cos(e), 0.8 * np.cos(e), np.sin(e)])


def per_pixel(luts, sun, height):
    """What the add-on computed before lut_gen.passes.panorama."""
    d = panorama.directions(*SIZE)
    view = (max(height, 0.0), d[..., 2], sun[2], d @ sun)
    return luts.sky_radiance(*view), luts.ground_radiance(*view)


def worst_relative_difference(fast, slow):
    """Largest |fast - slow| / slow where slow is above 1e-6 of its maximum, and below that the
    largest |fast - slow| in units of the maximum."""
    significant = slow > 1e-6 * slow.max()
    difference = np.abs(fast.astype(np.float64) - slow)
    return max((difference[significant] / slow[significant]).max(initial=0.0),
               (difference[~significant] / max(slow.max(), 1e-30)).max(initial=0.0))


@pytest.mark.parametrize("height", CAMERA_HEIGHTS_M)
@pytest.mark.parametrize("elevation", SUN_ELEVATIONS_DEG)
def test_panoramas_equal_the_per_pixel_look_ups(draft_luts, elevation, height):
    sun = sun_direction(elevation)
    sky, ground = panorama.panoramas(draft_luts, sun, height, SIZE)
    sky_ref, ground_ref = per_pixel(draft_luts, sun, height)
    assert sky.shape == sky_ref.shape == (SIZE[1], SIZE[0], 3)
    assert ground.shape == ground_ref.shape
    assert sky_ref.max() > 0 and ground_ref.max() > 0
    # The same products summed in the same order: measured equal to the bit (draft and default
    # tables); float32 rounding is the bound promised.
    assert worst_relative_difference(sky, sky_ref) <= 1e-5
    assert worst_relative_difference(ground, ground_ref) <= 1e-5
    assert np.all(ground[ground_ref == 0] == 0)


@pytest.mark.parametrize("elevation", (3.0, -5.0))
def test_panoramas_equal_the_per_pixel_look_ups_default_tables(default_luts, elevation):
    """The tables the add-on uses, packed as it keeps them (Luts.keep_packed; a copy of the
    shared fixture, whose other users do not pay for the packed tables)."""
    sun = sun_direction(elevation)
    packed = dataclasses.replace(default_luts, _packed=None).keep_packed()
    sky, ground = panorama.panoramas(packed, sun, 500.0, SIZE)
    sky_ref, ground_ref = per_pixel(default_luts, sun, 500.0)
    assert worst_relative_difference(sky, sky_ref) <= 1e-5
    assert worst_relative_difference(ground, ground_ref) <= 1e-5
