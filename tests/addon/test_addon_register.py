"""The add-on registers and unregisters cleanly; scene.ols holds the sample's GUI controls.

Runs under bpy (Blender as a Python module); skipped without it. ``addon_package`` (conftest)
imports the repo root as the extension package and registers it for each test.
"""
import sys

import pytest

bpy = pytest.importorskip("bpy")

pytestmark = pytest.mark.bpy


def _ols_types():
    return [name for name in dir(bpy.types) if name.startswith("OLS")]


def _package_classes(pkg):
    """Every class the add-on registers (PropertyGroups do not show up in bpy.types)."""
    classes = [*pkg.addon.props.CLASSES, *pkg.addon.ui.CLASSES]
    ops = sys.modules.get(pkg.__name__ + ".addon.ops")
    if ops is not None:
        classes += list(getattr(ops, "CLASSES", ()))
    return classes


def _package_handlers(package_name):
    """(list name, function) of every app handler defined in the package."""
    found = []
    for list_name in dir(bpy.app.handlers):
        handlers = getattr(bpy.app.handlers, list_name)
        if not isinstance(handlers, list):
            continue
        for fn in handlers:
            module = getattr(fn, "__module__", "") or ""
            if module == package_name or module.startswith(package_name + "."):
                found.append((list_name, fn))
    return found


@pytest.fixture
def scene(addon_package):
    """A fresh scene (fresh defaults), removed after the test."""
    scene = bpy.data.scenes.new("ols_test_scene")
    try:
        yield scene
    finally:
        bpy.data.scenes.remove(scene)


def test_register_unregister_50_times(addon_package):
    name = addon_package.__name__
    for _ in range(50):
        addon_package.unregister()
        assert not hasattr(bpy.types.Scene, "ols")
        assert not hasattr(bpy.types, "OLS_PT_atmosphere")
        assert "ols" not in bpy.types.Scene.bl_rna.properties
        assert _ols_types() == []
        assert [cls for cls in _package_classes(addon_package) if cls.is_registered] == []
        assert _package_handlers(name) == []
        node_groups = len(bpy.data.node_groups)

        addon_package.register()
        assert hasattr(bpy.types.Scene, "ols")
        assert hasattr(bpy.types, "OLS_PT_atmosphere")
        assert bpy.context.scene.ols.control_set == "BASIC"
        assert all(cls.is_registered for cls in _package_classes(addon_package))
        assert len(bpy.data.node_groups) == node_groups


def test_register_twice_is_harmless(addon_package):
    addon_package.register()  # already registered by the fixture
    assert hasattr(bpy.types, "OLS_PT_atmosphere")
    addon_package.unregister()
    assert _ols_types() == []
    assert not hasattr(bpy.types.Scene, "ols")
    addon_package.unregister()  # nothing left to undo
    addon_package.register()    # the fixture unregisters


def test_every_control_is_a_property(addon_package):
    props, settings = addon_package.addon.props, addon_package.addon.settings
    rna = props.OLSSettings.bl_rna.properties
    names = [name for names in settings.PROPERTIES_BY_SET.values() for name in names]
    assert len(names) == len(set(names))
    for name in ["control_set", *names]:
        assert name in rna, name
    assert set(settings.PROPERTIES_BY_SET) == {"BASIC", "ADDITIONAL", "TONE_MAPPING", "CLOUDS"}
    assert [item.identifier for item in rna["control_set"].enum_items] == [
        "BASIC", "ADDITIONAL", "TONE_MAPPING", "CLOUDS"]
    assert set(settings.WITHOUT_EFFECT) <= set(names)
    assert set(names) - set(settings.WITHOUT_EFFECT) == {
        "scattering_scale", "use_custom_scattering_coeffs", "rayleigh_color", "mie_color",
        "air_preset", "atmosphere_model", "aerosol_density", "aerosol_absorption", "atmosphere_preset", "ground_albedo",
        "ozone_column", "fog_visibility", "fog_height", "animate_sun",
        "day_start_frame", "day_end_frame",
        "middle_gray", "white_point", "luminance_saturation", "auto_exposure", "tone_mapping_operator",
        "light_adaptation", "tone_map_exr", "enable_light_scattering", "lighting_only", "enable_light_shafts",
        "shadow_map_resolution", "num_integration_steps", "jitter_steps", "single_scattering_mode", "multiple_scattering_mode",
        "num_cascades", "show_cascades", "smooth_shadows", "best_cascade_search", "cascade_partitioning_factor",
        "first_cascade_to_ray_march", "scattering_technique", "epipolar_slices", "samples_per_slice",
        "initial_sample_step", "epipole_sampling_density", "refinement_threshold", "show_sampling",
        "use_min_max_optimization", "clouds_enabled", "cloud_preset", "cloud_coverage", "cloud_base", "cloud_thickness",
        "cloud_density", "cloud_scale", "cloud_seed", "cloud_offset"}
    notes = set(settings.WITHOUT_EFFECT.values())
    for name in names:
        description = rna[name].description
        assert description, name
        assert any(note in description for note in notes) == (name in settings.WITHOUT_EFFECT), name
    # Windowing-only controls are left out.
    assert "full_screen" not in rna and "vsync" not in rna


