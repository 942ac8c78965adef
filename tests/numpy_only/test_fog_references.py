"""The references with the fog layer: the deterministic reference against closed forms, the
Monte Carlo path tracer's single scattering against the reference, and the tracer's energy
balance in a white fog over a white ground.

Closed forms: on a *vertical* ray the height is exactly h + s (or h - s), so the fog density
along it, exp(-(h + s) / H), and every integral of it are exact in the spherical atmosphere
(a "horizontal" segment is not: a straight ray rises by s^2 / 2R, and the Chapman function is
the closed form there). With the sun at the zenith too, the sun rays are vertical as well:

* zenith column from h:  N_F(h) = H e^{-h/H} (1 - e^{-(top - h)/H}),  T = exp(-beta_F N_F);
* horizontal column from the ground: H x e^x K1(x), x = R / H (Chapman at 90 deg; the part
  beyond the top is e^{-top/H}, nothing);
* looking up at the zenith with the sun there (nu = 1): the view path from the camera to a
  point and the sun path from the point to the top add up to the camera's own column, so
  T_view T_sun = e^{-tau} at every point and L = p_F(1) tau e^{-tau}, tau = beta_F N_F(h);
* looking straight down from h with the sun at the zenith (nu = -1): with v = e^{-z/H},
  L = p_F(-1) int_0^h beta e^{-z/H} e^{-beta H (v - v_h)} e^{-beta H v} dz
    = p_F(-1) / 2 (e^{-beta H v_h} - e^{-2 beta H + beta H v_h}),  v_h = e^{-h/H}.

p_F is mie_phase(., fog_g): a fog of pure scatterers (Rayleigh, Mie, ozone switched off).
"""
import dataclasses
import math

import numpy as np
import pytest

from lut_gen.model.atmosphere import AtmosphereParams, mie_phase
from lut_gen.verify import cloud_monte_carlo, fog, reference as ref, reference_rays
from lut_gen.verify.monte_carlo import radiance_by_order
from rays import ray_by_elevation as ray

PURE_FOG = dict(spectral=False, ozone=False, ground_albedo=0.0,
                rayleigh_scattering=(0.0, 0.0, 0.0), mie_scattering=(0.0, 0.0, 0.0))


def pure_fog(visibility, height, g=0.85):
    return AtmosphereParams(**PURE_FOG, fog_visibility=visibility, fog_height=height, fog_g=g)


def zenith_column(p, h):
    big_h = p.fog_height
    return big_h * math.exp(-h / big_h) * -math.expm1(-(p.atmosphere_height - h) / big_h)


# -- the deterministic reference: closed forms ---------------------------------------------------

@pytest.mark.parametrize("big_h", [10.0, 50.0, 500.0])
@pytest.mark.parametrize("h", [0.0, 20.0, 300.0])
def test_fog_zenith_column_and_transmittance_are_exact(big_h, h):
    p = pure_fog(100.0, big_h)
    net = ref.net_density_to_top(p, h, 1.0)
    assert net[3] == pytest.approx(zenith_column(p, h), rel=1e-9)
    np.testing.assert_allclose(ref.transmittance_to_top(p, h, 1.0), math.exp(-p.fog * zenith_column(p, h)), rtol=1e-9)
    # A vertical segment of 3 H from h: H e^{-h/H} (1 - e^{-3}).
    seg = ref.fog_net_density(p, h, 1.0, 3.0 * big_h)
    assert seg == pytest.approx(big_h * math.exp(-h / big_h) * -math.expm1(-3.0), rel=1e-9)


