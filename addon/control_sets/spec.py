"""What one control of the panel is: its declaration, in plain Python (no bpy).

A ``Control`` says everything the four consumers need, so that none of them repeats it: the
PropertyGroup (addon/props.py), the clamps the render reads through (addon/settings.py), the
panel row (addon/ui.py) and its line in docs/controls.md (addon/controls.py renders it).
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Callable


class Change(enum.Enum):
    """What changing a control does at once (its property's update callback, addon/props.py)."""
    REBAKE = "re-bakes the tables"
    COMPOSITOR = "updates the compositor"
    CLOUD_MAP = "remakes the cloud map"
    MODEL = "switches the model"
    PRESET = "sets the preset's controls"
    DAY_RANGE = "takes the frame range"
    DRIVERS = "drivers follow at once"
    NOTHING = "read when a frame renders"


class Reads(enum.Enum):
    """How a render reads a control."""
    TABLES = "table parameters"
    MODEL = "which groups are built"
    COMPOSITOR = "compositor inputs"
    SHAFT_GRAPH = "light-shaft groups"
    FRAME_PASSES = "per-frame passes"
    CLOUD_LAYER = "cloud layer"
    SUN = "sun animation"
    ADAPTATION = "light adaptation"
    PANEL = "panel only"
    NONE = "no effect"


KINDS = ("bool", "int", "float", "enum", "color", "vector")
# Blender's largest frame number (MAXFRAME): frame controls range over every frame a scene has.
MAX_FRAME = 1_048_574


@dataclass(frozen=True)
class Control:
    """One control of ``scene.ols``.

    ``range`` is (min, max), the hard limits: the panel cannot go past them and the render clamps
    a value written past them (settings.safe_value). ``soft_max``: where the slider stops.
    ``unit``: "m" for lengths, else a word for the docs ("DU"). ``param``: the
    ``AtmosphereParams`` field the control sets, whose limits (PARAMETER_RANGES) hold the range.
    ``enabled_by``: the row is enabled only while this holds for the settings. ``inert``: why the
    control has no effect in this design (the row is greyed, the tooltip says it).
    """
    name: str
    label: str
    description: str
    kind: str
    default: object
    section: str
    change: Change
    reads: tuple
    range: tuple | None = None
    soft_max: float | None = None
    unit: str = ""
    subtype: str = ""
    precision: int | None = None
    step: float | None = None
    items: tuple = ()
    param: str | None = None
    enabled_by: Callable | None = None
    inert: str | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"{self.name}: kind {self.kind!r} is not one of {KINDS}")
        if self.kind == "enum" and self.default not in [item[0] for item in self.items]:
            raise ValueError(f"{self.name}: default {self.default!r} is not one of its items")
        if self.range is not None and self.kind in ("int", "float"):
            low, high = self.range
            if not low <= self.default <= high:
                raise ValueError(f"{self.name}: default {self.default!r} lies outside {self.range}")

    @property
    def numeric(self) -> bool:
        return self.kind in ("int", "float", "color", "vector")

    @property
    def tooltip(self) -> str:
        return f"{self.description} {self.inert}" if self.inert else self.description

    def clamp(self, value):
        """``value`` as the render may use it: a float that is NaN or infinite reads as the
        default, and a number past the range is clamped into it (an ID-property write bypasses
        the range). Vectors are the property's own business: Blender keeps them in range."""
        if self.kind not in ("int", "float"):
            return value
        if self.kind == "float" and not math.isfinite(value):
            value = self.default
        if self.range is not None:
            value = min(max(value, self.range[0]), self.range[1])
        return type(value)(value)
