"""The world sky model's clouds (lut_gen.clouds.sky.view + composite, what the sky shader's twin
shows, per unit sun) against the Monte Carlo path tracer of the atmosphere with the cloud layer
(lut_gen.verify.cloud_monte_carlo), for a uniform layer (coverage 1: every column full
thickness, base 1500 m, 600 m thick).

The tracer is checked first against the two references it extends: without the cloud it is
monte_carlo.radiance_by_order (all orders), without the air it is the slab tracer
(slab_monte_carlo.trace). Both sides use the same three-channel media (the default atmosphere at
680/550/440 nm, ``spectrum.triple_params``), the model through a draft bake of them.

The bar: radiance and transmittance of a uniform layer within 10% of the path tracer at
sun 60, 20 and 5 deg, from below and above. Geometries: optical thickness 20 (the default
density) and 2.5; seen from below (camera at 2 m, looking up at 60 and 20 deg) and from above
(camera at 3 km, looking down at 60 and 20 deg); the sun at 60, 20 and 5 deg elevation, in the
line of sight's azimuth ("toward") or opposite ("away"). Transmittance: the global irradiance on
the ground (the diffuse sky and cloud light over the upper hemisphere plus the direct sun), and
the direct sun where the layer lets it through. Errors are relative, RGB norms
(|model - MC| / |MC|); ``pytest -s`` prints every geometry with the tracer's standard error.

Where the model holds (measured with the seeds and path counts below, 2026-12-07; MC standard
errors 1-4%): all 54 geometries are within the bar, median error 0.032, the largest 0.088 (the
thin layer seen from above, down 20 toward a sun at 60: 0.92x). With a quarter of the paths
(standard errors 2-7%) four geometries under a sun 5 deg high read 0.102-0.111, within two of
their standard errors; more paths took them to 0.03-0.085.

What was fixed (2026-12-03; 15 of 54 were within the bar before, the worst 20x):
1. The air between the camera and the cloud was lit as clear sky; under the deck it is in the
   cloud's shadow. lut_gen/clouds/air_shade.py shades its single scattering and higher orders by
   the sun's mean transmittance through the layer and adds the clouds' own light scattered by
   it. Looking up 20 deg toward a sun at 20 deg under the thick layer: 20.7x -> 1.0x; the
   ground's global irradiance under a sun at 20 and 5 deg 1.9-2.5x -> within the bar.
2. The ground's light on the cloud base (reflected back down from below, let through up from
   above) was missing: under the thick layer away from a sun at 60 deg 0.88x -> within the bar.
3. The skylight on the layer's top was the ground's (the ambient table): at a low sun most of
   it comes from the haze under the layer. lut_gen/clouds/top_light.py takes the sky's
   irradiance at the top from the 4D table, with what the bright deck sends up and the air
   above returns: the sun-5 geometries from 16 misses to 7.
4. The air over the deck scattered the light of a ground of the atmosphere's albedo, not the
   deck's (air_shade.py from above): looking down 20 deg toward a sun at 20 deg 0.89x -> within.
5. The diffuse light (the skylight on the top, the ground's light on the base) left a column
   isotropically, with the two-stream fluxes. A thick cloud's base is limb-darkened and its
   top, under a uniform sky, limb-brightened: slab.diffuse_shares now gives that light the
   angular shape of the slab's own collimated response integrated over the sky's directions.
   Looking up 20 deg from under the thick layer at a sun 5 deg high: 1.29x -> 1.10-1.11x.
6. The sun's colour was the atmosphere's transmittance from the layer's middle; the slab's sun
   falls on its top (sky.sun_at_lit_face): the deck seen from above toward a sun 5 deg high
   0.87-0.89x -> 0.94x.
7. The slab's higher orders were a three-term cosine series in azimuth, which rang around the
   second order's forward glow: 0.87x the slab tracer toward the sun and 1.18x away from it at
   optical depth 2, the thin layer from below away from the sun 1.13-1.16x here. The table now
   holds the series of their logarithm, four terms (slab_monte_carlo.log_cosine_series): within
   1-7% of the tracer there. With 5-7 (2026-12-07) and these path counts, 44 of 54 -> 54.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import lut_gen
from lut_gen.clouds import field, shadow, shafts, sky
from lut_gen.clouds.layer import CloudLayer
from lut_gen.model import spectrum
from lut_gen.passes import aerial
from lut_gen.verify import cloud_monte_carlo as cmc
from lut_gen.verify import slab_monte_carlo
from lut_gen.verify.monte_carlo import radiance_by_order

PARAMS = spectrum.triple_params(lut_gen.AtmosphereParams(), (680.0, 550.0, 440.0))
LAYERS = {
    "tau 20": CloudLayer(coverage=1.0),                          # the default density, 20 / 600 m
    "tau 2.5": CloudLayer(coverage=1.0, density=2.5 / 600.0),
}
SUN_ELEVATIONS = (60.0, 20.0, 5.0)
AZIMUTHS = {"toward": 0.0, "away": 180.0}
# name: (camera height m, view elevation deg)
VIEWS = {"below, up 60": (2.0, 60.0), "below, up 20": (2.0, 20.0),
         "above, down 60": (3000.0, -60.0), "above, down 20": (3000.0, -20.0)}
BAR = 0.10
SIGMAS = 4.0
# Paths per walk (one walk scores all six suns of a view): more from below a thick layer, where
# few paths reach the sunlit top.
PATHS = 32768
PATHS_BELOW_THICK = 65536
# The hemisphere quadrature of the model's diffuse irradiance: Gauss-Legendre in cos(zenith).
HEMISPHERE_ZENITHS, HEMISPHERE_AZIMUTHS = 48, 96


def direction(elevation_deg, azimuth_deg=0.0):
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


SUNS = [(elevation, side) for elevation in SUN_ELEVATIONS for side in AZIMUTHS]
SUN_VECTORS = np.array([direction(elevation, AZIMUTHS[side]) for elevation, side in SUNS])


def relative_error(model, reference):
    return float(np.linalg.norm(model - reference) / np.linalg.norm(reference))


# -- the tracer against its references -----------------------------------------------------------

def test_without_the_cloud_the_tracer_is_the_atmosphere_path_tracer():
    for height, elevation, sun in ((2.0, 20.0, direction(20.0, 0.0)), (3000.0, -40.0, direction(40.0, 90.0))):
        view = direction(elevation)
        ours = cmc.radiance(PARAMS, None, height, view, sun, paths=4096, seed=3)
        theirs = radiance_by_order(PARAMS, height, view[2], sun[2], view @ sun, orders=8, paths=4096, seed=4)
        total = theirs.atmosphere.sum(0) + theirs.ground.sum(0)
        se = np.hypot(ours.se[0], np.sqrt(theirs.atmosphere_cov.sum(axis=(0, 1)) + theirs.ground_cov.sum(axis=(0, 1))))
        print(height, elevation, ours.value[0], total, se)
        assert np.all(np.abs(ours.value[0] - total) <= SIGMAS * se + 0.01 * total)


def test_without_the_air_the_tracer_is_the_slab_tracer():
    """A thin atmosphere-free shell seen near the zenith is the plane-parallel slab."""
    vacuum = lut_gen.AtmosphereParams(spectral=False, ozone=False, ground_albedo=0.0, mie_scattering=(0.0,) * 3,
                                      rayleigh_scattering=(1e-12,) * 3)
    tau = 3.0
    layer = CloudLayer(coverage=1.0, density=tau / 600.0)
    sun = direction(50.0)
    views = [(2.0, direction(70.0, 0.0)), (2.0, direction(60.0, 180.0)), (3000.0, direction(-60.0, 90.0))]
    slab = slab_monte_carlo.trace(tau, sun[2], -np.array([v for _, v in views]), photons=20000, seed=9)
    for i, (height, view) in enumerate(views):
        ours = cmc.radiance(vacuum, layer, height, view, sun, paths=4096, seed=10 + i)
        want, want_se = (slab.below[i], slab.below_se[i]) if view[2] > 0 else (slab.above[i], slab.above_se[i])
        print(height, view, ours.value[0, 1], want)
        assert abs(ours.value[0, 1] - want) <= SIGMAS * math.hypot(ours.se[0, 1], want_se)


# -- the model against the tracer ----------------------------------------------------------------

@pytest.fixture(scope="module")
def luts():
    return lut_gen.bake(PARAMS, resolution="draft")


def model_radiance(luts, layer, height, directions, sun, light_shafts=False):
    """What the world shows (sky.view + composite, scattering scale and sun strength 1), per unit
    sun; ``light_shafts``: as camera rays show it with the shafts pass on (before the pass)."""
    ranks = field.cloud_map(0, 32)             # coverage 1: every rank is a full column
    cos_sun_view = directions @ sun
    clear = luts.sky_radiance(height, directions[:, 2], sun[2], cos_sun_view)
    ground = luts.ground_radiance(height, directions[:, 2], sun[2], cos_sun_view)
    return sky.composite(clear, 1.0, 1.0, sky.view(luts, layer, ranks, height, directions, sun), ground, light_shafts)


def model_irradiance(luts, layer, height, sun):
    """The model's diffuse irradiance on the ground: its radiance x cos over the upper hemisphere."""
    x, w = np.polynomial.legendre.leggauss(HEMISPHERE_ZENITHS)
    mu, mu_weight = 0.5 * (x + 1.0), 0.5 * w
    phi = (np.arange(HEMISPHERE_AZIMUTHS) + 0.5) * 2.0 * math.pi / HEMISPHERE_AZIMUTHS
    m, p = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1.0 - m * m)
    directions = np.stack([s * np.cos(p), s * np.sin(p), m], axis=-1).reshape(-1, 3)
    weights = (mu_weight[:, None] * m * (2.0 * math.pi / HEMISPHERE_AZIMUTHS)).reshape(-1)
    return weights @ model_radiance(luts, layer, height, directions, sun)