@pytest.mark.parametrize("big_h", [10.0, 50.0, 500.0])
def test_fog_horizontal_column_is_chapman(big_h):
    p = pure_fog(100.0, big_h)
    x = p.earth_radius / big_h
    chapman = big_h * math.sqrt(math.pi * x / 2) * (1 + 3 / (8 * x) - 15 / (128 * x * x) + 315 / (3072 * x ** 3))
    assert ref.net_density_to_top(p, 0.0, 0.0)[3] == pytest.approx(chapman, rel=1e-8)
    # The low-step sun-ray quadrature (single scattering's 64 steps) resolves it as well.
    assert ref.net_density_to_top(p, 0.0, 0.0, steps=64)[3] == pytest.approx(chapman, rel=1e-8)


@pytest.mark.parametrize("visibility, big_h, h", [(1000.0, 50.0, 2.0), (1000.0, 50.0, 120.0), (20.0, 50.0, 2.0),
                                                  (100.0, 10.0, 0.0), (200.0, 500.0, 40.0)])
def test_fog_single_scattering_up_and_down_is_exact(visibility, big_h, h):
    p = pure_fog(visibility, big_h)
    tau = p.fog * zenith_column(p, h)
    want_up = mie_phase(1.0, p.fog_g) * tau * math.exp(-tau)
    # The default steps within 3e-5 (the view ray's trapezoid: 3e-6 for H = 50 m, 2e-5 for 10 m
    # on an 80 km ray), converging to the closed form with more steps.
    np.testing.assert_allclose(ref.single_scattering(p, h, 1.0, 1.0, 1.0), want_up, rtol=3e-5)
    np.testing.assert_allclose(ref.single_scattering(p, h, 1.0, 1.0, 1.0, steps=1024), want_up, rtol=1e-7)
    if h > 0.0:
        bh, vh = p.fog * big_h, math.exp(-h / big_h)
        want = mie_phase(-1.0, p.fog_g) / 2 * (math.exp(-bh * vh) - math.exp(-2 * bh + bh * vh))
        np.testing.assert_allclose(ref.single_scattering(p, h, -1.0, 1.0, -1.0), want, rtol=3e-5)


def test_fog_phase_is_its_own():
    """The fog scatters with mie_phase(., fog_g), not the aerosol's mie_g, and adds to the air."""
    p = pure_fog(1000.0, 50.0, g=0.6)
    tau = p.fog * zenith_column(p, 2.0)
    got = ref.single_scattering(p, 2.0, 1.0, 1.0, 1.0)
    np.testing.assert_allclose(got, mie_phase(1.0, 0.6) * tau * math.exp(-tau), rtol=3e-5)
    assert abs(got[0] / (mie_phase(1.0, p.mie_g) * tau * math.exp(-tau)) - 1.0) > 0.1
    # Without fog the same params are the air's single scattering, and with it more light.
    air = AtmosphereParams(spectral=False, ozone=False, ground_albedo=0.0)
    foggy = dataclasses.replace(air, fog_visibility=1000.0, fog_height=50.0)
    args = ray(2.0, 10.0, 20.0, 0.0)
    assert np.all(ref.single_scattering(foggy, *args) > 1.5 * ref.single_scattering(air, *args))


def test_fog_single_scattering_converges_when_steps_double():
    rays = np.array([ray(2, 10, 5, 0), ray(2, 0, 5, 90), ray(500, -10, 5, 0), ray(125, 0, 5, 0),
                     ray(2, -5, 40, 180)]).T
    for visibility in (100.0, 1000.0):
        p = AtmosphereParams(spectral=False, ozone=True, ground_albedo=0.0, fog_visibility=visibility, fog_height=50.0)
        a = ref.single_scattering(p, *rays)
        b = ref.single_scattering(p, *rays, steps=512, sun_steps=128)
        assert np.all(b > 0)
        assert (np.abs(a - b) / b).max() < 2e-4


# -- the path tracer's single scattering against the reference ------------------------------------

MC_RAYS = {
    "2 m, up 10, sun 20 toward": ray(2.0, 10.0, 20.0, 0.0),
    "2 m, up 10, sun 20 away": ray(2.0, 10.0, 20.0, 180.0),
    "500 m, down 10, sun 20 toward": ray(500.0, -10.0, 20.0, 0.0),
    "500 m, down 10, sun 20 away": ray(500.0, -10.0, 20.0, 180.0),
}
SIGMAS = 4.0
MARGIN = 0.005  # the reference's own quadrature is ~1e-5


