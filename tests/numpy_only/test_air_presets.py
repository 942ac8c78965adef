"""Air presets (lut_gen.model.air_presets): a day's haze by its aerosol optical depth at 550 nm,
checked against the tables' own vertical transmittance at that wavelength."""
import dataclasses
import math

import numpy as np
import pytest

import lut_gen
from lut_gen.model import air_presets, spectrum


@pytest.mark.parametrize("name, depth", sorted(air_presets.AIR_PRESETS.items()))
def test_each_preset_has_its_aerosol_optical_depth(name, depth):
    params = dataclasses.replace(lut_gen.AtmosphereParams(), aerosol_density=air_presets.preset_density(name))
    assert math.isclose(air_presets.aerosol_optical_depth(params), depth, rel_tol=1e-9)
    # Independently: the aerosol's part of the optical depth of the table's vertical column, at
    # 550 nm (the optical-depth table holds the net densities to the top).
    triple = spectrum.triple_params(params, (550.0, 550.0, 550.0))
    luts = lut_gen.bake(triple, resolution=(4, 8, 4, 2), orders=1)
    mie_net = float(luts.net_density_to_top(0.0, np.array(1.0))[1])
    assert math.isclose(mie_net * triple.mie_extinction[1], depth, rel_tol=0.01), (mie_net, depth)


def test_hazy_is_hazier_than_clean():
    clean, hazy = (air_presets.preset_density(name) for name in ("clean-mountain-air", "hazy-summer-day"))
    assert clean < 1.0 < hazy          # the clear sky's aerosol sits between (0.11)


def test_an_unknown_preset_is_named():
    with pytest.raises(ValueError, match="unknown air preset 'fog'; choose one of hazy-summer-day, clean-mountain-air, light-haze, heavy-haze"):
        air_presets.preset_density("fog")
