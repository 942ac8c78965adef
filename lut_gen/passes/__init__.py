"""Per-frame work, in numpy: the aerial perspective, the light-scattering pass (brute force and
epipolar sampling), shadow maps and their min/max trees, the lighting panoramas, the camera's twilight correction
(sky_view), previews and tone mapping. Each compositor or shader node group's numpy twin lives here or in tables/lookup."""
from . import (aerial, epipolar, epipolar_air, epipolar_grid, frame_values, min_max, panorama,  # noqa: F401
               preview, render_detail, scattering_pass, shadow_map, shadow_raster, sky_view, terrain,
               tone_mapping)