@pytest.mark.parametrize("visibility", [1000.0, 5000.0])
@pytest.mark.parametrize("name", list(MC_RAYS))
def test_monte_carlo_single_scattering_in_fog_matches_reference(name, visibility):
    p = fog.fog_params(visibility, 50.0)  # air, aerosol, ozone and the fog
    result = radiance_by_order(p, *MC_RAYS[name], orders=1, paths=8192, seed=3)
    want = ref.single_scattering(p, *MC_RAYS[name])
    air = ref.single_scattering(dataclasses.replace(p, fog_visibility=0.0), *MC_RAYS[name])
    assert np.max(np.abs(want - air) / want) > 0.1  # the fog matters on every ray
    tolerance = SIGMAS * result.atmosphere_se[0] + MARGIN * want
    assert np.all(np.abs(result.atmosphere[0] - want) <= tolerance), (result.atmosphere[0], want, result.atmosphere_se[0])


@pytest.mark.parametrize("visibility, big_h", [(500.0, 50.0), (100.0, 10.0), (1000.0, 300.0)])
def test_monte_carlo_sees_the_sunlit_ground_through_the_fog(visibility, big_h):
    """The directly sunlit ground (the tracer's ground[0], no randomness in it): albedo / pi x
    cos(sun zenith at the ground point) x T_sun x T_view, with the reference's transmittances
    (T_view: the reversed view ray from the ground point to the top over the same line from
    the camera). Checks the tracer's own quadrature of the fog along sun and view rays."""
    p = fog.fog_params(visibility, big_h, ground_albedo=0.4)
    h, mu_v, mu_s, nu = ray(300.0, -20.0, 30.0, 90.0)
    result = radiance_by_order(p, h, mu_v, mu_s, nu, orders=1, paths=16, seed=1)
    camera = np.array([0.0, 0.0, p.earth_radius + h])
    view = np.array([math.sqrt(1 - mu_v ** 2), 0.0, mu_v])
    sun = np.array([0.0, math.sqrt(1 - mu_s ** 2), mu_s])  # azimuth 90 from the view
    assert abs(view @ sun - nu) < 1e-12
    d = reference_rays._distance_to_ground(p, camera[2], mu_v)
    ground = camera + d * view
    up = ground / np.linalg.norm(ground)
    sun_there = float(up @ sun)
    back = float(-view @ up)
    net = ref.net_density_to_top(p, np.array([0.0, h]), np.array([back, -mu_v]))
    t_view = np.exp(-(net[0] - net[1]) @ p.extinction_matrix())
    t_sun = ref.transmittance_to_top(p, 0.0, sun_there)
    want = p.ground_albedo / math.pi * sun_there * t_sun * t_view
    assert np.all(t_view < 0.97)  # the fog is in the way
    np.testing.assert_allclose(result.ground[0], want, rtol=1e-4)


