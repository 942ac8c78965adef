"""The controls registry (addon/controls.py): the PropertyGroup, the clamps, the panel's rows and
docs/controls.md's table are all made from it, and every range it allows is one the model takes."""
import math
import os

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from extension import ROOT, extension_module  # noqa: E402
from render_util import render_rgb  # noqa: E402

pytestmark = pytest.mark.bpy
WIDTH, HEIGHT = 48, 27


@pytest.fixture
def scene(addon_package):
    scene = bpy.data.scenes.new("ols_controls_scene")
    try:
        yield scene
    finally:
        bpy.data.scenes.remove(scene)


@pytest.fixture(scope="module")
def controls():
    return extension_module("addon.controls")


def test_scene_properties_are_the_registry(addon_package, controls):
    rna = addon_package.addon.props.OLSSettings.bl_rna.properties
    inherited = {p.identifier for p in bpy.types.PropertyGroup.bl_rna.properties}     # rna_type, name
    assert {p.identifier for p in rna if p.identifier not in inherited} == {c.name for c in controls.CONTROLS}


def test_each_property_is_its_declaration(addon_package, controls):
    rna = addon_package.addon.props.OLSSettings.bl_rna.properties
    for control in controls.CONTROLS:
        prop = rna[control.name]
        assert (prop.name, prop.description) == (control.label, control.tooltip), control.name
        if control.kind == "enum":
            assert prop.default == control.default
            assert [(i.identifier, i.name, i.description) for i in prop.enum_items] == list(control.items)
        elif control.kind == "bool":
            assert prop.default == control.default
        else:
            default = list(prop.default_array) if prop.array_length else [prop.default]
            want = list(control.default) if prop.array_length else [control.default]
            assert np.allclose(default, want, rtol=1e-6), control.name
            if control.range is not None:
                assert np.allclose((prop.hard_min, prop.hard_max), control.range, rtol=1e-6), control.name


def test_docs_table_is_the_registrys(controls):
    text = (ROOT / "docs" / "controls.md").read_text()
    assert controls.replace_docs_table(text) == text, (
        "docs/controls.md's table differs from the registry: run .venv/bin/python scripts/controls_table.py")
    for control in controls.CONTROLS:
        assert f"`{control.name}`" in text


def test_the_docs_table_shows_defaults_ranges_and_changes(controls):
    table = controls.docs_table()
    assert "| Fog Visibility | `fog_visibility` | 0 m | 0 to 50000 m (slider to 5000) | re-bakes the tables |" in table
    assert "| Num Integration Steps | `num_integration_steps` | 30 | 5 to 100 | updates the compositor |" in table
    assert "| Optimize Sample Locations | `optimize_sample_locations` | on |  | none (no effect here) |" in table


def test_the_panels_media_ranges_lie_inside_the_models(controls):
    atmosphere = extension_module("lut_gen.model.atmosphere")
    for control in controls.CONTROLS:
        if control.param is None:
            continue
        low, high = control.range
        if control.param == "fog_visibility":       # 0 is no fog; the rest lies in the model's range
            assert (low, high) == (0.0, atmosphere.FOG_VISIBILITY_RANGE[1])
            continue
        if control.param in ("rayleigh_scattering", "mie_scattering"):
            continue                                # colours scale coefficients: checked by validate() below
        model_low, model_high = atmosphere.PARAMETER_RANGES[control.param]
        assert model_low <= low <= high <= model_high, control.name


def test_nan_and_values_past_a_range_clamp(scene, controls):
    settings_module = extension_module("addon.settings")
    ols = scene.ols
    for control in controls.CONTROLS:
        if control.kind not in ("int", "float") or control.range is None:
            continue
        low, high = control.range
        ols[control.name] = 10 ** 9 if control.kind == "int" else 1e30          # an ID-property write
        assert settings_module.safe_value(ols, control.name) == pytest.approx(high, rel=1e-6), control.name
        ols[control.name] = -10 ** 9 if control.kind == "int" else -1e30
        assert settings_module.safe_value(ols, control.name) == pytest.approx(low, rel=1e-6), control.name
        if control.kind == "float":
            ols[control.name] = float("nan")
            assert settings_module.safe_value(ols, control.name) == pytest.approx(control.default, rel=1e-6)
        ols.property_unset(control.name)
    # A plain object (a script's stand-in for scene.ols) clamps by the registry itself.
    plain = type("Plain", (), {"scattering_scale": math.nan, "num_cascades": 99})()
    assert settings_module.safe_value(plain, "scattering_scale") == 0.5
    assert settings_module.safe_value(plain, "num_cascades") == 8


