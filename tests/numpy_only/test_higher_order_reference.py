"""The second scattering order: the brute-force reference, and the baker checked against it.

``reference.second_order`` integrates J2 (a sphere integral of ``reference.single_scattering``
against the phase functions) along the view ray with its own quadratures; it shares no code
with the baker. The fast tests check the reference itself (the sphere rule against exact
phase-function integrals and against an independent Fibonacci-sphere rule, quadratic scaling
in the optically thin limit, zero-length rays); the slow ones check its convergence and
compare ``bake(orders=2)``'s "higher" table (exactly the 2nd order) with it on representative
rays.
"""
import math

import numpy as np
import pytest

from lut_gen.verify import reference as ref
from lut_gen.model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase
from lut_gen.model.profiles import mie_density, rayleigh_density
from rays import ray

# The sample's three-channel media with a black ground: the reference integrates exactly
# these. The spectral media and the ground are checked against the Monte Carlo path tracer
# (tests/numpy_only/test_multiple_scattering_mc.py).
PARAMS = AtmosphereParams(spectral=False, ozone=False, ground_albedo=0.0)


RAYS = {
    "ground, zenith, sun 45": ray(0, 0, 45, 0),
    "ground, zenith, sun 80": ray(0, 0, 80, 0),
    "ground, view 85, sun 45, azimuth 90": ray(0, 85, 45, 90),
    "ground, view 85, sun 80, toward sun": ray(0, 85, 80, 0),
    "ground, view 85, sun 80, away from sun": ray(0, 85, 80, 180),
    "ground, view 60, sun 45, toward sun": ray(0, 60, 45, 0),
    "ground, view 60, sun 45, away from sun": ray(0, 60, 45, 180),
    "5 km, view 30, sun 45, azimuth 120": ray(5000, 30, 45, 120),
    "5 km, view 110 (to the ground), sun 45, azimuth 60": ray(5000, 110, 45, 60),
}

# Baker vs reference: every ray and channel within this relative error, the median of all
# within MEDIAN_TOLERANCE. (The reference converges to < 1%, see test_second_order_converges.)
RAY_TOLERANCE = 0.15
MEDIAN_TOLERANCE = 0.05


def thin(factor):
    return AtmosphereParams(
        spectral=False, ozone=False, ground_albedo=0.0,
        rayleigh_scattering=tuple(x * factor for x in PARAMS.rayleigh_scattering),
        mie_scattering=tuple(x * factor for x in PARAMS.mie_scattering),
    )


# -- the reference itself (fast) ------------------------------------------------------------

@pytest.mark.parametrize("height", [0.0, 5_000.0, 80_000.0])
@pytest.mark.parametrize("view", [(0, 0, 1), (1, 0, 0.05), (1, 0, -0.3), (0.3, 0.5, 0.5), (0, 0, -1)])
def test_sphere_rule_integrates_phase_functions_to_one(height, view):
    rayleigh, mie = ref.sphere_phase_integrals(PARAMS, height, view, sun_dir=(0.5, 0.3, 0.7))
    assert rayleigh == pytest.approx(1.0, abs=1e-9)
    assert mie == pytest.approx(1.0, abs=2e-4)


def fibonacci_source(params, h, cos_view, cos_sun, cos_sun_view, n=5000):
    """J2 with an independent rule: n points of a Fibonacci sphere, equal weights 4 pi / n."""
    sin_v, sin_s = math.sqrt(1 - cos_view**2), math.sqrt(1 - cos_sun**2)
    v = np.array([sin_v, 0.0, cos_view])
    cos_phi = (cos_sun_view - cos_view * cos_sun) / (sin_v * sin_s) if sin_v * sin_s > 0 else 1.0
    cos_phi = min(max(cos_phi, -1.0), 1.0)
    l = np.array([sin_s * cos_phi, sin_s * math.sqrt(1 - cos_phi**2), cos_sun])
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = math.pi * (1 + math.sqrt(5)) * i
    w = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=-1)
    l1 = ref.single_scattering(params, h, w[:, 2], cos_sun, w @ l, steps=32, sun_steps=16)
    c = w @ v
    kernel = (params.rayleigh * rayleigh_density(params, h) * rayleigh_phase(c)[:, None]
              + params.mie * mie_density(params, h) * mie_phase(c, params.mie_g)[:, None])
    return (kernel * l1).sum(axis=0) * 4 * math.pi / n