@pytest.mark.parametrize("visibility, height", [(200.0, 30.0), (5000.0, 60.0)])
def test_monte_carlo_scatters_fog_with_its_own_phase(visibility, height):
    """The tracer's scattering step at a point of air, aerosol and fog: its weights (kernel over
    proposal pdf) average to the total scattering coefficient and, times the cosine of the turn,
    to sum_X beta_X <cos>_X with each medium's own phase function (the fog's fog_g = 0.6, the
    aerosol's mie_g = 0.7: a fog drawn or weighted with the aerosol's g is 15% off). The energy
    balance below cannot see this (any phase function conserves energy)."""
    from lut_gen.model.atmosphere import rayleigh_phase
    from lut_gen.verify import monte_carlo_events, monte_carlo_media
    p = fog.fog_params(visibility, 50.0, fog_g=0.6)
    media = monte_carlo_media._Media.of(p)
    n = 50_000
    points = np.repeat(np.array([[0.0, 0.0, p.earth_radius + height]]), n, axis=0)
    incoming = np.repeat(np.array([[0.6, 0.0, 0.8]]), n, axis=0)
    directions, weight = monte_carlo_events._scatter_atmosphere(media, points, incoming, np.random.default_rng(2))
    turn = np.einsum("ni,ni->n", directions, incoming)
    beta_r, beta_m, beta_f = (b[0] for b in media.scattering(monte_carlo_media._norm(points[:1])))
    x, w = np.polynomial.legendre.leggauss(400)

    def mean_cos(phase):
        return 2.0 * math.pi * np.sum(w * x * phase(x))
    total = beta_r + beta_m + beta_f
    want = (beta_r * mean_cos(rayleigh_phase) + beta_m * mean_cos(lambda c: mie_phase(c, p.mie_g))
            + beta_f * mean_cos(lambda c: mie_phase(c, 0.6)))
    np.testing.assert_allclose(weight.mean(axis=0), total, rtol=0.01)
    got = (weight * turn[:, None]).mean(axis=0)
    se = (weight * turn[:, None]).std(axis=0) / math.sqrt(n)
    assert np.all(np.abs(got - want) <= 4.0 * se + 1e-3 * want), (got, want, se)
    assert np.all(beta_f > 0.05 * total)  # the fog takes part


# -- energy: a white fog over a white ground --------------------------------------------------------

@pytest.mark.parametrize("fog_g, visibility, orders, paths", [(0.5, 200.0, 40, 4096), (0.85, 500.0, 25, 8192)])
def test_white_fog_over_white_ground_sends_all_light_back_up(fog_g, visibility, orders, paths):
    """No absorption anywhere and a ground of albedo 1: the upward irradiance above the fog
    (all orders to ``orders``) is the sun's cos(zenith). Fog optical depths 1.96 and 0.78
    (fog height 100 m), so most of it comes from orders >= 2 (the sampled fog phase, the
    ground bounces)."""
    ratio, se, result = fog.energy_balance(visibility, 100.0, fog_g, 0.5, orders=orders, paths=paths)
    first = (result.atmosphere[0] + result.ground[0]) / 0.5
    assert np.all(first < 0.25)
    assert np.all(se < 0.03)
    # The orders beyond ``orders`` carry under 1%.
    assert np.all(np.abs(ratio - 1.0) <= 4.0 * se + 0.01), (ratio, se)


# -- geometries and the cloud tracer ------------------------------------------------------------------

def test_fog_geometries():
    geometries = fog.fog_geometries(50.0)
    assert len(geometries) >= 12
    rows = np.array(list(geometries.values()))
    h, mu_v, mu_s, nu = rows.T
    sin_v, sin_s = np.sqrt(1 - mu_v ** 2), np.sqrt(1 - mu_s ** 2)
    assert np.all((nu >= mu_v * mu_s - sin_v * sin_s - 1e-12) & (nu <= mu_v * mu_s + sin_v * sin_s + 1e-12))
    assert {2.0, 50.0, 125.0, 500.0} <= set(h.tolist())
    sun_elevation = np.degrees(np.arcsin(mu_s))
    assert np.allclose(sorted(set(np.round(sun_elevation, 6))), [5.0, 40.0])
    assert np.any(nu > 0.9) and np.any(nu < -0.5)  # toward and away from the sun
    assert fog.fog_geometries(100.0)["above 2.5H, down 10, sun 5 away"][0] == 250.0


def test_cloud_tracer_refuses_fog():
    p = fog.fog_params(1000.0, 50.0)
    with pytest.raises(ValueError, match="fog"):
        cloud_monte_carlo.radiance(p, None, 2.0, (0.0, 0.0, 1.0), [(0.0, 0.6, 0.8)], paths=4)
