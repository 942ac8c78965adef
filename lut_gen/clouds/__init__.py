"""The cloud layer: its field (a tileable map from a seed), its optics (a homogeneous slab per
map texel) and how the sky, the ground's light and the light shafts see it. Pure numpy; the
add-on's node groups are its twins (addon/nodes/clouds.py)."""

from . import field, layer, shadow, slab, sky  # noqa: F401,E402 (lut_gen.clouds.<module> for the add-on and tests)
