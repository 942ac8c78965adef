"""The precomputed tables: their parameterization and interpolation, the bake, the optical-depth
and ground terms, and the look-ups into them (``lookup.Luts``). Reads model/ only."""
from . import atlas, bake, ground, interpolation, lookup, optical_depth, parameterization  # noqa: F401