def test_defaults_and_ranges(scene, addon_package):
    ols = scene.ols
    assert ols.control_set == "BASIC"
    assert ols.enable_light_scattering is True and ols.enable_light_shafts is True
    assert ols.scattering_technique == "EPIPOLAR_SAMPLING"
    assert ols.shadow_map_resolution == "1024"
    assert (ols.num_integration_steps, ols.epipolar_slices, ols.samples_per_slice) == (30, 512, 256)
    assert (ols.initial_sample_step, ols.epipole_sampling_density) == (16, 2)
    assert ols.refinement_threshold == pytest.approx(0.03)
    assert ols.scattering_scale == pytest.approx(0.5)
    assert ols.show_sampling is False and ols.correct_depth_breaks is False
    assert ols.single_scattering_mode == "LUT"
    assert ols.multiple_scattering_mode == "UNOCCLUDED"
    assert (ols.num_cascades, ols.first_cascade_to_ray_march) == (6, 2)
    assert ols.cascade_partitioning_factor == pytest.approx(0.95)
    assert ols.extinction_evaluation_mode == "EPIPOLAR"
    assert ols.refinement_criterion == "INSCATTERING"
    assert ols.use_custom_scattering_coeffs is False
    assert tuple(ols.rayleigh_color) == pytest.approx((0.1753, 0.4096, 1.0), abs=1e-3)
    assert tuple(ols.mie_color) == (1.0, 1.0, 1.0)
    assert ols.aerosol_density == pytest.approx(1.0)
    assert ols.aerosol_absorption == pytest.approx(0.1)
    assert ols.atmosphere_preset == "CLEAR_SKY"
    assert ols.ground_albedo == pytest.approx(0.2) and ols.ozone_column == pytest.approx(300.0)
    assert ols.middle_gray == pytest.approx(0.18)
    assert ols.white_point == pytest.approx(3.0)
    assert ols.luminance_saturation == pytest.approx(1.0)
    assert ols.auto_exposure is True and ols.light_adaptation is True
    assert ols.tone_mapping_operator == "UNCHARTED2"
    rna = ols.bl_rna.properties
    assert [i.identifier for i in rna["tone_mapping_operator"].enum_items] == [
        "EXP", "REINHARD", "REINHARD_MOD", "UNCHARTED2", "FILMIC_ALU", "LOGARITHMIC", "ADAPTIVE_LOG",
        "BLENDER_VIEW"]
    assert [i.identifier for i in rna["shadow_map_resolution"].enum_items] == [
        "512", "1024", "2048", "4096"]
    ranges = {"num_integration_steps": (5, 100), "epipolar_slices": (32, 2048),
              "samples_per_slice": (32, 2048), "initial_sample_step": (2, 64),
              "epipole_sampling_density": (1, 32), "num_cascades": (1, 8),
              "first_cascade_to_ray_march": (0, 7)}
    for name, (lo, hi) in ranges.items():
        assert (rna[name].hard_min, rna[name].hard_max) == (lo, hi), name
    floats = {"refinement_threshold": (0.001, 0.5), "cascade_partitioning_factor": (0.0, 1.0),
              "aerosol_density": (0.1, 5.0), "aerosol_absorption": (0.0, 5.0),
              "ground_albedo": (0.0, 1.0), "ozone_column": (0.0, 600.0),
              "middle_gray": (0.01, 1.0), "white_point": (0.01, 10.0),
              "luminance_saturation": (0.1, 2.0)}
    for name, (lo, hi) in floats.items():
        assert (rna[name].hard_min, rna[name].hard_max) == pytest.approx((lo, hi)), name
    assert rna["scattering_scale"].hard_min == 0.0 and rna["scattering_scale"].soft_max == 2.0
    # Clamped to the sample's ranges.
    ols.epipolar_slices = 10_000
    assert ols.epipolar_slices == 2048
    ols.num_cascades = 0
    assert ols.num_cascades == 1