def model_direct(luts, layer, height, sun):
    """The sun's beam on the ground: the air's transmittance (tables) times the cloud shadow's."""
    ranks = field.cloud_map(0, 32)
    at = np.zeros(1)
    return luts.transmittance_to_top(height, sun[2]) * shadow.sun_transmittance(layer, ranks, at, at, sun[2] + at)


@pytest.fixture(scope="module")
def comparison(luts):
    """name: (model (3,), MC (3,), MC standard error (3,)) for every geometry; radiance and the
    global irradiance on the ground ("transmittance")."""
    rows = {}
    seed = 100
    for layer_name, layer in LAYERS.items():
        for view_name, (height, elevation) in VIEWS.items():
            seed += 1
            view = direction(elevation)
            paths = PATHS_BELOW_THICK if (height < 1000.0 and layer_name == "tau 20") else PATHS
            mc = cmc.radiance(PARAMS, layer, height, view, SUN_VECTORS, paths=paths, seed=seed)
            for j, (sun_elevation, side) in enumerate(SUNS):
                model = model_radiance(luts, layer, height, view[None], SUN_VECTORS[j])[0]
                rows[f"{layer_name}, {view_name}, sun {sun_elevation:.0f} {side}"] = (model, mc.value[j], mc.se[j])
        seed += 1
        suns = SUN_VECTORS[::2]
        paths = PATHS_BELOW_THICK if layer_name == "tau 20" else PATHS
        diffuse = cmc.irradiance(PARAMS, layer, 2.0, suns, paths=paths, seed=seed)
        direct = cmc.direct_transmittance(PARAMS, layer, 2.0, suns)
        for j, sun in enumerate(suns):
            model = model_irradiance(luts, layer, 2.0, sun) + sun[2] * model_direct(luts, layer, 2.0, sun)
            name = f"{layer_name}, global irradiance, sun {SUN_ELEVATIONS[j]:.0f}"
            rows[name] = (model, diffuse.value[j] + sun[2] * direct[j], diffuse.se[j])
    print()
    for name, (model, mc, se) in rows.items():
        print(f"{name:42s} model {np.array2string(model, precision=4)} MC {np.array2string(mc, precision=4)} "
              f"error {relative_error(model, mc):6.3f} MC se {np.linalg.norm(se) / np.linalg.norm(mc):.3f}")
    return rows


