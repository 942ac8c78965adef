"""Aerial perspective's transmittance in fog from a camera 2 m up (issue 26: "a 20 m fog scale
height near the ground must come out right ... in the aerial perspective from a camera 2 m
up"): lut_gen.passes.aerial.segment_transmittance, the twin of the add-on's "OLS Segment
Transmittance" group, read from the default-size optical-depth table, against brute-force
integration of the same media along each segment."""
import numpy as np
import pytest

from lut_gen.model.atmosphere import AtmosphereParams
from lut_gen.model.profiles import densities
from lut_gen.passes import aerial
from lut_gen.tables.bake import RESOLUTIONS, bake_optical_depth
from lut_gen.tables.lookup import Luts

CAMERA = np.array([0.0, 0.0, 2.0])


def brute_force_optical_depth(params, start, end, n=20001):
    s = np.linspace(0.0, 1.0, n)
    points = start + (end - start) * s[:, None]
    heights = np.linalg.norm(points + [0.0, 0.0, params.earth_radius], axis=1) - params.earth_radius
    return np.trapz(densities(params, heights) @ params.extinction_matrix(), s, axis=0) * np.linalg.norm(end - start)


@pytest.mark.parametrize("visibility, fog_height", [(300.0, 20.0), (1000.0, 50.0)])
def test_fog_transmittance_from_two_metres(visibility, fog_height):
    params = AtmosphereParams(fog_visibility=visibility, fog_height=fog_height)
    z = np.zeros((2, 2, 2, 2, 3), np.float32)
    luts = Luts(params, single=z, higher=z, optical_depth=bake_optical_depth(params, *RESOLUTIONS["default"].optical_depth),
                ambient=np.zeros((4, 3), np.float32))
    worst = 0.0
    for distance in (50.0, 200.0, 1000.0, 5000.0):
        for elevation_deg in (-1.0, -0.02, 0.0, 0.5, 2.0, 10.0):
            e = np.radians(elevation_deg)
            end = CAMERA + distance * np.array([0.0, np.cos(e), np.sin(e)])
            if end[2] - distance ** 2 / (2 * params.earth_radius) < 0.0:
                continue                # the ground is in the way
            got = aerial.segment_transmittance(luts, CAMERA[None], end[None])[0]
            tau = brute_force_optical_depth(params, CAMERA, end)
            # In optical depth: a transmittance of 1e-20 need not be right to 1%, its depth must.
            error = np.abs(-np.log(got) - tau)
            worst = max(worst, float(np.max(error / (0.02 * tau + 0.01))))
            assert np.all(error <= 0.02 * tau + 0.01), (distance, elevation_deg, -np.log(got), tau)
    print(f"fog {visibility:g} m / {fog_height:g} m: worst error / allowance {worst:.2f}")
