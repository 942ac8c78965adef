"""addon/settings.py without registering the add-on: plain objects stand in for scene.ols and its
RNA, so the clamping, the render-size caps and the parameter mapping are checked on their own."""
import math
from types import SimpleNamespace

import pytest

from extension import extension_module

pytest.importorskip("bpy")          # importing the add-on package needs bpy; nothing is registered


def fake_settings(values: dict, ranges: dict, render=None):
    """An object with the attributes settings.py reads: values, bl_rna.properties, id_data."""
    props = {name: SimpleNamespace(type="INT" if isinstance(default, int) else "FLOAT", default=default,
                                   hard_min=low, hard_max=high, array_length=0)
             for name, (default, low, high) in ranges.items()}
    settings = SimpleNamespace(**values, bl_rna=SimpleNamespace(properties=props),
                               id_data=SimpleNamespace(render=render))
    return settings


def test_safe_value_clamps_and_replaces_non_finite_numbers():
    settings_module = extension_module("addon.settings")
    ranges = {"scattering_scale": (0.5, 0.0, 10.0), "num_integration_steps": (30, 1, 512)}
    fake = fake_settings({"scattering_scale": math.nan, "num_integration_steps": 10 ** 9}, ranges)
    assert settings_module.safe_value(fake, "scattering_scale") == 0.5
    assert settings_module.safe_value(fake, "num_integration_steps") == 512
    fake.scattering_scale = -3.0
    assert settings_module.safe_value(fake, "scattering_scale") == 0.0
    fake.scattering_scale = 2.25
    assert settings_module.safe_value(fake, "scattering_scale") == 2.25


def test_sanitized_caps_the_epipolar_grid_by_the_render_size():
    settings_module = extension_module("addon.settings")
    ranges = {"epipolar_slices": (512, 32, 2048), "samples_per_slice": (256, 32, 2048)}
    values = {"epipolar_slices": 2048, "samples_per_slice": 2048}
    small = settings_module.Sanitized(fake_settings(values, ranges, SimpleNamespace(
        resolution_x=64, resolution_y=36, resolution_percentage=100)))
    large = settings_module.Sanitized(fake_settings(values, ranges, SimpleNamespace(
        resolution_x=1920, resolution_y=1080, resolution_percentage=100)))
    assert small.epipolar_slices < 2048 and small.samples_per_slice < 2048
    assert large.epipolar_slices == 2048 and large.samples_per_slice == 2048


def test_atmosphere_params_of_the_default_controls_are_the_default_tables():
    settings_module = extension_module("addon.settings")
    lut_gen = extension_module("lut_gen")
    defaults = SimpleNamespace(atmosphere_preset="CLEAR_SKY", use_custom_scattering_coeffs=False,
                               rayleigh_color=settings_module.DEFAULT_RAYLEIGH_COLOR,
                               mie_color=settings_module.DEFAULT_MIE_COLOR, aerosol_density=1.0,
                               aerosol_absorption=0.1, ground_albedo=0.2, ozone_column=300.0,
                               fog_visibility=0.0, fog_height=50.0)
    assert settings_module.atmosphere_params(defaults) == lut_gen.AtmosphereParams()
    foggy = settings_module.atmosphere_params(SimpleNamespace(**{**vars(defaults), "fog_visibility": 300.0}))
    assert foggy == lut_gen.AtmosphereParams(fog_visibility=300.0, fog_height=50.0)
    hazy = settings_module.atmosphere_params(SimpleNamespace(**{**vars(defaults), "aerosol_density": 3.0}))
    assert hazy.aerosol_density == 3.0 and hazy != lut_gen.AtmosphereParams()
