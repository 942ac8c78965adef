"""Helpers shared by the tests that compare baked tables with the Monte Carlo path tracer
(test_multiple_scattering_mc: the clear sky, spectrally; test_fog_bake_mc: the fog layer):
relative errors and standard errors as RGB norms, sums of orders with their standard errors,
and the printed rows."""
from __future__ import annotations

import math

import numpy as np


def sees_ground(params, geometry) -> bool:
    """Whether the view ray of geometry (height, cos view zenith, ...) ends on the ground."""
    height, cos_view = geometry[0], geometry[1]
    r = params.earth_radius + height
    return cos_view < -math.sqrt(max(1.0 - (params.earth_radius / r) ** 2, 0.0))


def order_sum(values, cov, start, stop):
    """Sum of orders [start, stop) of (orders, C) values and its standard error (C,), from the
    path tracer's covariances between orders (cov: (orders, orders, C))."""
    sl = slice(start, stop)
    return values[sl].sum(axis=0), np.sqrt(np.maximum(cov[sl, sl].sum(axis=(0, 1)), 0.0))


def relative_error(got, want) -> float:
    """|got - want| / |want| over the channels (the project's usual RGB error)."""
    return float(np.linalg.norm(np.asarray(got, np.float64) - want) / np.linalg.norm(want))


def relative_se(se, want) -> float:
    """A standard error (C,) relative to the value it belongs to, as an RGB norm."""
    return float(np.linalg.norm(se) / np.linalg.norm(want))


def fmt(values) -> str:
    return "(" + ", ".join(f"{x:.4e}" for x in values) + ")"


def deviation(got, want) -> str:
    """Per channel table / mc - 1, printed."""
    return "table/mc-1 (" + ", ".join(f"{g / w - 1.0:+6.1%}" for g, w in zip(got, want)) + ")"
