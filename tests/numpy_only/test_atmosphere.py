"""AtmosphereParams defaults (docs/lut_gen.md: Parameters), validation and phase functions."""
import math

import numpy as np
import pytest

from lut_gen import AtmosphereParams
from lut_gen.model.atmosphere import PRESETS, mie_phase, preset, rayleigh_phase
from lut_gen.model.profiles import densities, ozone_density

SAMPLE = preset("sample-2013")


def test_sample_preset_is_the_samples_media():
    p = SAMPLE
    assert p.earth_radius == 6_360_000 and p.atmosphere_height == 80_000
    np.testing.assert_allclose(p.rayleigh_scattering, (5.80e-6, 13.56e-6, 33.11e-6), rtol=2e-3)
    np.testing.assert_allclose(p.rayleigh, p.rayleigh_scattering)
    assert p.rayleigh_scale_height == 7994 and p.mie_scale_height == 1200
    np.testing.assert_allclose(p.mie, 2e-5)
    np.testing.assert_allclose(p.mie_extinction, 2e-5 * 1.1)
    assert p.mie_g == 0.76 and p.ozone is False and p.spectral is False and p.ground_albedo == 0.0
    np.testing.assert_array_equal(p.ozone_extinction, 0.0)


def test_defaults_are_spectral_with_ozone_and_ground():
    p = AtmosphereParams()
    assert p.spectral and p.ozone and p.ozone_column == 300.0 and 0.1 <= p.ground_albedo <= 0.3
    assert p == preset("clear-sky")
    # RGB coefficients of the spectral media: the clear day's aerosol (optical depth 0.1 at
    # 550 nm, Angstrom 1.3) stays bluish, Rayleigh stays blue-heavy,
    # ozone (Chappuis band, 500-700 nm) takes red and green, hardly blue.
    assert p.mie[2] > p.mie[1] > p.mie[0]
    assert p.mie[1] * p.mie_scale_height == pytest.approx(0.1, rel=0.02)
    np.testing.assert_allclose(p.mie_extinction, 1.1 * p.mie, rtol=1e-9)
    assert p.rayleigh[2] > 2 * p.rayleigh[1] > 2 * p.rayleigh[0]
    assert p.ozone_extinction[0] > 1e-6 and p.ozone_extinction[1] > 1e-6 and p.ozone_extinction[2] < 2e-7


def test_unknown_preset_is_refused_with_the_choices():
    with pytest.raises(ValueError, match="unknown preset 'sample-2012'.*clear-sky, sample-2013"):
        preset("sample-2012")
    assert set(PRESETS) == {"clear-sky", "sample-2013"}


def test_aerosol_density_and_absorption_scale_mie():
    p = preset("sample-2013", aerosol_density=2.0, aerosol_absorption=0.3)
    np.testing.assert_allclose(p.mie, 4e-5)
    np.testing.assert_allclose(p.mie_extinction, 4e-5 * 1.3)


@pytest.mark.parametrize("field, value", [
    ("aerosol_density", -1.0), ("aerosol_absorption", float("nan")), ("earth_radius", 0.0),
    ("mie_g", 1.0), ("mie_scale_height", float("inf")), ("rayleigh_scattering", (1e-6, -1e-6, 1e-6)),
    ("mie_scattering", (1e-6, 1e-6)), ("atmosphere_height", "80 km"), ("ozone", 1),
    ("ground_albedo", -0.1), ("ground_albedo", float("nan")), ("ground_albedo", 1.5),
    ("ozone_column", -300.0), ("ozone_column", float("nan")), ("spectral", "yes"),
])
def test_validate_names_the_bad_field(field, value):
    with pytest.raises(ValueError, match=field.split(".")[0]):
        AtmosphereParams(**{field: value}).validate()


def test_dict_round_trip_and_unknown_keys():
    p = AtmosphereParams(ozone=True, aerosol_density=1.5)
    assert AtmosphereParams.from_dict(p.to_dict()) == p
    with pytest.raises(ValueError, match="unknown"):
        AtmosphereParams.from_dict({"haze": 1})


@pytest.mark.parametrize("phase", [rayleigh_phase, lambda c: mie_phase(c, 0.76), lambda c: mie_phase(c, -0.3)])
def test_phase_functions_integrate_to_one(phase):
    c, w = np.polynomial.legendre.leggauss(400)
    assert 2 * math.pi * np.sum(phase(c) * w) == pytest.approx(1.0, rel=1e-6)


def test_mie_phase_peaks_forward():
    assert mie_phase(1.0, 0.76) > 10 * mie_phase(0.0, 0.76)


def test_density_profiles():
    p = AtmosphereParams()
    d = densities(p, np.array([0.0, 7994.0, 25_000.0]))
    np.testing.assert_allclose(d[:, 0], [1, math.exp(-1), math.exp(-25_000 / 7994)])
    np.testing.assert_allclose(ozone_density(p, [5_000, 10_000, 17_500, 25_000, 40_000]), [0, 0, 0.5, 1, 0])
