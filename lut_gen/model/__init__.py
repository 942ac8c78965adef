"""The media the light crosses: atmosphere parameters and presets, density profiles, spectra,
the Earth's geometry and the sun's disc. Imports nothing else of lut_gen."""
from . import analytic, atmosphere, geometry, profiles, spectrum, sun_disc  # noqa: F401
