"""The Clouds control set: one cloud layer, its look and the wind (lut_gen.clouds)."""
from ...lut_gen.clouds.layer import RANGES
from ...lut_gen.clouds.presets import CLOUD_PRESETS
from .spec import Change as C, Control, Reads as R

SECTION = "CLOUDS"
# Wind rarely moves a layer more than tens of kilometres in a shot; far past that the field's
# float32 coordinates lose the detail of its features.
OFFSET_RANGE = (-1e6, 1e6)


def _clouds_on(settings):
    return settings.clouds_enabled


def _preset_items():
    yield "CUSTOM", "Custom", "The controls as set"
    for key, values in CLOUD_PRESETS.items():
        yield (key.upper().replace("-", "_"), key.replace("-", " ").capitalize(),
               ", ".join(f"{k} {v:g}" for k, v in values.items()))


def _layer(name, label, description, **options):
    """A control of the layer's shape: default and range from lut_gen.clouds.layer.RANGES."""
    default, low, high = RANGES[name]
    return Control(f"cloud_{name}", label, section=SECTION, kind="float", default=default, range=(low, high),
                   change=C.DRIVERS, reads=(R.CLOUD_LAYER,), enabled_by=_clouds_on, description=description,
                   **options)


CONTROLS = (
    Control('clouds_enabled', 'Clouds', section=SECTION, kind='bool', default=False,
            change=C.CLOUD_MAP, reads=(R.CLOUD_LAYER, R.COMPOSITOR, R.SHAFT_GRAPH),
            description="A cloud layer in the sky: lit by the sun through the atmosphere and by the sky, hazed"
                        " by the air in front of it (world shader; Set Up Scene makes the images)"),
    Control("cloud_preset", "Preset", section=SECTION, kind="enum", default="CUSTOM",
            change=C.PRESET, reads=(R.PANEL,), items=tuple(_preset_items()), enabled_by=_clouds_on,
            description="Set the cloud controls for a common sky (they stay editable)"),
    _layer("coverage", "Coverage", "Fraction of the sky the clouds cover (0: clear, 1: overcast)", subtype="FACTOR"),
    _layer("base", "Base", "Height of the cloud base above the ground", unit="m"),
    _layer("thickness", "Thickness", "Thickness of a full cloud (thinner at its edges)", unit="m"),
    _layer("density", "Density", "Extinction inside a cloud, per metre (0.033: optical depth 20 through 600 m, "
           "a stratocumulus or fair-weather cumulus)", unit="1/m", precision=4, step=0.1),
    _layer("scale", "Scale", "Size of the cloud features", unit="m"),
    Control("cloud_seed", "Seed", section=SECTION, kind="int", default=0, range=(0, 1_000_000),
            change=C.CLOUD_MAP, reads=(R.CLOUD_LAYER,), enabled_by=_clouds_on,
            description="Which cloud field: every seed is another sky of the same coverage"),
    Control("cloud_offset", "Offset", section=SECTION, kind="vector", default=(0.0, 0.0), range=OFFSET_RANGE,
            unit="m", change=C.DRIVERS, reads=(R.CLOUD_LAYER, R.FRAME_PASSES), enabled_by=_clouds_on,
            description="Shift of the cloud field (x, y): keyframe it for wind"),
)
