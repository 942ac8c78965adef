"""Ray geometry shared by the tests: (height, cos view zenith, cos sun zenith, cos sun-view)."""
import math


def ray(height_m, view_zenith_deg, sun_zenith_deg, azimuth_deg):
    """A view and a sun direction azimuth_deg apart, zenith angles in degrees."""
    tv, ts, az = (math.radians(x) for x in (view_zenith_deg, sun_zenith_deg, azimuth_deg))
    cos_sun_view = math.cos(tv) * math.cos(ts) + math.sin(tv) * math.sin(ts) * math.cos(az)
    return (float(height_m), math.cos(tv), math.cos(ts), cos_sun_view)


def ray_by_elevation(height_m, view_elevation_deg, sun_elevation_deg, azimuth_deg):
    """The same with elevations (degrees above the horizontal)."""
    return ray(height_m, 90.0 - view_elevation_deg, 90.0 - sun_elevation_deg, azimuth_deg)
