"""The cloud layer's optics and field against references: the slab's radiance against the Monte
Carlo path tracer (a seed the table was not built with), and the map's coverage."""
import numpy as np
import pytest

from lut_gen.clouds import field, slab
from lut_gen.clouds.layer import CloudLayer, middle_hit
from lut_gen.verify import slab_monte_carlo as mc


def lines_of_sight(cos_sun):
    """Lines of sight (eye to cloud) looking up at zenith angles 0-70 deg, azimuths 0-180 from
    the sun, and the sun's direction (toward +x)."""
    views = []
    for zenith in (0.0, 30.0, 50.0, 70.0):
        for azimuth in (0.0, 60.0, 120.0, 180.0):
            z, a = np.radians(zenith), np.radians(azimuth)
            views.append([np.sin(z) * np.cos(a), np.sin(z) * np.sin(a), np.cos(z)])
    return np.array(views), np.array([np.sqrt(1.0 - cos_sun ** 2), 0.0, cos_sun])


@pytest.mark.parametrize("sun_elevation", [60.0, 20.0, 5.0])
@pytest.mark.parametrize("tau", [20.0, 3.0])
def test_slab_radiance_matches_the_path_tracer(tau, sun_elevation):
    cos_sun = np.sin(np.radians(sun_elevation))
    up, sun = lines_of_sight(cos_sun)
    down = up * np.array([1.0, 1.0, -1.0])
    ref = mc.trace(tau, cos_sun, np.concatenate([-up, -down]), photons=20000, seed=2024)
    n = len(up)
    for looks, reference, se, reflected in ((up, ref.below[:n], ref.below_se[:n], False),
                                            (down, ref.above[n:], ref.above_se[n:], True)):
        cos_view = np.abs(looks[:, 2])
        model = slab.radiance(tau, cos_sun, cos_view, looks @ sun,
                              slab.cos_azimuth(looks[:, 2], cos_sun, looks @ sun), reflected)
        assert np.all(se < 0.1 * reference)
        error = np.abs(model / reference - 1.0)
        # Medians measured 0.7-6.2% (2026-12-07, the log series; the bar was 10% before it).
        assert np.median(error) < 0.075, (reflected, np.round(model / reference, 2))
        # What the eye takes in over these views (cosine-weighted, as flux): within 10%.
        weights = cos_view
        assert abs((model * weights).sum() / (reference * weights).sum() - 1.0) < 0.1


def test_a_thick_slab_transmits_what_two_stream_says():
    for cos_sun in (0.9, 0.4):
        ref = mc.trace(20.0, cos_sun, np.array([[0.0, 0.0, -1.0]]), photons=20000, seed=5)
        _, diffuse = slab.two_stream(20.0, cos_sun)
        assert abs((diffuse + np.exp(-20.0 / cos_sun)) / ref.transmitted_flux - 1.0) < 0.1


def test_cloud_map_is_seeded_tileable_and_covers_what_coverage_says():
    a, b, c = field.cloud_map(3, 128), field.cloud_map(3, 128), field.cloud_map(4, 128)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).mean() > 0.1
    # Tileable: the step across the wrap is like any other step.
    inner = np.abs(np.diff(a, axis=1)).mean()
    assert np.abs(a[:, 0] - a[:, -1]).mean() < 2.0 * inner
    for coverage in (0.2, 0.5, 0.8):
        covered = (field.thickness_fraction(a, coverage) > 0.5).mean()
        assert abs(covered - coverage) <= field.SOFTNESS / 2 + 0.01
    assert field.thickness_fraction(a, 0.0).max() == 0.0
    assert field.thickness_fraction(a, 1.0).min() == 1.0


