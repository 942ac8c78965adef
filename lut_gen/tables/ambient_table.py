"""The ambient skylight table baked: E_sky, Yusov 2013 eq. (3), the irradiance of the whole sky
on a horizontal plane against the sun's zenith cosine, from the finished 4D tables."""
from __future__ import annotations

import numpy as np

from . import parameterization as par
from .bake_parallel import Progress, parallel_rows, workers
from .lookup import Luts

AMBIENT_HEIGHT_M = 20.0         # the sample's camera height for Yusov 2013 eq. (3)


def bake_ambient(luts: Luts, n: int, progress: Progress = lambda stage, fraction: None) -> np.ndarray:
    """E_sky(c_s) = integral over the upper hemisphere of L_M(20 m, w, l) (w . N) dw, the sun
    nodes shared between the cores (one took 1 s of the default bake)."""
    cos_sun = par.centre_nodes(n) * 2 - 1
    parts = np.array_split(np.arange(n), min(n, 2 * workers()))
    out = np.empty((n, 3), dtype=np.float32)

    def fill(part):
        rows = parts[part]
        out[rows] = luts.sky_irradiance(AMBIENT_HEIGHT_M, cos_sun[rows])
    # The tables packed for look-ups once for all parts (each look-up packs them anew otherwise),
    # and dropped after: the bake's Luts do not keep them.
    kept = luts._packed
    luts.keep_packed()
    try:
        for name in ("multiple", "single_mie") + (() if luts.single_fog is None else ("single_fog",)):
            luts._packed_table(name)
        parallel_rows(fill, len(parts), progress, "ambient skylight")
    finally:
        luts._packed = kept
    return out
