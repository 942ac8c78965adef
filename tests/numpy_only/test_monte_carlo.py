"""The Monte Carlo path tracer (lut_gen.verify.monte_carlo), checked against the brute-force quadratures.

Single scattering and the second order of the path tracer must agree with
``reference.single_scattering`` and ``reference.second_order`` within their statistical error;
the directly sunlit ground it sees must be the product of the transmittances; in an
optically thin atmosphere order n must scale as the n-th power of the scattering coefficient.
"""
import dataclasses
import math

import numpy as np
import pytest

from lut_gen.verify import reference as ref
from lut_gen.model import spectrum
from lut_gen.model.atmosphere import AtmosphereParams
from lut_gen.verify.monte_carlo import radiance_by_order
from rays import ray

PARAMS = AtmosphereParams(spectral=False, ozone=False, ground_albedo=0.0)
# The default clear sky (ozone, absorbing aerosols, a grey ground) at the three sample wavelengths.
CLEAR_SKY = spectrum.triple_params(AtmosphereParams(ground_albedo=0.3), (680.0, 550.0, 440.0))
# Statistical tolerance: SIGMAS standard errors plus a relative margin for the references'
# own quadrature error.
SIGMAS = 4.0
SINGLE_MARGIN = 0.02
SECOND_MARGIN = 0.03


RAYS = {
    "ground, zenith, sun 60": ray(0, 0, 60, 0),
    "ground, horizon, sun 60, azimuth 110": ray(0, 90, 60, 110),
    "ground, view 75, sun 78, toward sun": ray(0, 75, 78, 0),
    "1 km, view 120 (to the ground), sun 50, azimuth 60": ray(1000, 120, 50, 60),
    "8 km, view 84, sun 93 (twilight), azimuth 20": ray(8000, 84, 93, 20),
}


def assert_within_error(estimate, se, expected, margin):
    tolerance = SIGMAS * se + margin * np.abs(expected)
    assert np.all(np.abs(estimate - expected) <= tolerance), (estimate, expected, se)


@pytest.mark.parametrize("name", list(RAYS))
def test_single_scattering_matches_reference(name):
    result = radiance_by_order(PARAMS, *RAYS[name], orders=1, paths=8192)
    expected = ref.single_scattering(PARAMS, *RAYS[name])
    assert np.all(expected > 0.0)
    assert_within_error(result.atmosphere[0], result.atmosphere_se[0], expected, SINGLE_MARGIN)


@pytest.mark.parametrize("name", ["ground, zenith, sun 60", "1 km, view 120 (to the ground), sun 50, azimuth 60"])
@pytest.mark.parametrize("media", ["clear sky", "dense absorbing haze"])
def test_single_scattering_with_absorption_matches_reference(name, media):
    params = CLEAR_SKY
    if media == "dense absorbing haze":
        params = dataclasses.replace(CLEAR_SKY, aerosol_density=4.0, aerosol_absorption=1.0)
    result = radiance_by_order(params, *RAYS[name], orders=1, paths=8192)
    expected = ref.single_scattering(params, *RAYS[name])
    assert_within_error(result.atmosphere[0], result.atmosphere_se[0], expected, SINGLE_MARGIN)


@pytest.mark.parametrize("name", ["ground, zenith, sun 60", "1 km, view 120 (to the ground), sun 50, azimuth 60"])
def test_second_order_matches_reference(name):
    result = radiance_by_order(PARAMS, *RAYS[name], orders=2, paths=16384)
    expected = ref.second_order(PARAMS, *RAYS[name])
    assert np.all(result.atmosphere_se[1] < 0.02 * result.atmosphere[1])
    assert_within_error(result.atmosphere[1], result.atmosphere_se[1], expected, SECOND_MARGIN)


def test_black_ground_and_sky_views_have_no_ground_term():
    down = RAYS["1 km, view 120 (to the ground), sun 50, azimuth 60"]
    black = radiance_by_order(PARAMS, *down, orders=3, paths=2048)
    assert np.all(black.ground == 0.0) and np.all(black.ground_se == 0.0)
    sky = radiance_by_order(CLEAR_SKY, *RAYS["ground, zenith, sun 60"], orders=3, paths=2048)
    assert np.all(sky.ground == 0.0) and np.all(sky.ground_se == 0.0)


