"""The default bake's multiple scattering against the Monte Carlo path tracer, spectrally.

``lut_gen.verify.monte_carlo.radiance_by_order`` shares no code with the baker (only the media
definitions). The default params are spectral, so the path tracer runs per wavelength, on
SPECTRAL_NODES_NM three at a time (``spectrum.triple_params``), and its radiance is converted
to linear Rec.709 with ``spectrum.rgb_weights`` of those wavelengths, as the bake converts its
own nodes (12 nodes convert within ~0.3 % median of a 5 nm reference).

Compared on GEOMETRIES (viewer at 2 m, 1 km and 8 km; zenith, horizon, sunward and downward
views; sun from 60 deg to -4 deg elevation):

* totals: table "multiple" (orders 1-4 and the geometric tail of the rest,
  scattering_orders.geometric_tail) vs the path tracer's atmosphere orders 1-ORDERS (12: order
  12 adds under 0.2% anywhere in the draft table);
* higher orders: table "higher" (orders 2-4 and the tail, ground-reflected light scattered on
  included) vs atmosphere orders 2-ORDERS (both count a ground reflection as an event);
* ground (views that hit it): ``Luts.ground_radiance`` (T x albedo / pi x (direct sun +
  ambient skylight), the ambient being the "multiple" sky's irradiance at 20 m, i.e. ground
  orders 2-5) vs the path tracer's ground orders 1-5.

Errors are relative, per channel as an RGB norm: |got - want| / |want| (the project's usual).

Standard errors: each triple of wavelengths runs with its own seed, so the triples are
independent; the three wavelengths of one triple share their paths and are correlated. The
triples are interleaved (wavelengths k, k + 4, k + 8 of the 12) so that the wavelengths of a
triple weigh in different RGB channels, and the RGB error is propagated as if all 12 were
independent, se_rgb = sqrt(W^2 @ se^2) per sum of orders (sums of orders use the path
tracer's covariances between orders). Checked against the spread of 10 independent repeats
(zenith, sun 30): the formula is within the repeats' own ~25 % uncertainty for totals and
conservative for the higher orders' red (consecutive triples instead underestimated red by
~1.5x). Next to the sun the path tracer stays well behaved (the sun is a delta direction, met
by next-event estimation only): ~0.8 % for totals and ~1.2 % for orders 2-4 at 4096 paths,
from 10 deg down to 0.2 deg off the sun. In twilight it is noisy (most collisions lie in the
Earth's shadow): PATH_FACTOR.

Run time ~1 min of path tracing (2 cores) plus the default bake; ``pytest -s`` prints every
geometry's values, errors and standard errors.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from lut_gen import AtmosphereParams
from lut_gen.model import spectrum
from lut_gen.passes import sky_view
from lut_gen.verify import reference
from lut_gen.verify.monte_carlo import radiance_by_order
from mc_compare import deviation, fmt, order_sum, relative_error, relative_se, sees_ground
from rays import ray_by_elevation as ray

pytestmark = pytest.mark.slow

PARAMS = AtmosphereParams()
SPECTRAL_NODES_NM = tuple(float(v) for v in np.linspace(400.0, 700.0, 12))
TRIPLES = 4                  # SPECTRAL_NODES_NM[k::4], k = 0..3
ORDERS = 12                  # the path tracer's orders the tables stand for (four and the tail)
GROUND_ORDERS = 13           # ground_radiance's ambient is the sky reflected: ground orders 2..13
PATHS = 4096                 # per triple (and as many again for the ground of downward views)

# Bars.
TOTAL_MEDIAN, TOTAL_MAX = 0.03, 0.10
HIGHER_MEDIAN = 0.10
GROUND_MAX = 0.05


# name: (height m, view elevation, sun elevation, azimuth from the sun), degrees.
GEOMETRIES = {
    "2 m, zenith, sun 60": ray(2, 90, 60, 0),
    "2 m, zenith, sun 30": ray(2, 90, 30, 0),
    "2 m, zenith, sun 10": ray(2, 90, 10, 0),
    "2 m, zenith, sun -4": ray(2, 90, -4, 0),
    "2 m, view 2, sun 30, azimuth 90": ray(2, 2, 30, 90),
    "2 m, view 2, sun 30, azimuth 180": ray(2, 2, 30, 180),
    "2 m, view 2, sun 10, toward sun": ray(2, 2, 10, 0),
    "2 m, view 2, sun -4, toward sun": ray(2, 2, -4, 0),
    "2 m, view 10, sun 20, toward sun": ray(2, 10, 20, 0),
    "2 m, view 17, sun 20, toward sun (3 deg off)": ray(2, 17, 20, 0),
    "2 m, view 45, sun 20, azimuth 135": ray(2, 45, 20, 135),
    "1 km, zenith, sun 30": ray(1000, 90, 30, 0),
    "1 km, view 0, sun 30, azimuth 90": ray(1000, 0, 30, 90),
    "1 km, view -30 (ground), sun 45, azimuth 60": ray(1000, -30, 45, 60),
    "1 km, view -5 (ground), sun 20, azimuth 150": ray(1000, -5, 20, 150),
    "8 km, zenith, sun 30": ray(8000, 90, 30, 0),
    "8 km, view 0, sun 30, azimuth 120": ray(8000, 0, 30, 120),
    "8 km, view -2 (sky below the horizontal), sun 30, azimuth 90": ray(8000, -2, 30, 90),
    "8 km, view -45 (ground), sun 40, azimuth 90": ray(8000, -45, 40, 90),
}
# The sunset glow (the bar: within 10%, max, from sun +5 to -6 deg, views toward the sun
# included). Measured 2026-12-04 with two sets of seeds: median 1.8%, max 5.1% (these seeds) and
# 7.8% (the view 3 deg up 30 deg from a sun on the horizon, MC standard error 1.4%); toward a
# sun 2 deg up 2.7%, where four orders alone (without the tail) measured 22% off. At sun -6
# deg the path tracer's standard error is 5-8% even at 8x the paths (the zenith 3.1%, 5 deg up
# toward the sun 6.8%): too noisy to assert at a test's cost, so -6 is not in the set.
LOW_SUN_GEOMETRIES = {
    "2 m, view 3, sun 5, toward sun": ray(2, 3, 5, 0),
    "2 m, view 10, sun 5, azimuth 180": ray(2, 10, 5, 180),
    "2 m, view 3, sun 2, toward sun": ray(2, 3, 2, 0),
    "2 m, view 3, sun 2, azimuth 15": ray(2, 3, 2, 15),
    "2 m, zenith, sun 1": ray(2, 90, 1, 0),
    "1 km, view 1, sun 1, azimuth 60": ray(1000, 1, 1, 60),
    "2 m, view 3, sun 0, azimuth 30": ray(2, 3, 0, 30),
    "2 m, view 5, sun -2, toward sun": ray(2, 5, -2, 0),
    "2 m, view 20, sun -2, azimuth 180": ray(2, 20, -2, 180),
}
LOW_SUN_MAX = 0.10
# Deep twilight, sun -6 deg: against single scattering from the spectral reference plus the
# path tracer's orders 2-12 (its orders 1-12 had 5-8% standard errors at 8x the paths; this
# sum's are 1.5-2.6% at 32x). The sky the camera sees (with its twilight correction) is compared.
TWILIGHT_GEOMETRIES = {
    "2 m, zenith, sun -6": ray(2, 90, -6, 0),
    "2 m, view 5, sun -6, toward sun": ray(2, 5, -6, 0),
}
# Twilight: most collisions on the view ray lie in the Earth's shadow, so the path tracer needs
# many more paths there (its standard errors stay ~2 % even so); toward a low sun, twice as many.
PATH_FACTOR = {"2 m, zenith, sun -4": 8, "2 m, view 2, sun -4, toward sun": 8,
               **{name: 32 for name in TWILIGHT_GEOMETRIES},
               **{name: (8 if name.endswith(("sun -2, toward sun", "sun -2, azimuth 180")) else 2)
                  for name in LOW_SUN_GEOMETRIES}}


@dataclass(frozen=True)
class SpectralMC:
    """Path-tracer radiance in linear Rec.709 per unit sun (3,), with standard errors (3,)."""

    total: np.ndarray        # atmosphere orders 1..ORDERS
    total_se: np.ndarray
    higher: np.ndarray       # atmosphere orders 2..ORDERS
    higher_se: np.ndarray
    ground: np.ndarray       # ground orders 1..GROUND_ORDERS (0 if the view misses the ground)
    ground_se: np.ndarray
    ground_4: np.ndarray     # ground orders 1..4 only (what the tables held before the tail)
    by_order: np.ndarray     # (ORDERS, 3) atmosphere orders


def spectral_monte_carlo(params, geometry, paths=PATHS, seed=0, wavelengths_nm=SPECTRAL_NODES_NM) -> SpectralMC:
    """``radiance_by_order`` per wavelength of spectral ``params`` (interleaved triples, one seed
    each), converted with ``spectrum.rgb_weights``; errors as in the module docstring."""
    lam = np.asarray(wavelengths_nm, dtype=np.float64)
    n = len(lam)
    assert n % TRIPLES == 0 and n // TRIPLES == 3
    weights = spectrum.rgb_weights(lam)
    parts = {key: np.zeros((2, n)) for key in ("total", "higher", "ground", "ground_4")}
    by_order = np.zeros((ORDERS, n))
    # The extra order only matters for the ground (sky views trace ORDERS).
    orders = GROUND_ORDERS if sees_ground(params, geometry) else ORDERS
    for k in range(TRIPLES):
        idx = np.arange(k, n, TRIPLES)
        result = radiance_by_order(spectrum.triple_params(params, lam[idx]), *geometry,
                                   orders=orders, paths=paths, seed=1000 * seed + k)
        for key, values, cov, start, stop in (
                ("total", result.atmosphere, result.atmosphere_cov, 0, ORDERS),
                ("higher", result.atmosphere, result.atmosphere_cov, 1, ORDERS),
                ("ground", result.ground, result.ground_cov, 0, GROUND_ORDERS),
                ("ground_4", result.ground, result.ground_cov, 0, 4)):
            parts[key][:, idx] = order_sum(values, cov, start, stop)
        by_order[:, idx] = result.atmosphere[:ORDERS]
    rgb = {key: (weights @ v, np.sqrt((weights ** 2) @ se ** 2)) for key, (v, se) in parts.items()}
    return SpectralMC(*rgb["total"], *rgb["higher"], *rgb["ground"], rgb["ground_4"][0], by_order @ weights.T)


@pytest.fixture(scope="module")
def comparison(default_luts):
    return compare(default_luts, GEOMETRIES, first_seed=1)


@pytest.fixture(scope="module")
def low_sun_comparison(default_luts):
    return compare(default_luts, LOW_SUN_GEOMETRIES, first_seed=100)


def compare(luts, geometries, first_seed):
    """Per geometry: the path tracer's radiance and the tables' totals, higher orders and ground,
    with their relative errors (printed)."""
    rows = {}
    for i, (name, geometry) in enumerate(geometries.items()):
        mc = spectral_monte_carlo(PARAMS, geometry, paths=PATHS * PATH_FACTOR.get(name, 1), seed=first_seed + i)
        row = {
            "mc": mc,
            "total": luts.sky_radiance(*geometry, table="multiple").astype(np.float64),
            "higher": luts.sky_radiance(*geometry, table="higher").astype(np.float64),
            "ground": luts.ground_radiance(*geometry).astype(np.float64),
        }
        h, cos_view, cos_sun, cos_sun_view = geometry
        row["camera"] = sky_view.camera_sky(luts, sky_view.compute(luts, h, cos_sun), cos_view, cos_sun_view)
        row["camera_err"] = relative_error(row["camera"], mc.total)
        row["total_err"] = relative_error(row["total"], mc.total)
        row["higher_err"] = relative_error(row["higher"], mc.higher)
        if np.any(mc.ground > 0.0):
            row["ground_err"] = relative_error(row["ground"], mc.ground)
        rows[name] = row
    _print_table(rows)
    return rows


def _print_table(rows):
    print()
    for name, row in rows.items():
        mc = row["mc"]
        print(f"{name}")
        print(f"  total   table {fmt(row['total'])}  mc {fmt(mc.total)}  "
              f"err {row['total_err']:6.2%}  se {relative_se(mc.total_se, mc.total):5.2%}  {deviation(row['total'], mc.total)}")
        print(f"  camera  sky   {fmt(row['camera'])}  (the look-up with the twilight correction)  err {row['camera_err']:6.2%}")
        print(f"  higher  table {fmt(row['higher'])}  mc {fmt(mc.higher)}  "
              f"err {row['higher_err']:6.2%}  se {relative_se(mc.higher_se, mc.higher):5.2%}  {deviation(row['higher'], mc.higher)}")
        if "ground_err" in row:
            print(f"  ground  table {fmt(row['ground'])}  mc {fmt(mc.ground)}  "
                  f"err {row['ground_err']:6.2%}  se {relative_se(mc.ground_se, mc.ground):5.2%}  "
                  f"{deviation(row['ground'], mc.ground)}  (vs mc orders 1-4: {relative_error(row['ground'], mc.ground_4):6.2%})")
    total = [r["total_err"] for r in rows.values()]
    higher = [r["higher_err"] for r in rows.values()]
    ground = [r["ground_err"] for r in rows.values() if "ground_err" in r]
    if ground:
        print(f"ground: max {np.max(ground):.2%}")
    print(f"totals: median {np.median(total):.2%} max {np.max(total):.2%}; "
          f"higher: median {np.median(higher):.2%} max {np.max(higher):.2%}")


def test_statistical_error_is_well_under_the_bars(comparison):
    total = {name: relative_se(row["mc"].total_se, row["mc"].total) for name, row in comparison.items()}
    higher = {name: relative_se(row["mc"].higher_se, row["mc"].higher) for name, row in comparison.items()}
    ground = {name: relative_se(row["mc"].ground_se, row["mc"].ground)
              for name, row in comparison.items() if "ground_err" in row}
    assert np.median(list(total.values())) <= 0.01 and max(total.values()) <= 0.03, total
    assert np.median(list(higher.values())) <= 0.015 and max(higher.values()) <= 0.04, higher
    assert max(ground.values()) <= 0.01, ground


def test_totals_match_monte_carlo(comparison):
    errors = {name: row["total_err"] for name, row in comparison.items()}
    assert np.median(list(errors.values())) <= TOTAL_MEDIAN, errors
    assert max(errors.values()) <= TOTAL_MAX, {k: v for k, v in errors.items() if v > TOTAL_MAX}


def test_higher_orders_match_monte_carlo(comparison):
    errors = {name: row["higher_err"] for name, row in comparison.items()}
    assert np.median(list(errors.values())) <= HIGHER_MEDIAN, errors


def test_ground_radiance_matches_monte_carlo(comparison):
    errors = {name: row["ground_err"] for name, row in comparison.items() if "ground_err" in row}
    assert len(errors) >= 3
    assert max(errors.values()) <= GROUND_MAX, errors


@pytest.fixture(scope="module")
def twilight_comparison(default_luts):
    rows = {}
    for i, (name, geometry) in enumerate(TWILIGHT_GEOMETRIES.items()):
        mc = spectral_monte_carlo(PARAMS, geometry, paths=PATHS * PATH_FACTOR[name], seed=300 + i)
        h, cos_view, cos_sun, cos_sun_view = geometry
        single = np.maximum(reference.spectral(reference.single_scattering, PARAMS,
                                               *[np.atleast_1d(v) for v in geometry])[0], 0.0)
        view = sky_view.compute(default_luts, h, cos_sun)
        camera = sky_view.camera_sky(default_luts, view, cos_view, cos_sun_view).astype(np.float64)
        want = single + mc.higher
        rows[name] = {"err": relative_error(camera, want), "se": relative_se(mc.higher_se, want),
                      "mc_err": relative_error(camera, mc.total), "mc_se": relative_se(mc.total_se, mc.total)}
        print(f"{name}: camera sky {fmt(camera)} reference single + mc orders 2+ {fmt(want)} err "
              f"{rows[name]['err']:.2%} se {rows[name]['se']:.2%} (against mc orders 1+: {rows[name]['mc_err']:.2%}, "
              f"se {rows[name]['mc_se']:.2%})")
    return rows


def test_deep_twilight_matches_monte_carlo(twilight_comparison):
    """Sun -6 deg (the bar: within 10%, max). Measured: 2.7% at the zenith, 3.2% 5 deg
    up toward the sun (standard errors 2.6% and 1.5%; against the tracer's own orders 1-12,
    2.4% and 2.4% with standard errors 4.0% and 2.9%)."""
    assert max(row["se"] for row in twilight_comparison.values()) <= 0.03, twilight_comparison
    errors = {name: row["err"] for name, row in twilight_comparison.items()}
    assert max(errors.values()) <= LOW_SUN_MAX, errors


def test_the_sunset_glow_matches_monte_carlo(low_sun_comparison):
    """Multiple scattering with the sun from +5 to -2 deg, toward it and away from it."""
    standard_errors = {name: relative_se(row["mc"].total_se, row["mc"].total) for name, row in low_sun_comparison.items()}
    assert max(standard_errors.values()) <= 0.03, standard_errors
    for key in ("total_err", "camera_err"):         # the tables, and the sky the camera sees
        errors = {name: row[key] for name, row in low_sun_comparison.items()}
        assert max(errors.values()) <= LOW_SUN_MAX, {k: v for k, v in errors.items() if v > LOW_SUN_MAX}
