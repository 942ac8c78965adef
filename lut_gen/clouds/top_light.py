"""The skylight on the cloud layer's top: the sky's irradiance at the top's height, from the 4D
table (Luts.sky_irradiance), not the ambient table's at the ground.

At a low sun most of the ground's diffuse light is scattered by the haze of the lowest
kilometres (the aerosol's scale height is 1.2 km), which lies under the layer: the ground's
skylight taken for the top's put a deck's underside at sun 5 deg 1.4x over the Monte Carlo
tracer (tests/numpy_only/test_cloud_monte_carlo.py). Above the haze the top sees less of it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..tables.lookup import Luts
from . import field, slab
from .layer import CloudLayer

SUN_NODES = 17      # a frame's rays see the sun at zenith cosines a degree or two apart


def skylight(luts: Luts, layer: CloudLayer, cos_sun) -> np.ndarray:
    """(..., 3) the sky's irradiance on a horizontal plane at the layer's top, per unit sun, for
    the sun's zenith cosines ``cos_sun`` (...) there: exact on a few nodes spanning them,
    linear between."""
    cos_sun = np.clip(np.asarray(cos_sun, dtype=np.float64), -1.0, 1.0)
    low, high = float(cos_sun.min(initial=1.0)), float(cos_sun.max(initial=-1.0))
    if cos_sun.size == 0:
        return np.zeros(cos_sun.shape + (3,))
    if high - low < 1e-9:
        return np.broadcast_to(_over_deck(luts, layer, np.array([low]))[0], cos_sun.shape + (3,)).copy()
    nodes = np.linspace(low, high, SUN_NODES)
    values = _over_deck(luts, layer, nodes)
    return np.stack([np.interp(cos_sun, nodes, values[:, c]) for c in range(3)], axis=-1)


@dataclass
class DeckLight:
    extra: np.ndarray       # (3,) the deck top's mean radiance beyond what the tables count, per unit sun
    counted: np.ndarray     # (3,) the radiance of a ground of the atmosphere's albedo under the same light


def deck_light(luts: Luts, layer: CloudLayer, cos_sun: float) -> DeckLight:
    """The light the deck's top sends up (its mean over the columns, as diffuse radiance), less
    a ground of the atmosphere's albedo under the same sun and sky, whose light the tables hold
    already."""
    up, down = _top_fluxes(luts, layer, np.array([cos_sun]))
    counted = luts.params.ground_albedo * down[0] / np.pi
    return DeckLight(extra=np.maximum(up[0] / np.pi - counted, 0.0), counted=counted)


def _top_fluxes(luts: Luts, layer: CloudLayer, cos_sun):
    """((n, 3), (n, 3)): the deck's upward flux and the sun's and sky's flux on its top."""
    sun, r_sun, r_sky, table_sky = _deck(luts, layer, cos_sun)
    sky = _with_deck_gain(luts.params, layer, sun, r_sun, r_sky, table_sky)
    return r_sun[:, None] * sun + r_sky[:, None] * sky, sun + sky


def _deck(luts: Luts, layer: CloudLayer, cos_sun):
    """The sun's flux on the top (n, 3), the columns' mean reflectances for the sun and for the
    sky (n,) each, and the table's sky irradiance at the top (n, 3)."""
    top = layer.base + layer.thickness
    mu_s = np.maximum(cos_sun, 0.0)
    sun = luts.transmittance_to_top(top, cos_sun) * mu_s[:, None]
    full = layer.density * layer.thickness

    def reflectances(fraction):
        reflected_sun, _ = slab.two_stream(full * fraction, np.maximum(mu_s, slab.MIN_COS))
        reflected_sky, _ = slab.diffuse_two_stream(full * fraction)
        return np.stack([reflected_sun, np.broadcast_to(reflected_sky, reflected_sun.shape)], axis=-1)

    r_sun, r_sky = np.moveaxis(field.column_mean(layer.coverage, reflectances), -1, 0)
    return sun, r_sun, r_sky, luts.sky_irradiance(top, cos_sun)


def _over_deck(luts: Luts, layer: CloudLayer, cos_sun) -> np.ndarray:
    """(n, 3) the table's sky irradiance at the top, with what the deck sends back up and the
    air above returns (the module docstring)."""
    return _with_deck_gain(luts.params, layer, *_deck(luts, layer, cos_sun))


def _with_deck_gain(params, layer: CloudLayer, sun, r_sun, r_sky, sky) -> np.ndarray:
    """The table's sky irradiance ``sky`` at the top plus what the air above returns of the
    deck's light (_deck's terms)."""
    top = layer.base + layer.thickness
    above = np.array([params.rayleigh_scale_height * np.exp(-top / params.rayleigh_scale_height),
                      params.mie_scale_height * np.exp(-top / params.mie_scale_height)])
    x = 0.75 * (above[0] * params.rayleigh + (1.0 - params.mie_g) * above[1] * params.mie)
    albedo = x / (1.0 + x)
    up = r_sun[:, None] * sun + r_sky[:, None] * sky
    gain = albedo * np.maximum(up - params.ground_albedo * (sun + sky), 0.0) / (1.0 - albedo * r_sky[:, None])
    return sky + gain