def test_atmosphere_params(scene, addon_package):
    settings = addon_package.addon.settings
    lut_gen = addon_package.lut_gen
    ols = scene.ols
    default = lut_gen.AtmosphereParams()
    assert settings.atmosphere_params(ols) == default

    # Custom coefficients left at their default colours reproduce the defaults exactly
    # (so the bake cache key does not change).
    ols.use_custom_scattering_coeffs = True
    assert settings.atmosphere_params(ols) == default

    ols.rayleigh_color = (1.0, 1.0, 1.0)
    ols.mie_color = (0.5, 1.0, 0.25)
    params = settings.atmosphere_params(ols)
    blue = max(default.rayleigh_scattering)
    assert params.rayleigh_scattering == pytest.approx((blue, blue, blue), rel=1e-12)
    m = default.mie_scattering
    assert params.mie_scattering == pytest.approx((0.5 * m[0], m[1], 0.25 * m[2]), rel=1e-6)
    assert params.aerosol_density == 1.0 and params.aerosol_absorption == 0.1
    params.validate()

    # The colours only count with custom coefficients on.
    ols.use_custom_scattering_coeffs = False
    assert settings.atmosphere_params(ols) == default

    # Aerosol values map to the decimals typed, not their float32 storage.
    ols.aerosol_density = 2.3
    ols.aerosol_absorption = 0.3
    params = settings.atmosphere_params(ols)
    assert params == lut_gen.AtmosphereParams(aerosol_density=2.3, aerosol_absorption=0.3)

    # Ground albedo and ozone reach the tables; the Sample 2013 preset is the sample's media.
    ols.ground_albedo = 0.35
    ols.ozone_column = 0.0
    params = settings.atmosphere_params(ols)
    assert params.ground_albedo == 0.35 and params.ozone is False and params.spectral
    ols.atmosphere_preset = "SAMPLE_2013"
    params = settings.atmosphere_params(ols)
    assert params == lut_gen.preset("sample-2013", aerosol_density=2.3, aerosol_absorption=0.3)
    assert params.mie_scattering == (2e-5, 2e-5, 2e-5) and params.mie_g == 0.76


# -- panel ----------------------------------------------------------------------------------

class _FakeLayout:
    """Records what a draw function puts into a layout (UILayout cannot be built headless)."""

    def __init__(self, log, active=True, enabled=True):
        self.log = log
        self.active = active
        self.enabled = enabled
        self.use_property_split = False
        self.use_property_decorate = True

    def _child(self, *args, **kwargs):
        return _ChildLayout(self)

    column = row = box = split = _child

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, name
        self.log.append(("prop", name, self._active(), self._enabled()))

    def operator(self, idname, **kwargs):
        self.log.append(("operator", idname, self._active(), self._enabled()))

    def label(self, **kwargs):
        self.log.append(("label", kwargs.get("text", ""), self._active(), self._enabled()))

    def separator(self, **kwargs):
        pass

    def _active(self):
        return self.active

    def _enabled(self):
        return self.enabled


class _ChildLayout(_FakeLayout):
    def __init__(self, parent):
        super().__init__(parent.log)
        self.parent = parent

    def _active(self):
        return self.active and self.parent._active()

    def _enabled(self):
        return self.enabled and self.parent._enabled()


