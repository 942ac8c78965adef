"""Clouds as extra Mie density along view rays to surfaces (the demoscene ray marcher's last
step): a peak whose top stands in the cloud layer is veiled by the same cloud the sky shows
behind it. Twin of the "OLS Cloud Veil" compositor group (addon/nodes/cloud_veil.py).

The part of the camera -> surface segment inside the layer's height band is marched in STEPS
equal steps. Each step crosses the column under its middle, a homogeneous slab filling
field.thickness_fraction of the thickness about the layer's middle (layer.py); the step is in
cloud over the share of its height range that lies in the slab (so a nearly level ray through
a cloud edge fades, rather than stepping on and off), and adds extinction density x length x
share. Its source, per unit sun, is the column's own light at that depth:
- the sun scattered once: the cloud phase function x the sun's transmittance through the
  atmosphere to the layer (the tables, as the sky's clouds) x exp(-tau_above / mu_s), tau_above
  the slab's optical depth over the point;
- the diffuse light inside the slab, from the delta-Eddington fluxes the sky's clouds use
  (slab.two_stream, diffuse_two_stream), linear in optical depth (the Eddington solution inside
  a conservative slab): downward from the ambient skylight's irradiance E at the top (the sun's
  diffuse part 0 there) to T mu_s + T_d E at the bottom, upward from R mu_s + R_d E at the top
  to 0 at the bottom. A forward-scattering cloud sends on mostly the light travelling the view's
  way: F_down / pi looking up (so a thick cloud's base looks as the sky's clouds show it from
  below), F_up / pi looking down, the Eddington I0 + I1 mu in between (``toward``).
The veil sits at the surface's end of the segment: the render's surface light L becomes
    L T_v + V x sun strength,   T_v = exp(-sum dtau),   V = sum_i J_i exp(-tau_<i) (1 - exp(-dtau_i)),
which the aerial perspective then hazes as it hazes any surface. The air between the cloud and
the surface so counts as in front of the cloud; where a peak stands in the cloud that is the
shorter part of the path.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import slab, top_light
from .layer import CloudLayer
from .sky import column_fraction

# The "OLS Frame Values" rows the veil group reads besides lut_gen.clouds.shafts.ROWS.
ROWS = ("Cloud Shape", "Cloud Sun", "Cloud Ambient")
STEPS = 8           # steps through the layer's band: 75 m each through a 600 m layer seen from below
MIN_RISE = 1.0      # m: a step's height range is at least this, so level rays take the point's state


@dataclass(frozen=True)
class VeilLight:
    """The light reaching the layer, per unit sun, for the frame (the scene spans a few tens of
    kilometres: the same for every point): the sun's transmittance through the atmosphere to the
    layer's middle (RGB) and the sky's irradiance on its top (RGB, top_light.py)."""
    sun: tuple
    ambient: tuple

    @classmethod
    def of(cls, luts, layer: CloudLayer, sun_direction) -> "VeilLight":
        cos_sun = float(np.clip(np.asarray(sun_direction, dtype=np.float64)[2], -1.0, 1.0))
        sun = np.asarray(luts.transmittance_to_top(layer.middle, np.array([cos_sun])), dtype=np.float64).reshape(3)
        ambient = np.asarray(top_light.skylight(luts, layer, np.array([cos_sun])), dtype=np.float64).reshape(3)
        return cls(tuple(sun), tuple(ambient))          # 0 where the Earth hides the sun from the layer


def toward(down, up, view_z):
    """The diffuse radiance travelling toward a viewer looking along zenith cosine ``view_z``,
    from the downward and upward fluxes (per unit irradiance): F_down / pi looking straight up,
    F_up / pi straight down, in between the Eddington form I0 + I1 mu."""
    return ((1.0 + view_z) * down + (1.0 - view_z) * up) / (2.0 * np.pi)


def frame_rows(layer: CloudLayer | None, light: VeilLight | None) -> dict:
    """The rows of ROWS: Cloud Shape (base, thickness, density), Cloud Sun and Cloud Ambient (the
    frame's VeilLight). No layer: no cloud (zero density)."""
    if layer is None or light is None:
        return {"Cloud Shape": (0.0, 1.0, 0.0), "Cloud Sun": (0.0, 0.0, 0.0), "Cloud Ambient": (0.0, 0.0, 0.0)}
    return {"Cloud Shape": (layer.base, layer.thickness, layer.density), "Cloud Sun": light.sun,
            "Cloud Ambient": light.ambient}


def veil(layer: CloudLayer, cloud, light: VeilLight, camera, points, sun):
    """(T_v (...), V (..., 3)) for the camera -> ``points`` (..., 3) segments: the share of the
    surface's light the cloud lets through, and the cloud's own light in front of it per unit
    sun (module docstring)."""
    camera = np.asarray(camera, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    sun = np.asarray(sun, dtype=np.float64)
    d = points - camera
    length = np.linalg.norm(d, axis=-1)
    view = d / np.maximum(length, 1e-9)[..., None]
    rise = d[..., 2]
    rise = np.where(np.abs(rise) < 1e-6, 1e-6, rise)
    low, high = layer.base, layer.base + layer.thickness
    a, b = (low - camera[2]) / rise, (high - camera[2]) / rise
    enter, leave = np.clip(np.minimum(a, b), 0.0, 1.0), np.clip(np.maximum(a, b), 0.0, 1.0)
    span = leave - enter
    mu_s = max(float(sun[2]), slab.MIN_COS)
    phase = slab.phase(view @ sun)
    up = view[..., 2]
    sun_light, ambient = np.asarray(light.sun), np.asarray(light.ambient)
    through = np.ones(points.shape[:-1])
    glow = np.zeros(points.shape[:-1] + (3,))
    for k in range(STEPS):
        s0, s1 = enter + span * k / STEPS, enter + span * (k + 1) / STEPS
        middle = camera + d * (0.5 * (s0 + s1))[..., None]
        z0, z1 = camera[2] + d[..., 2] * s0, camera[2] + d[..., 2] * s1
        centre, half = 0.5 * (z0 + z1), np.maximum(0.5 * np.abs(z1 - z0), 0.5 * MIN_RISE)
        fraction = column_fraction(layer, cloud, middle[..., 0], middle[..., 1])
        slab_half = 0.5 * layer.thickness * fraction
        bottom, top = layer.middle - slab_half, layer.middle + slab_half
        share = np.clip((np.minimum(centre + half, top) - np.maximum(centre - half, bottom)) / (2.0 * half), 0.0, 1.0)
        dtau = layer.density * share * span * length / STEPS
        column = layer.density * (top - bottom)
        above = layer.density * (top - np.clip(centre, bottom, top))
        depth = above / np.maximum(column, 1e-9)
        reflected, transmitted = slab.two_stream(column, mu_s)
        back, diffuse = slab.diffuse_two_stream(column)
        sun_down, sun_up = depth * transmitted * mu_s, (1.0 - depth) * reflected * mu_s
        sky_down, sky_up = (1.0 - depth) + depth * diffuse, (1.0 - depth) * back
        source = (sun_light * (phase * np.exp(-above / mu_s) + toward(sun_down, sun_up, up))[..., None]
                  + ambient * toward(sky_down, sky_up, up)[..., None])
        glow += source * (through * -np.expm1(-dtau))[..., None]
        through = through * np.exp(-dtau)
    return through, glow


def veiled(image, transmittance, glow, sun_strength, geometry):
    """The render's surface light behind the veil (sky pixels unchanged)."""
    image = np.asarray(image, dtype=np.float64)
    out = image * transmittance[..., None] + glow * sun_strength
    return np.where(np.asarray(geometry)[..., None], out, image)
