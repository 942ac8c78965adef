"""Checks of the brute-force reference integrators against independent facts.

Independent means: closed forms (exponential columns, the Chapman function at 90 degrees,
the tent area), an optically thin limit, hard geometric facts (Earth hits, the Earth's
shadow, zero-length rays) and a slow, fully 3D uniform-step integrator written here that
shares nothing with ``lut_gen.verify.reference`` except the density and phase functions.
"""
import math

import numpy as np
import pytest

from lut_gen.verify import reference as ref, reference_rays, reference_transmittance
from lut_gen.model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase
from lut_gen.model.profiles import densities, ozone_density

# The three-channel integrators are checked on the sample's media; the per-wavelength wrapper
# at the end of this file covers spectral params.
PARAMS = AtmosphereParams(spectral=False, ozone=False, ground_albedo=0.0)
OZONE = AtmosphereParams(spectral=False, ozone=True, ground_albedo=0.0)
R = PARAMS.earth_radius
TOP = PARAMS.atmosphere_height


def horizon_cos(h):
    return -math.sqrt(1.0 - (R / (R + h)) ** 2)


def thin(params, factor=1e-9):
    """Same media, scattering scaled down until the atmosphere is optically thin."""
    return AtmosphereParams(
        spectral=False, ozone=False, ground_albedo=0.0,
        rayleigh_scattering=tuple(x * factor for x in params.rayleigh_scattering),
        mie_scattering=tuple(x * factor for x in params.mie_scattering),
        rayleigh_scale_height=params.rayleigh_scale_height,
        mie_scale_height=params.mie_scale_height,
        mie_g=params.mie_g,
    )


def exp_column(h, big_h, top=TOP):
    """Vertical column of exp(-z/H) from height h to the top."""
    return big_h * math.exp(-h / big_h) * (1.0 - math.exp(-(top - h) / big_h))


def tent_column(h):
    """Vertical column of the ozone tent (0 below 10 km and above 40 km, 1 at 25 km) above h."""
    def antiderivative(z):  # integral of the tent from 0 to z
        z = min(max(z, 10_000.0), 40_000.0)
        if z <= 25_000.0:
            return (z - 10_000.0) ** 2 / (2 * 15_000.0)
        return 15_000.0 - (40_000.0 - z) ** 2 / (2 * 15_000.0)
    return antiderivative(TOP) - antiderivative(h)


def chapman_horizontal(big_h):
    """Net density of exp(-z/H) along a horizontal ray from the ground, unbounded atmosphere:
    H * Ch(x, 90 deg) = H * x e^x K1(x), x = R/H (asymptotic series of K1, exact to ~1e-12)."""
    x = R / big_h
    series = 1 + 3 / (8 * x) - 15 / (128 * x * x) + 315 / (3072 * x**3)
    return big_h * math.sqrt(math.pi * x / 2) * series


def uniform_net_density(params, h, mu, n=200_001):
    """Brute force: uniform steps to the top sphere, plain trapezoid, atmosphere's densities."""
    r = R + h
    length = -r * mu + math.sqrt(r * r * (mu * mu - 1) + params.top_radius**2)
    s = np.linspace(0.0, length, n)
    rs = np.sqrt(r * r + s * s + 2 * r * mu * s)
    rho = densities(params, rs - R)
    return np.trapz(rho, s, axis=0)


# -- net density / transmittance -------------------------------------------------------------

@pytest.mark.parametrize("h", [0.0, 3_000.0, 17_000.0, 33_000.0, 79_000.0])
def test_zenith_net_density_is_exact_column(h):
    got = ref.net_density_to_top(PARAMS, h, 1.0)
    want = [exp_column(h, PARAMS.rayleigh_scale_height), exp_column(h, PARAMS.mie_scale_height), tent_column(h)]
    np.testing.assert_allclose(got[:2], want[:2], rtol=1e-7)
    assert abs(got[2] - want[2]) < 1e-4  # metres; the whole tent is 15 km


def test_zenith_ozone_column_is_tent_area():
    assert ref.net_density_to_top(OZONE, 0.0, 1.0)[2] == pytest.approx(15_000.0, rel=1e-10)


def test_horizontal_ray_matches_chapman():
    got = ref.net_density_to_top(PARAMS, 0.0, 0.0)
    ray_r = chapman_horizontal(PARAMS.rayleigh_scale_height)
    ray_m = chapman_horizontal(PARAMS.mie_scale_height)
    # Leading term sqrt(pi R H / 2), within 1 %.
    assert got[0] == pytest.approx(math.sqrt(math.pi * R * PARAMS.rayleigh_scale_height / 2), rel=1e-2)
    # Full Chapman function: only the part beyond the 80 km top (~1e-5 for Rayleigh) is missing.
    assert got[0] == pytest.approx(ray_r, rel=3e-5)
    assert got[0] < ray_r
    assert got[1] == pytest.approx(ray_m, rel=1e-8)