def _extremes(controls):
    """(name, value) of every numeric control at its panel minimum and maximum (vectors: every
    channel at once), and the smallest fog the panel gives with each fog height."""
    cases = []
    for control in controls.CONTROLS:
        if not control.numeric or control.range is None:
            continue
        for end in control.range:
            value = tuple(end for _ in control.default) if control.kind in ("color", "vector") else end
            cases.append(((control.name, value),))
    fog_low = extension_module("lut_gen.model.atmosphere").FOG_VISIBILITY_RANGE[0]
    for height in controls.BY_NAME["fog_height"].range:
        cases.append((("fog_visibility", fog_low), ("fog_height", height)))
    return cases


@pytest.fixture(scope="module")
def wired(tmp_path_factory):
    """The sample scene wired to draft tables at 48 x 27, one Cycles sample; its own cache."""
    from conftest import import_extension
    cache = tmp_path_factory.mktemp("cache")
    previous = os.environ.get("OLS_CACHE_DIR")
    os.environ["OLS_CACHE_DIR"] = str(cache)
    pkg = import_extension()
    pkg.register()
    batch = extension_module("addon.batch")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    args = batch.parse_args(["--sample", "--tables", "draft", "--resolution", f"{WIDTH}x{HEIGHT}",
                             "--samples", "1", "--output", str(cache / "x.png")])
    scene = batch.prepare(args)
    batch.apply_options(scene, args)
    directory = extension_module("addon.baking").bake_if_needed(pkg.lut_gen.AtmosphereParams(), "draft")
    extension_module("addon.scene.setup.wiring").wire_scene(
        scene, directory, [o for o in scene.objects if o.select_get()], resolution="draft")
    scene.cycles.samples = 1
    scene.render.use_persistent_data = True
    yield scene, tmp_path_factory.mktemp("renders")
    pkg.unregister()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if previous is None:
        del os.environ["OLS_CACHE_DIR"]
    else:
        os.environ["OLS_CACHE_DIR"] = previous


def test_every_numeric_controls_ends_validate_and_render(wired, controls, capfd):
    """Each numeric control at its panel minimum and maximum (the others at their defaults): the
    table parameters validate, the tables bake and a frame renders, finite, with no traceback."""
    scene, renders = wired
    settings_module = extension_module("addon.settings")
    baking = extension_module("addon.baking")
    rebakes = {c.name for c in controls.CONTROLS if c.change is controls.Change.REBAKE}
    ols = scene.ols
    cases = _extremes(controls)
    assert len(cases) > 40
    for index, case in enumerate(cases):
        for name in controls.BY_NAME:
            if name != "control_set":
                ols.property_unset(name)
        if any(name in ("rayleigh_color", "mie_color") for name, _ in case):
            ols.use_custom_scattering_coeffs = True
        if any(name.startswith("cloud_") for name, _ in case):
            ols.clouds_enabled = True
        for name, value in case:
            setattr(ols, name, value)
        params = settings_module.validated_params(ols)     # raises naming the field if refused
        if any(name in rebakes for name, _ in case):            # what the background re-bake swaps in
            baking.swap_in(scene, baking.bake_if_needed(params, "draft"))
        rgb = render_rgb(scene, renders / f"case_{index}.exr", composite=True)
        assert rgb.shape == (HEIGHT, WIDTH, 3)
        assert np.isfinite(rgb).all() and (rgb >= 0).all(), case
        assert rgb.max() > 0.0, case                            # a picture, not a black frame
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-3000:]
    for name in controls.BY_NAME:
        if name != "control_set":
            ols.property_unset(name)
