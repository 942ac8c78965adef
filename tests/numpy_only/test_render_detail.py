"""Level of detail of the per-frame light-shaft data (lut_gen.passes.render_detail): small renders use
shadow maps and epipolar tables no larger than their pixels resolve, and the picture they show
is that of the full settings."""
import numpy as np
import pytest

from lut_gen.passes import render_detail, scattering_pass
from occluders import CAMERA, Scene, fence, pillars, sun_at


def test_caps_follow_the_render_size():
    assert render_detail.epipolar_slices(2048, 64, 36) == 200                # the perimeter
    assert render_detail.epipolar_samples(2048, 64, 36) == 147               # twice the diagonal
    assert render_detail.shadow_map_resolution(4096, 64, 36) == 512          # 8 x 64, a power of two
    assert render_detail.shadow_map_resolution(4096, 160, 90) == 2048        # 1280 -> 2048
    # Below the caps a setting is used as it is, and the panel's smallest values always are.
    assert render_detail.epipolar_slices(128, 64, 36) == 128
    assert render_detail.epipolar_slices(32, 4, 4) == 32 and render_detail.epipolar_samples(32, 4, 4) == 32
    assert render_detail.shadow_map_resolution(512, 4, 4) == 512
    # A capped value is capped again to itself (the add-on's settings arrive capped at the twin).
    for width, height in ((64, 36), (333, 97), (1, 1)):
        for cap in (render_detail.epipolar_slices, render_detail.epipolar_samples, render_detail.shadow_map_resolution):
            once = cap(4096, width, height)
            assert cap(once, width, height) == once


@pytest.mark.parametrize("size", [(1024, 576), (1920, 1080), (576, 1024)])
def test_renders_from_1024_pixels_use_every_setting(size):
    assert render_detail.epipolar_slices(2048, *size) == 2048
    assert render_detail.epipolar_samples(2048, *size) == 2048
    assert render_detail.shadow_map_resolution(4096, *size) == 4096


def test_render_size_follows_the_percentage():
    assert render_detail.render_size(1920, 1080, 25) == (480, 270)
    assert render_detail.render_size(3, 3, 1) == (1, 1)


def shaft_error(image, reference, unshadowed):
    """Summed |image - reference| over the shafts' own effect, |reference - unshadowed|."""
    return np.abs(image - reference).sum() / max(np.abs(reference - unshadowed).sum(), 1e-30)


SUNS = [(4.0, 5.0), (12.0, -20.0)]


@pytest.mark.parametrize("name, boxes", [("pillars", pillars()), ("fence", fence())])
@pytest.mark.parametrize("elevation, azimuth", SUNS)
def test_capped_epipolar_tables_show_what_the_full_ones_show(draft_luts, name, boxes, elevation, azimuth,
                                                             monkeypatch):
    """At 64 x 36, 1024 x 1024 tables (2048 x 2048 cost 4 times more here) are capped to
    200 x 147. The shafts move by at most 6% of their own effect (measured), where the epipolar
    technique itself differs from brute force by 16-63% at this size."""
    scene = Scene(boxes, CAMERA, sun_at(elevation, azimuth), 64, 36)
    unshadowed = scene.shafts(draft_luts, enable_light_shafts=False)
    settings = dict(scattering_technique="EPIPOLAR_SAMPLING", num_integration_steps=16,
                    epipolar_slices=1024, samples_per_slice=1024)
    capped = scene.shafts(draft_luts, **settings)
    monkeypatch.setattr(render_detail, "epipolar_slices", lambda value, w, h: value)
    monkeypatch.setattr(render_detail, "epipolar_samples", lambda value, w, h: value)
    full = scene.shafts(draft_luts, **settings)
    assert np.abs(capped - full).max() > 0.0            # the cap did change the tables
    assert shaft_error(capped, full, unshadowed) <= 0.1, name


@pytest.mark.parametrize("name, boxes", [("pillars", pillars()), ("fence", fence())])
@pytest.mark.parametrize("elevation, azimuth", SUNS)
def test_capped_shadow_maps_show_what_the_full_ones_show(draft_luts, name, boxes, elevation, azimuth):
    """At 64 x 36, 4096-texel cascades are capped to 512: brute-force shafts through the same
    occluders move by 1-7% of their own effect (measured)."""
    cap = render_detail.shadow_map_resolution(4096, 64, 36)
    assert cap == 512
    sun = sun_at(elevation, azimuth)
    images = {resolution: Scene(boxes, CAMERA, sun, 64, 36, resolution=resolution).shafts(
        draft_luts, scattering_technique="BRUTE_FORCE", num_integration_steps=32) for resolution in (cap, 4096)}
    unshadowed = Scene(boxes, CAMERA, sun, 64, 36).shafts(draft_luts, enable_light_shafts=False)
    assert np.abs(images[4096] - unshadowed).max() > 1e-5          # there are shafts to compare
    assert shaft_error(images[cap], images[4096], unshadowed) <= 0.1, name


def test_the_twin_caps_as_the_add_on_does(draft_luts):
    """scattering_pass's epipolar pass at a small size uses the capped grid: 2048 slices there
    give exactly the picture of the capped number."""
    scene = Scene(pillars(), CAMERA, sun_at(6.0, 10.0), 48, 27)
    common = dict(scattering_technique="EPIPOLAR_SAMPLING", num_integration_steps=8)
    big = scene.shafts(draft_luts, epipolar_slices=2048, samples_per_slice=2048, **common)
    same = scene.shafts(draft_luts, epipolar_slices=render_detail.epipolar_slices(2048, 48, 27),
                        samples_per_slice=render_detail.epipolar_samples(2048, 48, 27), **common)
    np.testing.assert_array_equal(big, same)
    assert scattering_pass.PassSettings().epipolar_slices == 512