@pytest.mark.parametrize(
    "h, mu",
    [
        (0.0, 0.1),
        (1_500.0, 0.02),
        (20_000.0, -0.07),  # passes a tangent point at ~4.4 km
        (79_000.0, horizon_cos(79_000.0) + 1e-3),  # grazes down to ~7 km, ~2000 km long
        (5_000.0, horizon_cos(5_000.0) + 1e-6),  # grazes the ground
    ],
)
def test_net_density_matches_uniform_brute_force(h, mu):
    got = ref.net_density_to_top(OZONE, h, mu)
    want = uniform_net_density(OZONE, h, mu)
    np.testing.assert_allclose(got[:2], want[:2], rtol=2e-5)
    assert abs(got[2] - want[2]) < 2e-5 * want[2] + 1e-3


def _ray_grid():
    hs = np.array([0.0, 500.0, 2_000.0, 10_000.0, 30_000.0, 79_900.0])
    rows = []
    for h in hs:
        ch = horizon_cos(h)
        for mu in (1.0, 0.5, 0.1, 0.01, 0.0, ch + 1e-2, ch + 1e-4, ch + 1e-7):
            if mu >= ch:
                rows.append((h, mu))
    return np.array(rows).T


def test_net_density_converges_when_steps_double():
    h, mu = _ray_grid()
    a = ref.net_density_to_top(OZONE, h, mu, steps=512)
    b = ref.net_density_to_top(OZONE, h, mu, steps=1024)
    rel = np.abs(a[:, :2] - b[:, :2]) / b[:, :2]
    assert rel.max() < 1e-6
    assert np.abs(a[:, 2] - b[:, 2]).max() < 1e-3
    # Even 64 steps are within 1e-4 of 1024.
    c = ref.net_density_to_top(OZONE, h, mu, steps=64)
    assert (np.abs(c[:, :2] - b[:, :2]) / b[:, :2]).max() < 1e-4


def test_rays_into_the_earth():
    h = 10_000.0
    ch = horizon_cos(h)
    hit = ref.net_density_to_top(PARAMS, [h, h, 0.0, 0.0], [ch - 1e-6, -1.0, -1e-9, -0.5])
    assert np.all(hit == ref.HIT_EARTH_NET_DENSITY)
    miss = ref.net_density_to_top(PARAMS, [h, 0.0], [ch + 1e-6, 0.0])
    assert np.all(miss < 1e7) and np.all(miss[:, 0] > 1e5)
    t = ref.transmittance_to_top(OZONE, [h, h], [ch - 1e-6, ch + 1e-6])
    assert np.all(t[0] == 0.0)
    assert np.all(t[1] > 0.0)


def test_transmittance_is_exp_of_optical_depth():
    h, mu = _ray_grid()
    t = ref.transmittance_to_top(OZONE, h, mu)
    net = ref.net_density_to_top(OZONE, h, mu)
    np.testing.assert_allclose(t, np.exp(-net @ OZONE.extinction_matrix()), rtol=1e-12)
    assert np.all((t > 0) & (t <= 1))
    np.testing.assert_array_equal(ref.transmittance_to_top(OZONE, TOP, 0.3), [1.0, 1.0, 1.0])
    # Blue is extinguished more than red by Rayleigh; less light along longer paths.
    zen = ref.transmittance_to_top(PARAMS, 0.0, 1.0)
    assert zen[2] < zen[1] < zen[0] < 1.0
    mus = np.linspace(1.0, 0.0, 21)
    tr = ref.transmittance_to_top(PARAMS, 0.0, mus)
    assert np.all(np.diff(tr, axis=0) < 0)


def test_shapes_and_clamping():
    assert ref.net_density_to_top(PARAMS, 1000.0, 0.3).shape == (4,)  # Rayleigh, Mie, ozone, fog
    assert ref.transmittance_to_top(PARAMS, np.zeros((4, 1)), np.linspace(0, 1, 5)).shape == (4, 5, 3)
    net = ref.net_density_to_top
    np.testing.assert_array_equal(net(PARAMS, -50.0, 0.4), net(PARAMS, 0.0, 0.4))
    np.testing.assert_array_equal(net(PARAMS, TOP + 9.0, -0.4), net(PARAMS, TOP, -0.4))
    assert ref.single_scattering(PARAMS, 1000.0, 0.3, 0.2, 0.1, steps=32, sun_steps=16).shape == (3,)
    out = ref.single_scattering(PARAMS, np.zeros((2, 1)), [0.1, 0.5, 1.0], 0.4, 0.0, steps=32, sun_steps=16)
    assert out.shape == (2, 3, 3)


