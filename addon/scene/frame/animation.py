"""animate_sun: the sun follows a day across the frames day_start_frame-day_end_frame (the
scene's frame range when Animate Sun was turned on; kept apart from it so that a farm's chunk,
which changes the frame range, gets the same sun). Equinox at 45 deg N: rises in the east,
culminates due south at 45 deg, sets in the west; the first frame is sunrise minus an hour, the
last sunset plus an hour."""
from __future__ import annotations

import math

LATITUDE = math.radians(45.0)
HOUR_ANGLE_RANGE = math.radians(105.0)      # +-7 h around noon


def sun_angles_for_frame(frame: float, frame_start: int, frame_end: int):
    """(elevation_deg, azimuth_deg) with azimuth measured from +Y (north... here: the view
    direction of the sample camera) toward +X."""
    span = max(frame_end - frame_start, 1)
    t = min(max((frame - frame_start) / span, 0.0), 1.0)
    hour = (2.0 * t - 1.0) * HOUR_ANGLE_RANGE
    # Equinox: declination 0. Direction in (east, north, up) for hour angle h.
    east = -math.sin(hour)
    north = -math.sin(LATITUDE) * math.cos(hour)
    up = math.cos(LATITUDE) * math.cos(hour)
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, up))))
    # Face south (+Y of the sample camera): azimuth from +Y (south) toward +X (west).
    azimuth = math.degrees(math.atan2(-east, -north))
    return elevation, azimuth
