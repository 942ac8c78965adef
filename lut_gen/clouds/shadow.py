"""Cloud shadows: the sun's transmittance through the cloud column over a point, the twin of the
"OLS Cloud Shadow" group on the add-on's shadow-only layer (addon/nodes/cloud_shadow.py).

The layer is a flat, shadow-only plane at the clouds' middle height: a shadow ray toward the sun
from any point below crosses it where the sun line meets the layer, and takes the column's
transmittance along the sun, exp(-tau / mu_s). Over the few tens of kilometres a scene spans the
Earth's curvature lowers the shell by metres, which the plane ignores.
"""
from __future__ import annotations

import numpy as np

from . import slab
from .layer import CloudLayer
from .sky import column_fraction


def sun_transmittance(layer: CloudLayer, cloud, x, y, cos_sun):
    """Transmittance toward the sun through the cloud column at layer-plane point (x, y)."""
    tau = layer.density * layer.thickness * column_fraction(layer, cloud, x, y)
    return np.exp(-tau / np.maximum(cos_sun, slab.MIN_COS))


def ground_transmittance(layer: CloudLayer, cloud, points, sun):
    """sun_transmittance for world ``points`` (..., 3) below the layer: where their sun line
    meets the layer plane. 1 where the sun is below the horizon or the point above the layer."""
    points = np.asarray(points, dtype=np.float64)
    sun = np.asarray(sun, dtype=np.float64)
    if sun[2] <= 0:
        return np.ones(points.shape[:-1])
    rise = (layer.middle - points[..., 2]) / sun[2]
    t = sun_transmittance(layer, cloud, points[..., 0] + rise * sun[0], points[..., 1] + rise * sun[1], sun[2])
    return np.where(rise > 0, t, 1.0)
