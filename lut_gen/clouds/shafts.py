"""Light shafts under the cloud layer: the clouds as a partial occluder of the sun in the air.

Both light-shaft techniques (the brute-force march, lut_gen.passes.aerial.light_shafts with the
"OLS Light Shafts" group, and the epipolar tables, lut_gen.passes.epipolar) test each march point
against the shadow maps. With clouds on, the point's sun visibility is that test times the
cloud column's transmittance toward the sun where the point's sun line crosses the layer
(lut_gen.clouds.shadow.ground_transmittance, the shadow-only layer's twin): a step under a cloud
counts as a fraction lit, so shafts fan out from the gaps and the air under a cloud darkens.
The product keeps the min/max shortcut exact: the maps decide the geometry's part alone and
the cloud factor multiplies what they decide.

Crepuscular rays run for kilometres, far past the scene's shadow cascades, so a sky pixel's
march goes on past the last cascade to where its ray meets the layer's middle (the cloud the
world shows there), at most SHAFT_RANGE away: there the air's light lies in front of the cloud,
as the world group composites it (lut_gen.clouds.sky), and the march replaces exactly that.

The compositor reads the layer from two "OLS Frame Values" rows (``frame_rows``), written each
frame, so a keyframed offset moves the shafts with the clouds in every render.
"""
from __future__ import annotations

import numpy as np

from . import field
from .layer import SHAFT_RANGE, CloudLayer, middle_hit  # noqa: F401 (shafts.SHAFT_RANGE)
from .shadow import ground_transmittance

ROWS = ("Cloud Layer", "Cloud Map")
# The epipolar tables' distance intervals grow geometrically to kilometres near SHAFT_RANGE,
# longer than a cloud feature: their cloud factor is the mean of samples this far apart (in
# cloud scales), at most MAX_INTERVAL_SAMPLES per interval. One sample per interval put the
# epipolar shafts 36 dB from a 256-step march at 16 steps (brute force: 43 dB).
INTERVAL_SPACING = 0.25
MAX_INTERVAL_SAMPLES = 16


def of_settings(settings):
    """(CloudLayer, map ranks) of settings with the panel's names while Clouds is on, else None
    (the map made from the seed, as the add-on makes its image)."""
    layer = CloudLayer.enabled_in(settings)
    return None if layer is None else (layer, field.cached_map(layer.seed))


def sun_visibility(is_lit, layer: CloudLayer, cloud, sun):
    """``is_lit(points) -> (...)`` (the shadow maps) times the cloud's transmittance toward the
    sun at each point."""
    def visible(points):
        return np.asarray(is_lit(points), dtype=np.float64) * ground_transmittance(layer, cloud, points, sun)
    return visible


def interval_transmittance(layer: CloudLayer, cloud, origin, directions, t, sun):
    """(n, len(t) - 1): the cloud's transmittance toward the sun (ground_transmittance) averaged
    over each distance interval [t_k, t_k+1] of the rays from ``origin`` along unit
    ``directions`` (n, 3), by evenly spaced samples (INTERVAL_SPACING)."""
    directions = np.asarray(directions, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    lengths = np.diff(t)
    counts = np.clip(np.ceil(lengths / (INTERVAL_SPACING * layer.scale)), 1, MAX_INTERVAL_SAMPLES).astype(int)
    mean = np.empty((len(directions), len(lengths)))
    for k, (start, length, count) in enumerate(zip(t[:-1], lengths, counts)):
        along = start + length * (np.arange(count) + 0.5) / count
        points = origin + directions[:, None, :] * along[None, :, None]
        mean[:, k] = ground_transmittance(layer, cloud, points, sun).mean(axis=-1)
    return mean


def march_distance(layer: CloudLayer, camera_position, directions, earth_radius: float):
    """(...) distance along unit ``directions`` from the camera to the layer's middle, capped
    at SHAFT_RANGE; 0 for rays that do not meet it (a sky pixel then ends at the cascades)."""
    distance, hit = middle_hit(layer, max(float(camera_position[2]), 0.0), directions, earth_radius)
    return np.where(hit, np.minimum(distance, SHAFT_RANGE), 0.0)


def reach(layer: CloudLayer, camera_position, directions, earth_radius: float) -> float:
    """The farthest march distance of ``directions`` (a screen's border rays, say)."""
    return float(np.max(march_distance(layer, camera_position, directions, earth_radius), initial=0.0))


def frame_rows(layer: CloudLayer | None) -> dict:
    """The two "OLS Frame Values" rows of the layer, as the shadow-test group reads them:
    Cloud Layer (the coverage threshold, the middle height, the full column's optical depth),
    Cloud Map (1 / the tile's size in metres, the offset). No layer: a clear column."""
    if layer is None:
        return {"Cloud Layer": (2.0, 0.0, 0.0), "Cloud Map": (0.0, 0.0, 0.0)}
    tile = field.TILE_FEATURES * layer.scale
    return {"Cloud Layer": (float(field.threshold(layer.coverage)), layer.middle, layer.density * layer.thickness),
            "Cloud Map": (1.0 / tile, float(layer.offset[0]), float(layer.offset[1]))}