@pytest.mark.parametrize("point", [(1000.0, 0.3, 0.7, 0.2), (0.0, 1.0, 0.5, 0.5), (5000.0, -0.2, 0.17, 0.9)])
def test_source_matches_fibonacci_sphere(point):
    # Measured agreement: < 0.1% (the two rules share only single_scattering).
    got = ref.second_order_source(PARAMS, *point)
    want = fibonacci_source(PARAMS, *point)
    np.testing.assert_allclose(got, want, rtol=5e-3)


def test_second_order_is_quadratic_in_scattering_when_thin():
    rays = np.array([RAYS["ground, view 60, sun 45, toward sun"], RAYS["5 km, view 30, sun 45, azimuth 120"]])
    cheap = dict(ray_steps=8, sphere_zeniths=6, sphere_azimuths=12, l1_steps=16, l1_sun_steps=8)
    a = ref.second_order(thin(1e-4), *rays.T, **cheap)
    b = ref.second_order(thin(2e-4), *rays.T, **cheap)
    assert np.all(a > 0)
    np.testing.assert_allclose(b / a, 4.0, rtol=2e-3)


def test_second_order_zero_length_ray_and_shapes():
    top = PARAMS.atmosphere_height
    out = ref.second_order(PARAMS, np.array([[top], [top]]), 1.0, 0.5, np.array([0.5, 0.4]),
                           ray_steps=4, sphere_zeniths=2, sphere_azimuths=4, l1_steps=4, l1_sun_steps=2)
    assert out.shape == (2, 2, 3)
    assert np.all(out == 0.0)


# -- convergence and the baker (slow) ----------------------------------------------------------

@pytest.mark.slow
def test_second_order_converges():
    # The ray that converges slowest (grazing, toward a low sun: Mie peak of L1 next to the
    # horizon jump). Measured: sphere x2 0.54%, ray and L1 steps x2 < 0.02%, every setting x2
    # on all RAYS <= 0.53%.
    r = RAYS["ground, view 85, sun 80, toward sun"]
    base = ref.second_order(PARAMS, *r)
    finer_sphere = ref.second_order(PARAMS, *r, sphere_zeniths=32, sphere_azimuths=64)
    finer_rays = ref.second_order(PARAMS, *r, ray_steps=64, l1_steps=64, l1_sun_steps=32,
                                  transmittance_steps=256)
    np.testing.assert_allclose(base, finer_sphere, rtol=1e-2)
    np.testing.assert_allclose(base, finer_rays, rtol=1e-2)


@pytest.fixture(scope="module")
def luts():
    import lut_gen

    return lut_gen.bake(PARAMS, resolution="default", orders=2)


@pytest.fixture(scope="module")
def reference_values():
    return {name: ref.second_order(PARAMS, *r) for name, r in RAYS.items()}


def relative_error(luts, reference_values, name):
    got = luts.sky_radiance(*RAYS[name], table="higher").astype(np.float64)
    want = reference_values[name]
    return got / want - 1.0


@pytest.mark.slow
@pytest.mark.parametrize("name", list(RAYS))
def test_baked_second_order_matches_reference(luts, reference_values, name):
    err = relative_error(luts, reference_values, name)
    assert np.all(np.abs(err) <= RAY_TOLERANCE), f"{name}: relative error (r, g, b) {np.round(err * 100, 1)} %"


@pytest.mark.slow
def test_baked_second_order_median_error(luts, reference_values):
    errors = np.array([relative_error(luts, reference_values, name) for name in RAYS])
    assert np.median(np.abs(errors)) <= MEDIAN_TOLERANCE, np.round(errors * 100, 1)
