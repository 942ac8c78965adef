"""Cloud presets: settings of lut_gen.clouds.layer.CloudLayer for common skies, shared by the
panel's Preset control and `scripts/render.py --clouds NAME`.

Heights and thicknesses are typical of each genus (WMO cloud atlas); densities give the optical
depths such clouds have (fair-weather cumulus 10-30, stratocumulus at sunset 5-15, overcast
stratus 20-60)."""
CLOUD_PRESETS = {
    "fair-weather-cumulus": dict(coverage=0.35, base=1200.0, thickness=800.0, density=0.03, scale=1500.0),
    "broken-sunset": dict(coverage=0.55, base=2000.0, thickness=500.0, density=0.02, scale=3000.0),
    "overcast": dict(coverage=1.0, base=800.0, thickness=1000.0, density=0.04, scale=4000.0),
}
