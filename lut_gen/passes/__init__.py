"""Per-frame work, in numpy: the aerial perspective, the light-scattering pass (brute force and
epipolar sampling), shadow maps and their min/max trees, the lighting panoramas, previews and
tone mapping. Each compositor or shader node group's numpy twin lives here or in tables/lookup."""
from . import (aerial, epipolar, epipolar_air, min_max, panorama, preview, render_detail,  # noqa: F401
               scattering_pass, shadow_map, tone_mapping)