def test_inline_ozone_tent_matches_atmosphere_profile():
    rng = np.random.default_rng(5)
    h = rng.uniform(0, TOP, 200)
    mu = rng.uniform(-1, 1, 200)
    r = R + h
    got = reference_transmittance._ozone_line(OZONE, r, mu, 16)
    for i in range(0, 200, 40):  # brute force through the atmosphere module's profile
        length = reference_rays._distance_to_top(OZONE, r[i], mu[i])
        s = np.linspace(0, length, 400_001)
        z = np.sqrt(r[i] ** 2 + s * s + 2 * r[i] * mu[i] * s) - R
        assert got[i] == pytest.approx(np.trapz(ozone_density(OZONE, z), s), rel=1e-6, abs=1e-3)


def test_panel_nodes_generalise_ray_nodes():
    rng = np.random.default_rng(9)
    r = R + rng.uniform(0, TOP, 50)
    mu = rng.uniform(-0.3, 1.0, 50)
    length = reference_rays._distance_to_top(PARAMS, r, mu)
    s1, j1, du1 = reference_rays._ray_nodes(r, mu, length, 40)
    low = np.clip(-r * mu, 0, length)
    s2, j2, du2 = reference_rays._panel_nodes(np.stack([np.zeros_like(r), low, length], axis=-1), 40)
    np.testing.assert_allclose(s1, s2, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(j1, j2, rtol=1e-12, atol=1e-6)
    assert np.all(np.diff(s1, axis=-1) >= 0)
    np.testing.assert_allclose(s1[:, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(s1[:, -1], length, rtol=1e-12)
    # The Jacobian integrates to the ray length.
    np.testing.assert_allclose((j1 * reference_rays._trapezoid_weights(40, du1)).sum(-1), length, rtol=1e-4)


# -- single scattering --------------------------------------------------------------------------

def test_single_scattering_thin_zenith_is_analytic():
    p = thin(PARAMS)
    got = ref.single_scattering(p, 0.0, 1.0, 1.0, 1.0)
    want = p.rayleigh * rayleigh_phase(1.0) * exp_column(0.0, p.rayleigh_scale_height) + p.mie * mie_phase(
        1.0, p.mie_g
    ) * exp_column(0.0, p.mie_scale_height)
    np.testing.assert_allclose(got, want, rtol=1e-6)
    # Looking straight down from the top with the sun overhead: the same column, backscatter.
    down = ref.single_scattering(p, TOP, -1.0, 1.0, -1.0)
    want_down = p.rayleigh * rayleigh_phase(-1.0) * exp_column(0.0, p.rayleigh_scale_height) + p.mie * mie_phase(
        -1.0, p.mie_g
    ) * exp_column(0.0, p.mie_scale_height)
    np.testing.assert_allclose(down, want_down, rtol=1e-6)


def test_single_scattering_thin_matches_net_density_along_view():
    """Thin atmosphere, sun overhead at the observer (never blocked along these rays):
    L = beta_R p_R(nu) N_R + beta_M p_M(nu) N_M with N the view ray's net densities."""
    p = thin(PARAMS)
    h = np.array([0.0, 0.0, 2_000.0, 20_000.0, 60_000.0, 80_000.0])
    mu = np.array([0.0, 0.3, horizon_cos(2_000.0) + 1e-4, -0.07, horizon_cos(60_000.0) + 1e-3, -0.1])
    nu = mu  # sun at the observer's zenith
    got = ref.single_scattering(p, h, mu, 1.0, nu)
    net = ref.net_density_to_top(p, h, mu)
    want = (
        p.rayleigh * rayleigh_phase(nu)[:, None] * net[:, :1]
        + p.mie * mie_phase(nu, p.mie_g)[:, None] * net[:, 1:2]
    )
    np.testing.assert_allclose(got, want, rtol=1e-5)


def test_single_scattering_depends_on_sun_only_through_phase_when_thin():
    # Same view ray and scattering angle, three sun elevations: equal in a thin atmosphere,
    # different in the real one (the sun transmittance enters).
    mu_v, nu = 0.5, 0.5
    mu_s = np.array([1.0, 0.5, 0.05])
    thin_l = ref.single_scattering(thin(PARAMS), 0.0, mu_v, mu_s, nu)
    np.testing.assert_allclose(thin_l, thin_l[[0, 0, 0]], rtol=1e-6)
    real = ref.single_scattering(PARAMS, 0.0, mu_v, mu_s, nu)
    assert np.all(real[2] < 0.9 * real[0])


def test_single_scattering_zero_when_sun_blocked_everywhere():
    # Looking straight down from 20 km, sun far below the horizon at every point of the ray.
    blocked = ref.single_scattering(PARAMS, 20_000.0, -1.0, -0.9, 0.9)
    np.testing.assert_array_equal(blocked, [0.0, 0.0, 0.0])
    # Looking up from the ground with the sun 30 degrees below the horizon.
    np.testing.assert_array_equal(ref.single_scattering(PARAMS, 0.0, 1.0, -0.5, -0.5), [0.0, 0.0, 0.0])
    # The same rays with the sun above the horizon do see light.
    assert np.all(ref.single_scattering(PARAMS, 20_000.0, -1.0, 0.9, -0.9) > 0)
    assert np.all(ref.single_scattering(PARAMS, 0.0, 1.0, 0.5, 0.5) > 0)


def test_single_scattering_zero_length_rays():
    out = ref.single_scattering(PARAMS, [0.0, TOP, 0.0], [-0.3, 0.5, -1.0], 0.7, 0.0)
    np.testing.assert_array_equal(out, np.zeros((3, 3)))


def test_cos_sun_view_is_clamped_to_the_geometry():
    # View at the zenith: the scattering angle is the sun's zenith angle whatever is passed.
    base = ref.single_scattering(PARAMS, 1_000.0, 1.0, 0.3, 0.3)
    for nu in (-1.0, 0.0, 0.9, 1.0):
        np.testing.assert_allclose(ref.single_scattering(PARAMS, 1_000.0, 1.0, 0.3, nu), base, rtol=1e-12)
    # Otherwise the range is [ca cs - sa ss, ca cs + sa ss].
    ca, cs = 0.2, 0.6
    hi = ca * cs + math.sqrt((1 - ca * ca) * (1 - cs * cs))
    np.testing.assert_allclose(
        ref.single_scattering(PARAMS, 0.0, ca, cs, 1.0), ref.single_scattering(PARAMS, 0.0, ca, cs, hi), rtol=1e-12
    )


def test_single_scattering_forward_peak_and_colour():
    ca, cs = 0.1, 0.1
    sa = math.sqrt(1 - ca * ca)
    toward = ref.single_scattering(PARAMS, 0.0, ca, cs, ca * cs + sa * sa)  # same azimuth as the sun
    away = ref.single_scattering(PARAMS, 0.0, ca, cs, ca * cs - sa * sa)
    assert np.all(toward > 2 * away)  # Mie forward peak
    zenith_sky = ref.single_scattering(PARAMS, 0.0, 1.0, 0.8, 0.8)
    assert zenith_sky[2] > zenith_sky[1] > zenith_sky[0]  # blue sky


HARD_RAYS = np.array(
    [
        # h, cos view zenith, cos sun zenith, cos sun-view
        (0.0, 0.0, 0.05, 0.0),
        (0.0, 0.02, -0.02, 0.995),  # crosses the Earth's shadow
        (20_000.0, -1.0, 0.5, -0.5),
        (20_000.0, horizon_cos(20_000.0) - 1e-4, 0.1, 0.2),  # just hits the ground, ~1000 km
        (20_000.0, horizon_cos(20_000.0) + 1e-4, 0.1, 0.2),  # just misses it
        (80_000.0, horizon_cos(80_000.0) + 1e-3, 0.0, 0.99),  # grazing from the top, ~2000 km
        (5_000.0, -0.03, -0.06, 0.99),  # observer in the shadow, the far part of the ray lit
        (1_000.0, -0.3, 0.2, 0.1),
        (0.0, 0.3, 0.8, 0.4),
    ]
).T


def test_single_scattering_converges_when_steps_double():
    a = ref.single_scattering(OZONE, *HARD_RAYS)
    b = ref.single_scattering(OZONE, *HARD_RAYS, steps=512, sun_steps=128)
    assert np.all(b > 0)
    assert (np.abs(a - b) / b).max() < 1e-4


# -- an independent, slow, fully 3D brute force ---------------------------------------------------

def brute_single_scattering(params, h, mu_v, mu_s, nu, n_view=3000, n_sun=3000):
    """Uniform steps, 3D vectors, plain trapezoids; sun transmittance integrated per sample."""
    up = np.array([0.0, 0.0, 1.0])
    origin = (R + h) * up
    view = np.array([math.sqrt(1 - mu_v**2), 0.0, mu_v])
    ss = math.sqrt(max(1 - mu_s**2, 0.0))
    sv = math.sqrt(1 - mu_v**2)
    cos_az = (nu - mu_v * mu_s) / (sv * ss)
    sun = np.array([ss * cos_az, ss * math.sqrt(max(1 - cos_az**2, 0.0)), mu_s])
    assert abs(sun @ view - nu) < 1e-12

    def exit_distance(p, d, radius, first):
        b = p @ d
        disc = b * b - (p @ p - radius * radius)
        if disc < 0:
            return None
        root = math.sqrt(disc)
        return -b - root if first else -b + root

    ground = exit_distance(origin, view, R, True)
    if ground is not None and ground > 0:
        length = ground
    else:
        length = exit_distance(origin, view, params.top_radius, False)
    s = np.linspace(0.0, length, n_view)
    pts = origin + s[:, None] * view
    z = np.linalg.norm(pts, axis=1) - R
    rho = densities(params, z)
    ext = params.extinction_matrix()
    depth = np.concatenate([[np.zeros(rho.shape[1])], np.cumsum(0.5 * (rho[1:] + rho[:-1]) * np.diff(s)[:, None], axis=0)])
    t_view = np.exp(-depth @ ext)
    t_sun = np.zeros((n_view, 3))
    for i in range(0, n_view, 500):  # sun rays in blocks
        p = pts[i : i + 500]
        b = p @ sun
        blocked = (b < 0) & (np.einsum("ij,ij->i", p, p) - b * b < R * R)
        top = -b + np.sqrt(b * b - (np.einsum("ij,ij->i", p, p) - params.top_radius**2))
        u = np.linspace(0.0, 1.0, n_sun)
        q = p[:, None, :] + (top[:, None, None] * u[None, :, None]) * sun
        rq = densities(params, np.linalg.norm(q, axis=-1) - R)
        net = np.trapz(rq, dx=1.0 / (n_sun - 1), axis=1) * top[:, None]
        t_sun[i : i + 500] = np.where(blocked[:, None], 0.0, np.exp(-net @ ext))
    f = (
        params.rayleigh * rayleigh_phase(nu) * rho[:, :1] + params.mie * mie_phase(nu, params.mie_g) * rho[:, 1:2]
        + params.fog * mie_phase(nu, params.fog_g) * rho[:, 3:4]  # 0 without fog
    ) * t_view * t_sun
    return np.trapz(f, s, axis=0)


@pytest.mark.parametrize(
    "h, mu_v, mu_s, nu",
    [
        (0.0, 0.3, 0.2, 0.5),
        (20_000.0, -0.5, 0.5, 0.1),  # down to the ground
        (0.0, 0.05, 0.02, 0.9),  # sunset, towards the sun
        (10_000.0, 0.1, -0.05, -0.3),  # sun below the horizon, away from it
    ],
)
def test_single_scattering_matches_3d_brute_force(h, mu_v, mu_s, nu):
    got = ref.single_scattering(OZONE, h, mu_v, mu_s, nu)
    want = brute_single_scattering(OZONE, h, mu_v, mu_s, nu)
    assert np.all(want > 0)
    np.testing.assert_allclose(got, want, rtol=1e-4)


def test_spectral_reference_is_the_three_channel_one_per_wavelength():
    """ref.spectral: each wavelength is the three-channel integrator on that wavelength's
    media, and the sum is converted with the white-balanced weights (a flat spectrum -> 1, 1, 1)."""
    from lut_gen.model import spectrum
    spectral = AtmosphereParams()
    lam = (450.0, 550.0, 650.0)
    args = (1000.0, 0.3, 0.7, 0.5)
    per_wavelength = ref.per_wavelength(ref.single_scattering, spectral, *args, wavelengths_nm=lam)
    three = ref.single_scattering(spectrum.triple_params(spectral, lam), *args)
    np.testing.assert_allclose(per_wavelength, three, rtol=1e-12)
    flat = ref.spectral(lambda params, x: np.ones(np.shape(x) + (3,)), spectral, np.zeros(2))
    np.testing.assert_allclose(flat, 1.0, rtol=1e-9)
    sample = ref.spectral(ref.single_scattering, PARAMS, *args)
    np.testing.assert_array_equal(sample, ref.single_scattering(PARAMS, *args))