def test_directly_lit_ground_is_transmittance_times_lambert():
    """ground[0] = T(viewer -> ground) albedo / pi cos(sun zenith at the ground) T_sun(ground)."""
    height, mu_v, mu_s, _ = RAYS["1 km, view 120 (to the ground), sun 50, azimuth 60"]
    # Sun in the plane of the view (azimuth 0), to build the ground point's vectors simply.
    sin_v, sin_s = math.sqrt(1.0 - mu_v ** 2), math.sqrt(1.0 - mu_s ** 2)
    result = radiance_by_order(CLEAR_SKY, height, mu_v, mu_s, mu_v * mu_s + sin_v * sin_s, orders=2, paths=2048)
    big_r = CLEAR_SKY.earth_radius
    viewer = np.array([0.0, 0.0, big_r + height])
    view = np.array([sin_v, 0.0, mu_v])
    sun = np.array([sin_s, 0.0, mu_s])
    b = viewer @ view
    ground_point = viewer + (-b - math.sqrt(b * b - (viewer @ viewer - big_r ** 2))) * view
    normal = ground_point / big_r
    # The view ray's transmittance: the ray from the ground up through the viewer to the top,
    # divided by the viewer's part of it.
    t_view = (ref.transmittance_to_top(CLEAR_SKY, 0.0, normal @ -view)
              / ref.transmittance_to_top(CLEAR_SKY, height, -mu_v))
    t_sun = ref.transmittance_to_top(CLEAR_SKY, 0.0, normal @ sun)
    expected = t_view * CLEAR_SKY.ground_albedo / math.pi * (normal @ sun) * t_sun
    np.testing.assert_allclose(result.ground[0], expected, rtol=1e-3)
    assert np.all(result.ground_se[0] < 1e-6 * expected)  # no randomness in this term
    # Sky light reflected by that ground: there, and weaker than the sun's under a high sun.
    assert np.all(result.ground[1] > 4.0 * result.ground_se[1])
    assert np.all(result.ground[1] < result.ground[0])


def test_bright_ground_adds_to_higher_orders_only():
    down = RAYS["1 km, view 120 (to the ground), sun 50, azimuth 60"]
    black = radiance_by_order(dataclasses.replace(CLEAR_SKY, ground_albedo=0.0), *down, orders=2, paths=8192)
    grey = radiance_by_order(CLEAR_SKY, *down, orders=2, paths=8192, seed=1)
    se = np.hypot(black.atmosphere_se, grey.atmosphere_se)
    assert np.all(np.abs(grey.atmosphere[0] - black.atmosphere[0]) <= SIGMAS * se[0])
    assert np.all(grey.atmosphere[1] - black.atmosphere[1] > SIGMAS * se[1])


def thin(factor):
    """Pure Rayleigh scattering (no absorption, no Mie, black ground), scaled by factor."""
    return AtmosphereParams(spectral=False, ozone=False, ground_albedo=0.0, mie_scattering=(0.0, 0.0, 0.0),
                            rayleigh_scattering=tuple(x * factor for x in PARAMS.rayleigh_scattering))


def test_orders_scale_with_scattering_when_thin():
    """Optically thin: order n ~ beta^n, so each order is far below the one before and halving
    beta divides order n by 2^n (the same seed keeps the two estimates correlated)."""
    geometry = RAYS["ground, zenith, sun 60"]
    a = radiance_by_order(thin(0.01), *geometry, orders=3, paths=8192)
    b = radiance_by_order(thin(0.005), *geometry, orders=3, paths=8192)
    assert np.all(a.atmosphere_se < 0.1 * a.atmosphere)
    assert np.all(a.atmosphere[1] < 0.02 * a.atmosphere[0])
    assert np.all(a.atmosphere[2] < 0.02 * a.atmosphere[1])
    for order, rtol in ((1, 0.01), (2, 0.05), (3, 0.1)):
        np.testing.assert_allclose(a.atmosphere[order - 1] / b.atmosphere[order - 1], 2.0 ** order, rtol=rtol)


def test_orders_fall_off_in_the_default_atmosphere():
    result = radiance_by_order(PARAMS, *RAYS["ground, zenith, sun 60"], orders=4, paths=8192)
    assert np.all(np.diff(result.atmosphere, axis=0) < 0.0)
    assert np.all(result.atmosphere_se < 0.2 * result.atmosphere)
    # The orders of a path are correlated: the sum's error is not the root sum of squares.
    higher, higher_se = result.atmosphere_sum(1, 4)
    np.testing.assert_allclose(higher, result.atmosphere[1:].sum(axis=0))
    assert np.all(higher_se < 0.03 * higher)
    assert np.all(higher_se > result.atmosphere_se[1])


def test_seeds_paths_and_validation():
    geometry = RAYS["ground, horizon, sun 60, azimuth 110"]
    first = radiance_by_order(PARAMS, *geometry, orders=2, paths=2048, seed=5)
    again = radiance_by_order(PARAMS, *geometry, orders=2, paths=2048, seed=5)
    other = radiance_by_order(PARAMS, *geometry, orders=2, paths=2048, seed=6)
    np.testing.assert_array_equal(first.atmosphere, again.atmosphere)
    assert not np.array_equal(first.atmosphere, other.atmosphere)
    more = radiance_by_order(PARAMS, *geometry, orders=2, paths=8192, seed=7)
    ratio = first.atmosphere_se[0] / more.atmosphere_se[0]  # sqrt(4) = 2 expected
    assert np.all((ratio > 1.5) & (ratio < 2.7))
    assert first.atmosphere.shape == first.ground.shape == (2, 3) and first.paths == 2048
    with pytest.raises(ValueError):
        radiance_by_order(AtmosphereParams(), *geometry)
    with pytest.raises(ValueError):
        radiance_by_order(PARAMS, *geometry, orders=0)