@pytest.mark.slow
def test_the_tracer_is_precise_enough_to_judge_the_bar(comparison):
    for name, (_, mc, se) in comparison.items():
        assert np.linalg.norm(se) / np.linalg.norm(mc) < 0.05, name


@pytest.mark.slow
def test_within_the_bar(comparison):
    holds = {name: relative_error(model, mc) for name, (model, mc, _) in comparison.items()}
    over = {name: round(error, 3) for name, error in holds.items() if error > BAR}
    assert not over, over


@pytest.mark.slow
def test_the_direct_sun_through_the_layer(luts):
    """Where the layer lets the sun through (thin, sun 60 and 20): the shadow's exp(-tau / mu)
    against the tracer's chord through the curved shell, times the air's transmittance."""
    layer = LAYERS["tau 2.5"]
    for elevation in (60.0, 20.0):
        sun = direction(elevation)
        mc = cmc.direct_transmittance(PARAMS, layer, 2.0, sun)[0]
        model = model_direct(luts, layer, 2.0, sun)
        print(elevation, model, mc)
        assert relative_error(model, mc) < BAR


@pytest.mark.slow
def test_light_shafts_take_the_clouds_shadow_out_of_the_air(luts, comparison):
    """With light shafts on (the default; LUT single scattering, multiple UNOCCLUDED), camera
    rays of the world leave the air's single scattering in front of the cloud to the pass
    (sky.composite with light_shafts), which weights it by the cloud's transmittance toward the
    sun step by step (lut_gen.clouds.shafts): under a uniform layer, world + shafts against the
    tracer must come to what the world alone gives with the mean shade (air_shade.py). Measured:
    world + shafts equals the world-alone error within 0.001 on every geometry from below
    (0.01-0.09, 2026-12-07); the world's camera rays alone (before the pass) are up to 17x off
    toward a low sun, as the whole world was before air_shade."""
    ranks = field.cloud_map(0, 32)
    improved = {}
    for layer_name, layer in LAYERS.items():
        for view_name in ("below, up 60", "below, up 20"):
            height, elevation = VIEWS[view_name]
            view = direction(elevation)
            camera = np.array([0.0, 0.0, height])
            end = camera + view * shafts.march_distance(layer, camera, view[None], PARAMS.earth_radius)[0]
            for j, (sun_elevation, side) in enumerate(SUNS):
                sun = SUN_VECTORS[j]
                name = f"{layer_name}, {view_name}, sun {sun_elevation:.0f} {side}"
                _, mc, _ = comparison[name]
                world = model_radiance(luts, layer, height, view[None], sun, light_shafts=True)[0]
                lit = aerial.light_shafts(luts, camera[None], end[None], sun,
                                          lambda points: shadow.ground_transmittance(layer, ranks, points, sun), 64)[0]
                with_shafts = world + lit - aerial.segment_inscattering(luts, camera[None], end[None], sun)[0]
                improved[name] = (relative_error(world, mc), relative_error(with_shafts, mc))
                print(f"{name:42s} world {improved[name][0]:6.3f}  world + shafts {improved[name][1]:6.3f}")
    # Toward the sun, where the air's forward peak lies in the cloud's shadow, the shafts take
    # the excess out; everywhere they land where the world's mean shade does.
    toward = {name: errors for name, errors in improved.items() if "toward" in name and errors[0] > 0.3}
    assert toward and all(after < 0.5 * before for before, after in toward.values()), toward
    assert np.median([after for _, after in improved.values()]) < 0.2
    for name, (_, after) in improved.items():
        model, mc, _ = comparison[name]
        assert abs(after - relative_error(model, mc)) < 0.02, (name, after, relative_error(model, mc))