def _draw(panel_cls, scene):
    log = []
    fake = type("FakePanel", (), {})()
    fake.layout = _FakeLayout(log)
    context = type("FakeContext", (), {"scene": scene})()
    assert panel_cls.poll(context)
    panel_cls.draw(fake, context)
    return log


def test_panel(scene, addon_package):
    settings = addon_package.addon.settings
    panel = bpy.types.OLS_PT_atmosphere
    assert panel.bl_space_type == "VIEW_3D" and panel.bl_region_type == "UI"
    assert panel.bl_category == "Atmosphere"
    assert callable(panel.poll)
    for control_set, names in settings.PROPERTIES_BY_SET.items():
        scene.ols.control_set = control_set
        log = _draw(panel, scene)
        drawn = [entry for entry in log if entry[0] == "prop"]
        assert drawn[0] == ("prop", "control_set", True, True)  # the top drop-down
        assert [entry[1] for entry in drawn[1:]] == names
        for _, name, active, enabled in drawn[1:]:
            assert active == (name not in settings.WITHOUT_EFFECT), name
            if name in ("rayleigh_color", "mie_color", "day_start_frame", "day_end_frame", "jitter_steps",
                        "fog_height") or name.startswith("cloud_"):
                # custom coefficients, Animate Sun, fog and clouds are off by default; jitter is
                # brute force's, and the default technique is epipolar sampling
                assert enabled is False
            else:
                assert enabled is True, name
        notes = [e for e in log if e[0] == "label" and "tooltips say why" in e[1]]
        assert bool(notes) == any(name in settings.WITHOUT_EFFECT for name in names)
        buttons = [e[1] for e in log if e[0] == "operator"]
        for idname in ("ols.setup_scene", "ols.bake_luts", "ols.render"):
            module, op = idname.split(".")
            assert (idname in buttons) == hasattr(bpy.types, f"OLS_OT_{op}")

    scene.ols.control_set = "ADDITIONAL"
    scene.ols.use_custom_scattering_coeffs = True
    log = _draw(panel, scene)
    colours = [e for e in log if e[0] == "prop" and e[1] in ("rayleigh_color", "mie_color")]
    assert [e[3] for e in colours] == [True, True]
    # The Sample 2013 preset has no ground and no ozone: their rows are disabled.
    scene.ols.atmosphere_preset = "SAMPLE_2013"
    log = _draw(panel, scene)
    spectral_only = [e for e in log if e[0] == "prop" and e[1] in ("ground_albedo", "ozone_column")]
    assert [e[3] for e in spectral_only] == [False, False]


def test_panel_poll_without_scene(addon_package):
    context = type("FakeContext", (), {"scene": None})()
    assert not bpy.types.OLS_PT_atmosphere.poll(context)


def test_failed_register_rolls_back(addon_package, monkeypatch):
    ui = addon_package.addon.ui

    class OLS_PT_broken(bpy.types.Panel):
        bl_label = "Broken"
        bl_space_type = "NOT_A_SPACE"
        bl_region_type = "UI"

        def draw(self, context):
            pass

    addon_package.unregister()
    monkeypatch.setattr(ui, "CLASSES", (*ui.CLASSES, OLS_PT_broken))
    with pytest.raises(Exception):
        addon_package.register()
    assert "ols" not in bpy.types.Scene.bl_rna.properties
    assert [cls for cls in _package_classes(addon_package) if cls.is_registered] == []
    assert _package_handlers(addon_package.__name__) == []
    monkeypatch.undo()
    addon_package.register()  # the fixture unregisters
    assert bpy.context.scene.ols.control_set == "BASIC"


def test_register_adds_the_operators_and_every_handler_and_unregister_removes_them(addon_package):
    """handlers.HANDLERS are all in Blender's handler lists after register, once each, and none
    after unregister; the operators likewise."""
    handlers, ops = addon_package.addon.handlers, addon_package.addon.ops
    for _ in range(2):
        for event, function in handlers.HANDLERS:
            assert event.count(function) == 1, function.__name__
        assert all(cls.is_registered for cls in ops.CLASSES)
        addon_package.unregister()
        assert all(function not in event for event, function in handlers.HANDLERS)
        assert not any(cls.is_registered for cls in ops.CLASSES)
        assert _package_handlers(addon_package.__name__) == []
        addon_package.register()