def test_the_layer_sinks_toward_the_horizon_and_clamps_bad_input():
    layer = CloudLayer()
    up = np.array([[0.0, 0.0, 1.0], [0.0, np.cos(0.1), np.sin(0.1)], [0.0, 1.0, 0.0]])
    distance, hit = middle_hit(layer, 2.0, up, 6360e3)
    assert hit.all()
    np.testing.assert_allclose(distance[0], layer.middle - 2.0, rtol=1e-9)
    # Horizontal: the curved middle sphere is ~150 km away, not infinitely far.
    assert 1.3e5 < distance[2] < 1.7e5
    bad = CloudLayer(coverage=float("nan"), base=-50.0, thickness=0.0, density=float("inf"),
                     scale=float("nan"), offset=(float("nan"), 3.0)).clamped()
    assert (bad.coverage, bad.base, bad.thickness, bad.density, bad.scale) == (0.4, 0.0, 10.0, 1.0, 2000.0)
    assert bad.offset == (0.0, 3.0)
    high = CloudLayer(base=19000.0, thickness=4000.0).clamped()
    assert high.base == 15000.0 and high.base + high.thickness <= 20000.0


def diffuse_by_the_tracer(tau, cos_views, zeniths=8, azimuths=8, seed=40):
    """(below, above) radiance toward zenith cosines ``cos_views`` of the slab under a sky of
    unit radiance on its top, by the path tracer: its collimated response integrated over the
    sky (Gauss-Legendre in the sun's zenith cosine, the view's azimuths averaged for the sun's)."""
    x, w = np.polynomial.legendre.leggauss(zeniths)
    mu_s, w = 0.5 * (x + 1.0), 0.5 * w
    a = (np.arange(azimuths) + 0.5) * 2.0 * np.pi / azimuths
    s = np.sqrt(1.0 - cos_views ** 2)[:, None]
    horizontal = np.stack([s * np.cos(a), s * np.sin(a)], axis=-1)                # (V, A, 2)
    below = np.concatenate([horizontal, np.broadcast_to(-cos_views[:, None, None], horizontal.shape[:2] + (1,))], -1)
    views = np.concatenate([below, below * np.array([1.0, 1.0, -1.0])]).reshape(-1, 3)
    n = len(cos_views) * azimuths
    out_below, out_above = 0.0, 0.0
    for k, (mu, weight) in enumerate(zip(mu_s, w)):
        ref = mc.trace(tau, mu, views, photons=8000, seed=seed + k)
        out_below = out_below + 2.0 * np.pi * weight * ref.below[:n].reshape(len(cos_views), azimuths).mean(-1)
        out_above = out_above + 2.0 * np.pi * weight * ref.above[n:].reshape(len(cos_views), azimuths).mean(-1)
    return out_below, out_above


@pytest.mark.parametrize("tau", [20.0, 3.0])
def test_diffuse_light_leaves_a_slab_with_the_tracers_angular_shape(tau):
    """The skylight on a cloud's top and the ground's light on its base (slab.diffuse_shares)
    against the path tracer lit by a uniform sky. Measured (2026-12-07): within 0.3-1.7% at zenith
    cosines 0.34-0.94, optical depths 20 and 3; the isotropic two-stream radiance was 1.39x the
    tracer's through the thick slab at 0.34 (a view 20 deg above the horizon) and 0.83x at 0.94,
    0.72-1.41x over both slabs and sides. Energy: 1.0006 (20) and 0.992 (3)."""
    cos_views = np.array([0.34, 0.64, 0.94])
    below, above = diffuse_by_the_tracer(tau, cos_views)
    back, through = slab.diffuse_shares(np.full(3, tau), cos_views)
    # Per unit sky radiance: the shares are radiance per unit irradiance (pi) times pi.
    assert np.all(np.abs(through / below - 1.0) < 0.05), through / below
    assert np.all(np.abs(back / above - 1.0) < 0.05), back / above
    iso_back, iso_through = slab.diffuse_two_stream(tau)
    if tau > 10.0:
        # The base is limb-darkened: the isotropic fluxes are off at both ends, the shares not.
        assert iso_through / below[0] > 1.25 and iso_through / below[2] < 0.92
    # Energy: a conservative slab reflects or lets through (scattered or straight) all the sky's
    # light, though nothing in the collimated model forces it.
    mu, w = np.polynomial.legendre.leggauss(32)
    mu, w = 0.5 * (mu + 1.0), 0.5 * w
    back_all, through_all = slab.diffuse_shares(np.full(32, tau), mu)
    straight = 2.0 * np.sum(np.exp(-tau / mu) * mu * w)
    assert abs(2.0 * np.sum((back_all + through_all) * mu * w) + straight - 1.0) < 0.03
