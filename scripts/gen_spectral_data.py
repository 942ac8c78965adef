"""Regenerate lut_gen/model/data/spectral_data.json, the spectral data the bake ships with.

Development only (the extension itself stays numpy-only). colour-science needs numpy >= 2 and
bpy 5.0.1 pins numpy < 2, so run it from a separate virtualenv:

    python3.11 -m venv /tmp/colour-venv
    /tmp/colour-venv/bin/pip install colour-science==0.4.7
    /tmp/colour-venv/bin/python scripts/gen_spectral_data.py

Contents, on a 5 nm grid from 360 to 830 nm:
  cmf_xyz          CIE 1931 2 degree colour-matching functions (colour.MSDS_CMFS)
  solar_etr        ASTM G-173 extraterrestrial irradiance (W m^-2 nm^-1), averaged over each
                   5 nm bin centred on the wavelength (the raw table is 0.5-1 nm)
  ozone_cross_section  ozone absorption cross section (m^2) at 233 K, Serdyuchenko et al. 2014
                   (IUP Bremen), 10 nm bin averages as published in Bruneton's
                   precomputed_atmospheric_scattering (atmosphere/demo/demo.cc), linearly
                   interpolated onto the 5 nm grid. colour-science has no ozone data.
  xyz_to_rec709    XYZ -> linear ITU-R BT.709 (Blender's scene-linear), D65 white
"""
import json
from pathlib import Path

import numpy as np
import colour
from colour.plotting.datasets.astm_g_173 import SD_ASTMG173_ETR

OUT = Path(__file__).resolve().parent.parent / "lut_gen" / "model" / "data" / "spectral_data.json"
WAVELENGTHS = np.arange(360, 831, 5)

# Bruneton's kOzoneCrossSection, 360..830 nm in 10 nm steps (m^2 per molecule).
OZONE_10NM = [
    1.18e-27, 2.182e-28, 2.818e-28, 6.636e-28, 1.527e-27, 2.763e-27, 5.52e-27,
    8.451e-27, 1.582e-26, 2.316e-26, 3.669e-26, 4.924e-26, 7.752e-26, 9.016e-26,
    1.48e-25, 1.602e-25, 2.139e-25, 2.755e-25, 3.091e-25, 3.5e-25, 4.266e-25,
    4.672e-25, 4.398e-25, 4.701e-25, 5.019e-25, 4.305e-25, 3.74e-25, 3.215e-25,
    2.662e-25, 2.238e-25, 1.852e-25, 1.473e-25, 1.209e-25, 9.423e-26, 7.455e-26,
    6.566e-26, 5.105e-26, 4.15e-26, 4.228e-26, 3.237e-26, 2.451e-26, 2.801e-26,
    2.534e-26, 1.624e-26, 1.465e-26, 2.078e-26, 1.383e-26, 7.105e-27,
]


def bin_average(sd, centres, width):
    fine = np.arange(centres[0] - width / 2, centres[-1] + width / 2 + 1e-9, 0.5)
    values = sd[np.clip(fine, sd.shape.start, sd.shape.end)]
    return np.array([values[(fine >= c - width / 2) & (fine < c + width / 2)].mean() for c in centres])


def main():
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    cmf = cmfs[WAVELENGTHS]
    solar = bin_average(SD_ASTMG173_ETR, WAVELENGTHS, 5.0)
    ozone = np.interp(WAVELENGTHS, np.arange(360, 831, 10), OZONE_10NM)
    rec709 = colour.RGB_COLOURSPACES["ITU-R BT.709"]
    data = {
        "source": "scripts/gen_spectral_data.py with colour-science " + colour.__version__,
        "wavelengths_nm": WAVELENGTHS.tolist(),
        "cmf_xyz": np.round(cmf, 8).tolist(),
        "solar_etr": np.round(solar, 6).tolist(),
        "ozone_cross_section": [float(f"{v:.5g}") for v in ozone],
        "xyz_to_rec709": np.round(rec709.matrix_XYZ_to_RGB, 10).tolist(),
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
