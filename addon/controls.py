"""The controls registry: every control of ``scene.ols``, declared once (addon/control_sets/).

Made from it: the PropertyGroup (addon/props.py), the clamps the render reads through
(addon/settings.py), the panel's rows (addon/ui.py) and the table in docs/controls.md
(``docs_table``; ``python -m scripts.controls_table`` writes it, a test holds the two equal).
Plain Python, no bpy.
"""
from __future__ import annotations

from .control_sets import additional, basic, clouds, tone_mapping
from .control_sets.spec import Change, Control, Reads

CONTROL_SET = Control(
    "control_set", "Control Set", section="", kind="enum", default="BASIC", change=Change.NOTHING,
    reads=(Reads.PANEL,),
    items=(("BASIC", "Basic", "Light scattering, epipolar sampling and shadow map controls"),
           ("ADDITIONAL", "Additional", "Scattering modes, shadow cascades and atmosphere media"),
           ("TONE_MAPPING", "Tone Mapping", "HDR to LDR conversion controls"),
           ("CLOUDS", "Clouds", "A cloud layer in the sky, lit by the sun through the atmosphere")),
    description="Which of the sample's three control sets the panel shows")

# Panel order: the control sets in the drop-down's order, each set's controls in the sample's.
SECTIONS = {module.SECTION: module.CONTROLS for module in (basic, additional, tone_mapping, clouds)}
CONTROLS: tuple[Control, ...] = (CONTROL_SET, *(control for controls in SECTIONS.values() for control in controls))
BY_NAME = {control.name: control for control in CONTROLS}
if len(BY_NAME) != len(CONTROLS):
    raise RuntimeError("two controls share a name")

CONTROL_SETS = tuple(SECTIONS)
PROPERTIES_BY_SET = {section: [control.name for control in controls] for section, controls in SECTIONS.items()}
# The sample's controls that have no counterpart in this design, and why (the panel greys them
# out and their tooltips end with the reason).
WITHOUT_EFFECT = {control.name: control.inert for control in CONTROLS if control.inert}
ENABLED_BY = {control.name: control.enabled_by for control in CONTROLS if control.enabled_by}

DEFAULT_RAYLEIGH_COLOR = additional.DEFAULT_RAYLEIGH_COLOR
DEFAULT_MIE_COLOR = additional.DEFAULT_MIE_COLOR
RAYLEIGH_SCATTERING_SCALE = additional.RAYLEIGH_SCATTERING_SCALE


# -- docs/controls.md ---------------------------------------------------------------------------

DOCS_BEGIN = "<!-- controls table: made from addon/controls.py by `.venv/bin/python scripts/controls_table.py` -->"
DOCS_END = "<!-- end of the controls table -->"
_SECTION_TITLES = {"": "Panel", "BASIC": "Basic", "ADDITIONAL": "Additional", "TONE_MAPPING": "Tone Mapping",
                   "CLOUDS": "Clouds"}


def _number(value, unit="") -> str:
    text = f"{value:g}" if isinstance(value, float) else str(value)
    return f"{text} {unit}" if unit else text


def docs_default(control: Control) -> str:
    if control.kind == "bool":
        return "on" if control.default else "off"
    if control.kind == "enum":
        return next(label for identifier, label, _ in control.items if identifier == control.default)
    if control.kind in ("color", "vector"):
        return "(" + ", ".join(f"{c:.3g}" for c in control.default) + ")" + (f" {control.unit}" if control.unit else "")
    return _number(control.default, control.unit)


def docs_range(control: Control) -> str:
    if control.kind == "enum":
        return ", ".join(label for _, label, _ in control.items)
    if control.range is None:
        return ""
    low, high = control.range
    text = f"{_number(low)} to {_number(high, control.unit)}"
    return f"{text} (slider to {_number(control.soft_max)})" if control.soft_max is not None else text


def docs_table() -> str:
    """The table of every control, as docs/controls.md holds it between DOCS_BEGIN and DOCS_END."""
    rows = ["| set | control | Python name | default | range | a change | the render reads it as |",
            "|---|---|---|---|---|---|---|"]
    for control in CONTROLS:
        change = "none (no effect here)" if control.inert else control.change.value
        reads = ", ".join(r.value for r in control.reads)
        rows.append(f"| {_SECTION_TITLES[control.section]} | {control.label} | `{control.name}` | "
                    f"{docs_default(control)} | {docs_range(control)} | {change} | {reads} |")
    return "\n".join([DOCS_BEGIN, "", *rows, "", DOCS_END])


def replace_docs_table(text: str) -> str:
    """``text`` (docs/controls.md) with its table made anew; ValueError when the markers are missing."""
    start, end = text.find(DOCS_BEGIN), text.find(DOCS_END)
    if start < 0 or end < start:
        raise ValueError("docs/controls.md has no controls-table markers")
    return text[:start] + docs_table() + text[end + len(DOCS_END):]
