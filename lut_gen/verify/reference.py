"""Brute-force reference integrators: the "truth" the precomputed tables are checked against.

Nothing here reads a table or interpolates precomputed data. Every quantity is integrated
numerically along straight rays through the spherical atmosphere of ``AtmosphereParams``:

* ``net_density_to_top``: integrated Rayleigh / Mie / ozone / fog densities to the top
  (``profiles.MEDIA``'s order, the rows of ``AtmosphereParams.extinction_matrix``).
* ``transmittance_to_top``: ``exp(-net @ extinction_matrix)``.
* ``single_scattering``: single-scattered radiance per unit extraterrestrial sun,
  phase functions included, with the sun's optical depth at every view sample integrated
  numerically as well (a ray per sample, not an analytic approximation). The fog
  (``params.has_fog``) is a fourth medium that only scatters, grey, with its own
  Cornette-Shanks phase function ``mie_phase(cos, params.fog_g)``.
* ``second_order``: twice-scattered radiance (no ground reflection), and its source term
  ``second_order_source``.
* ``spectral`` / ``per_wavelength``: any of these per wavelength, converted to RGB, for
  spectral params.

The references are deliberately self-contained (they share no geometry code with the baker)
so that they stay an independent check. Everything is float64 numpy, broadcast over the
inputs and processed in chunks to bound memory.

This module gathers the public names; each part has its own module, which documents its
quadrature and what was measured:

* ``reference_rays``: ray geometry, the clustered nodes and the trapezoid and cumulative rules;
* ``reference_transmittance``: net densities, transmittance, the ozone and fog line integrals;
* ``reference_single_scattering``: single scattering;
* ``reference_second_order``: the second order and its sphere quadrature;
* ``reference_spectral``: the per-wavelength integration and its conversion to RGB.
"""
from __future__ import annotations

from .reference_second_order import SECOND_ORDER_DEFAULTS, second_order, second_order_source, sphere_phase_integrals
from .reference_single_scattering import single_scattering
from .reference_spectral import REFERENCE_WAVELENGTHS_NM, per_wavelength, spectral
from .reference_transmittance import HIT_EARTH_NET_DENSITY, fog_net_density, net_density_to_top, transmittance_to_top

__all__ = ["net_density_to_top", "transmittance_to_top", "single_scattering", "HIT_EARTH_NET_DENSITY",
           "fog_net_density", "second_order", "second_order_source", "sphere_phase_integrals",
           "SECOND_ORDER_DEFAULTS", "per_wavelength", "spectral", "REFERENCE_WAVELENGTHS_NM"]
