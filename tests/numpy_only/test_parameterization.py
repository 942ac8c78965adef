"""Eqs. (4)-(7) of Yusov 2013 and Listing 2: texel mappings and their inverses."""
import numpy as np
import pytest

from lut_gen import AtmosphereParams
from lut_gen.tables import parameterization as par

P = AtmosphereParams()


def test_height_mapping_is_eq4():
    n = 32
    assert par.height_to_x(20_000, n, 80_000) == pytest.approx(0.5 * (n - 1))
    x = np.linspace(0, n - 1, 17)
    np.testing.assert_allclose(par.height_to_x(par.x_to_height(x, n, 80_000), n, 80_000), x, atol=1e-9)


def test_view_zenith_halves_follow_listing2():
    n, h = 128, 20_000.0
    c_h = float(par.cos_horizon(h, P.earth_radius))
    x_up, above = par.view_zenith_to_x(1.0, h, n, P.earth_radius)
    assert above and x_up == pytest.approx(n - 1)
    x_hor, above = par.view_zenith_to_x(c_h, h, n, P.earth_radius, above_horizon=True)
    assert x_hor == pytest.approx(n / 2)
    assert not par.view_zenith_to_x(c_h, h, n, P.earth_radius)[1]     # the horizon ray itself is "below"
    x_down, above = par.view_zenith_to_x(-1.0, h, n, P.earth_radius)
    assert not above and x_down == pytest.approx(n / 2 - 1)
    # Power 0.2 of Yusov 2013 eq. (5): halfway up the upper half is (0.5)^5 of the way in cosine.
    c_mid = c_h + 0.5 ** 5 * (1 - c_h)
    assert par.view_zenith_to_x(c_mid, h, n, P.earth_radius)[0] == pytest.approx(n / 2 + 0.5 * (n / 2 - 1))


@pytest.mark.parametrize("h", [0.0, 150.0, 20_000.0, 79_000.0])
def test_view_zenith_round_trip(h):
    n = 128
    x = np.arange(n, dtype=float)
    c, above = par.x_to_view_zenith(x, h, n, P.earth_radius)
    back, above2 = par.view_zenith_to_x(c, h, n, P.earth_radius, above_horizon=above)
    np.testing.assert_allclose(back, x, atol=1e-6)
    np.testing.assert_array_equal(above, x >= n // 2)


def test_forced_horizon_flag_clamps_to_the_seam():
    h, n = 5000.0, 128
    c_h = float(par.cos_horizon(h, P.earth_radius))
    x, _ = par.view_zenith_to_x(c_h - 0.01, h, n, P.earth_radius, above_horizon=True)
    assert x == pytest.approx(n / 2)
    x, _ = par.view_zenith_to_x(c_h + 0.01, h, n, P.earth_radius, above_horizon=False)
    assert x == pytest.approx(0.0)


def test_sun_zenith_mapping_is_bruneton_eq6():
    n = 64
    assert par.sun_zenith_to_x(1.0, n) == pytest.approx(n - 1, abs=1e-3)
    assert par.sun_zenith_to_x(-0.1975, n) == pytest.approx(0.0, abs=0.05)
    assert par.sun_zenith_to_x(-0.9, n) == par.sun_zenith_to_x(-0.1975, n)   # clamped below -0.1975
    # Node 0 sits at c = -0.19774, a hair below the clamp of Yusov 2013 eq. (6); all others
    # round-trip.
    x = np.arange(1, n, dtype=float)
    np.testing.assert_allclose(par.sun_zenith_to_x(par.x_to_sun_zenith(x, n), n), x, atol=1e-6)


def test_sun_view_mapping_is_uniform_in_angle():
    """Yusov 2013 eq. (7) with power 1: with the Mie phase applied at look-up (no forward peak left
    in the tables) nodes evenly spaced in angle (12 deg at 16 nodes) beat the paper's power 1.5,
    whose 30 deg gap around 90 deg put kinks into the twilight sky."""
    n = 16
    assert par.sun_view_to_x(1.0, n) == pytest.approx(0.0)
    assert par.sun_view_to_x(0.0, n) == pytest.approx(0.5 * (n - 1))
    assert par.sun_view_to_x(-1.0, n) == pytest.approx(n - 1)
    assert par.sun_view_to_x(np.cos(np.radians(45.0)), n) == pytest.approx(0.25 * (n - 1))
    x = np.arange(n, dtype=float)
    np.testing.assert_allclose(par.sun_view_to_x(par.x_to_sun_view(x, n), n), x, atol=1e-6)
    gaps = np.diff(np.degrees(np.arccos(par.x_to_sun_view(x, n))))
    np.testing.assert_allclose(gaps, 12.0, rtol=1e-9)


def test_clamp_sun_view_keeps_geometry_consistent():
    ca, cs = 0.9, 0.2
    lo, hi = ca * cs - np.sqrt((1 - ca**2) * (1 - cs**2)), ca * cs + np.sqrt((1 - ca**2) * (1 - cs**2))
    assert par.clamp_sun_view(ca, cs, 1.0) == pytest.approx(hi)
    assert par.clamp_sun_view(ca, cs, -1.0) == pytest.approx(lo)
    assert par.clamp_sun_view(ca, cs, 0.3) == pytest.approx(0.3)
