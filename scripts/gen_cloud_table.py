"""Regenerate lut_gen/clouds/data/higher_orders.json: the cloud slab's second and higher
scattering orders from the Monte Carlo path tracer (lut_gen/verify/slab_monte_carlo.py), as
ratios to the delta-Eddington fluxes, as the cosine series in azimuth of their logarithms
(lut_gen/clouds/slab.py reads it). About a minute on 2 cores (67 s, 2026-12-07):
    .venv/bin/python scripts/gen_cloud_table.py
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from lut_gen.clouds import slab  # noqa: E402
from lut_gen.store.atomic import atomic_path  # noqa: E402
from lut_gen.verify.slab_monte_carlo import higher_order_samples, log_cosine_series  # noqa: E402

PHOTONS = 12000


def main():
    taus, cos_suns, cos_views = slab.TABLE_TAUS, slab.TABLE_COS, slab.TABLE_COS
    radiance = higher_order_samples(taus, cos_suns, cos_views, photons=PHOTONS)
    ratio = np.zeros_like(radiance)
    for i, tau in enumerate(taus):
        for j, cos_sun in enumerate(cos_suns):
            reflected, transmitted = slab.two_stream(tau, cos_sun)
            ratio[0, i, j] = radiance[0, i, j] / max(cos_sun * transmitted / np.pi, 1e-12)
            ratio[1, i, j] = radiance[1, i, j] / max(cos_sun * reflected / np.pi, 1e-12)
    # The diffuse flux is the tracer's too, so exp(c0) is near the flux's shape factor; the
    # other terms carry the azimuthal shape (the forward glow of thin clouds, the glint of a
    # low sun).
    ratio = log_cosine_series(ratio, slab.LOG_TERMS)
    out = {"about": __doc__.strip().splitlines()[0], "photons": PHOTONS, "phase_lobes": slab.PHASE_LOBES,
           "taus": list(taus), "cos": list(cos_suns), "log_series": np.round(ratio, 5).tolist()}
    with atomic_path(slab.TABLE_PATH) as tmp:
        with open(tmp, "w") as f:
            json.dump(out, f)
    print("wrote", slab.TABLE_PATH, "log-series range", ratio.min(), ratio.max())


if __name__ == "__main__":
    main()
