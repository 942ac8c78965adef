"""Spectral media and the conversion of spectral radiance to Blender's scene-linear RGB.

The bake integrates radiance per unit extraterrestrial solar irradiance at a few wavelengths
("nodes"). Between nodes the radiance is taken as piecewise linear in wavelength (constant
beyond the end nodes), so its RGB value is a fixed linear combination of the node values:

    RGB_c = sum_k W[c, k] L(lambda_k),
    W[c, k] = int M_c(l) S(l) hat_k(l) dl / int M_c(l) S(l) dl

with M = (XYZ -> linear Rec.709) x CIE 1931 2 deg colour-matching functions, S the ASTM G-173
extraterrestrial solar spectrum and hat_k the piecewise-linear basis function of node k
(Bruneton 2017 converts its 15 precomputed wavelengths the same way). The denominator white
balances: a radiance of 1 at every wavelength, the extraterrestrial sun itself, is RGB (1, 1, 1),
so the tables keep meaning "per unit extraterrestrial sun".

Media coefficients per wavelength come from the RGB triples of AtmosphereParams (given at
680/550/440 nm): Rayleigh and Mie as the power law through the three values (exactly lambda^-4
for the default Rayleigh, flat for the default Mie), ozone from its measured cross section
times the number density of a ``ozone_column`` Dobson-unit layer with Bruneton's tent profile.
"""
from __future__ import annotations

import dataclasses
import functools
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .profiles import densities

DATA_FILE = Path(__file__).resolve().parent / "data" / "spectral_data.json"
TRIPLE_WAVELENGTHS_NM = (680.0, 550.0, 440.0)     # the sample's wavelengths, red-green-blue
DOBSON_UNIT = 2.687e20                              # molecules per m^2
OZONE_PROFILE_INTEGRAL_M = 15_000.0                 # integral of the 10-25-40 km tent of height 1
# Nodes of the bake. Chosen by measurement against the 10 nm reference conversion of the same
# spectra (README, "Spectral bake"): 12 nodes are within 0.23% median, 1.2% p99 of it.
SINGLE_NODES_NM = tuple(float(v) for v in np.linspace(400.0, 700.0, 12))
# Orders >= 2 are smooth in wavelength (no sharp extinction edge survives a second scattering
# event): fewer nodes, with single scattering interpolated onto them.
HIGHER_NODES_NM = tuple(float(v) for v in np.linspace(400.0, 700.0, 7))


@functools.lru_cache(maxsize=1)
def spectral_data() -> dict:
    """The shipped data (scripts/gen_spectral_data.py) as float64 arrays."""
    try:
        raw = json.loads(DATA_FILE.read_text())
    except (OSError, ValueError) as exc:
        raise RuntimeError(f"spectral data {DATA_FILE} is unreadable ({exc}); reinstall the add-on") from None
    return {k: np.asarray(v, dtype=np.float64) for k, v in raw.items() if k != "source"}


def rec709_sensitivities() -> np.ndarray:
    """(3, n) linear Rec.709 colour-matching functions on the data's wavelength grid."""
    data = spectral_data()
    return data["xyz_to_rec709"] @ data["cmf_xyz"].T


def rgb_weights(nodes_nm) -> np.ndarray:
    """(3, len(nodes)) W of the module docstring: spectral radiance at the nodes -> RGB."""
    data = spectral_data()
    grid = data["wavelengths_nm"]
    nodes = np.asarray(nodes_nm, dtype=np.float64)
    hats = np.stack([np.interp(grid, nodes, np.eye(len(nodes))[k]) for k in range(len(nodes))])  # (k, grid)
    weighted = rec709_sensitivities() * data["solar_etr"]                                        # (3, grid)
    return (weighted @ hats.T) / weighted.sum(axis=1, keepdims=True)


@functools.lru_cache(maxsize=4)
def _midpoint_weights(nodes_nm: tuple):
    nodes = np.asarray(nodes_nm, dtype=np.float64)
    refined = np.empty(2 * len(nodes) - 1)
    refined[0::2], refined[1::2] = nodes, 0.5 * (nodes[:-1] + nodes[1:])
    weights = rgb_weights(refined)
    return weights[:, 0::2].T.astype(np.float32), weights[:, 1::2].T.astype(np.float32)


def spectra_to_rgb(spectra: np.ndarray, nodes_nm) -> np.ndarray:
    """(..., 3) linear Rec.709 of non-negative spectra (..., C) at ``nodes_nm``, each interval's
    midpoint taken as the geometric mean of its two nodes: log-linear between nodes where
    rgb_weights is linear. At sunset a sunward spectrum falls by factors of several from node
    to node toward the blue, and linear interpolation between the 12 nodes then reads it 4%
    too bright (p99, 5% at most) against the 10 nm conversion of the same spectrum; with the
    midpoints it is within 1.7% (p99) and 2% at most, at the cost of one product and square
    root per interval."""
    at_nodes, at_midpoints = _midpoint_weights(tuple(float(v) for v in nodes_nm))
    shape = np.shape(spectra)
    # 2D, so that each product is one matrix product and not a stack of tiny ones.
    spectra = np.maximum(np.reshape(spectra, (-1, shape[-1])), np.float32(0.0))
    midpoints = spectra[:, :-1] * spectra[:, 1:]
    np.sqrt(midpoints, out=midpoints)
    rgb = spectra @ at_nodes
    rgb += midpoints @ at_midpoints
    return rgb.reshape(shape[:-1] + (3,))


def chromaticity(rgb) -> np.ndarray:
    """CIE xy of linear Rec.709 colours (..., 3)."""
    xyz = np.asarray(rgb, dtype=np.float64) @ np.linalg.inv(spectral_data()["xyz_to_rec709"]).T
    return xyz[..., :2] / np.maximum(xyz.sum(axis=-1, keepdims=True), 1e-300)


def correlated_colour_temperature(rgb) -> np.ndarray:
    """McCamy's approximation of the CCT (K) from CIE xy; good to ~2 K within 2 000-12 500 K
    and a few percent up to ~50 000 K on the Planckian locus."""
    x, y = np.moveaxis(chromaticity(rgb), -1, 0)
    n = (x - 0.3320) / (0.1858 - y)
    return 449.0 * n ** 3 + 3525.0 * n ** 2 + 6823.3 * n + 5520.33


def power_law(triple, wavelengths_nm) -> np.ndarray:
    """Values at ``wavelengths_nm`` of the power law a * lambda^-b fitted (least squares in log)
    through a (red, green, blue) triple given at 680/550/440 nm; 0 stays 0."""
    values = np.asarray(triple, dtype=np.float64)
    lam = np.asarray(wavelengths_nm, dtype=np.float64)
    if np.any(values <= 0.0):
        # No power law through a zero: fall back to linear interpolation (clamped ends).
        order = np.argsort(TRIPLE_WAVELENGTHS_NM)
        return np.interp(lam, np.asarray(TRIPLE_WAVELENGTHS_NM)[order], values[order])
    slope, intercept = np.polyfit(np.log(TRIPLE_WAVELENGTHS_NM), np.log(values), 1)
    return np.exp(intercept + slope * np.log(lam))


@dataclass(frozen=True)
class Media:
    """Coefficients per channel (1/m at unit density) for C wavelengths or RGB channels."""
    wavelengths_nm: tuple        # C wavelengths, () for the three-channel Sample 2013 media
    rayleigh: np.ndarray         # (C,) scattering = extinction
    mie: np.ndarray              # (C,) scattering, aerosol density applied
    mie_extinction: np.ndarray   # (C,)
    ozone: np.ndarray            # (C,) absorption at the tent's peak (0 without ozone)
    to_rgb: np.ndarray           # (3, C) channel values -> linear Rec.709
    fog: np.ndarray = None       # (C,) fog scattering = extinction at the ground (grey; 0 without fog)

    def __post_init__(self):
        if self.fog is None:
            object.__setattr__(self, "fog", np.zeros_like(self.rayleigh))

    @property
    def channels(self) -> int:
        return len(self.rayleigh)

    @property
    def has_fog(self) -> bool:
        return bool(np.any(self.fog > 0.0))

    def extinction_matrix(self) -> np.ndarray:
        """(4 media, C): optical depth = net densities (Rayleigh, Mie, ozone, fog) @ this."""
        return np.stack([self.rayleigh, self.mie_extinction, self.ozone, self.fog])


def ozone_peak_absorption(params, wavelengths_nm) -> np.ndarray:
    """Ozone absorption (1/m) at the tent's peak density for a column of params.ozone_column DU."""
    data = spectral_data()
    density = params.ozone_column * DOBSON_UNIT / OZONE_PROFILE_INTEGRAL_M
    cross = np.interp(wavelengths_nm, data["wavelengths_nm"], data["ozone_cross_section"])
    return density * cross * (1.0 if params.ozone else 0.0)


def media_at(params, wavelengths_nm) -> Media:
    """Spectral media of ``params`` at the given wavelengths, converted with rgb_weights."""
    lam = np.asarray(wavelengths_nm, dtype=np.float64)
    mie = power_law(params.mie_scattering, lam) * params.aerosol_density
    return Media(tuple(float(v) for v in lam), power_law(params.rayleigh_scattering, lam), mie,
                 mie * (1.0 + params.aerosol_absorption), ozone_peak_absorption(params, lam), rgb_weights(lam),
                 np.full(len(lam), params.fog))


def triple_media(params) -> Media:
    """The Sample 2013 media: three wavelengths used directly as red, green and blue."""
    mie = np.asarray(params.mie_scattering, dtype=np.float64) * params.aerosol_density
    ozone = np.asarray(params.ozone_absorption, dtype=np.float64) * (1.0 if params.ozone else 0.0)
    return Media((), np.asarray(params.rayleigh_scattering, dtype=np.float64), mie,
                 mie * (1.0 + params.aerosol_absorption), ozone, np.eye(3), np.full(3, params.fog))


def bake_media(params, which: str = "single") -> Media:
    """Media the bake integrates: spectral nodes, or the triples for Sample 2013 params."""
    if not params.spectral:
        return triple_media(params)
    return media_at(params, SINGLE_NODES_NM if which == "single" else HIGHER_NODES_NM)


def reference_media(params) -> Media:
    """Every wavelength of the data grid (5 nm): the conversion the bake is checked against."""
    if not params.spectral:
        return triple_media(params)
    return media_at(params, spectral_data()["wavelengths_nm"])


# -- RGB coefficients for the run-time node groups ------------------------------------------

def _fit_paths(params):
    """Net densities (Rayleigh, Mie, ozone, fog) of sun paths a scene meets: from 0-30 km up, from
    the zenith to just past the horizon."""
    heights = np.array([0.0, 200.0, 1000.0, 3000.0, 8000.0, 15000.0, 30000.0])
    angles = np.radians(np.concatenate([np.linspace(0.0, 85.0, 18), np.linspace(86.0, 95.0, 19)]))
    h, mu = np.meshgrid(heights, np.cos(angles), indexing="ij")
    r = params.earth_radius + h.ravel()
    mu = mu.ravel()
    top = params.earth_radius + params.atmosphere_height
    disc = r * r * (mu * mu - 1.0) + top * top
    length = -r * mu + np.sqrt(np.maximum(disc, 0.0))
    ground = r * r * (mu * mu - 1.0) + params.earth_radius ** 2
    clear = ~((mu < 0) & (ground >= 0))
    u = np.linspace(0.0, 1.0, 4001)
    s = length[:, None] * u ** 2
    ds = np.gradient(s, axis=1)
    alt = np.sqrt(r[:, None] ** 2 + s * s + 2 * r[:, None] * mu[:, None] * s) - params.earth_radius
    net = np.einsum("pkm,pk->pm", densities(params, alt), ds)
    return net[clear]


def _transmittance_rgb(media: Media, net):
    """Without the fog, whose grey extinction needs no fit."""
    return np.exp(-net[:, :3] @ media.extinction_matrix()[:3]) @ media.to_rgb.T


@functools.lru_cache(maxsize=16)
def rgb_coefficients(params):
    """(Rayleigh scattering RGB, Mie scattering RGB, 3x3 extinction matrix) for node groups
    that work in RGB: scattering is the white-balanced spectral mean (exact for thin media);
    the extinction rows are fitted so that exp(-net @ matrix) matches the RGB of the spectral
    transmittance over the sun paths of _fit_paths (log-space least squares weighted by the
    transmittance, so deep twilight paths count little)."""
    media = reference_media(params)
    rayleigh, mie = media.to_rgb @ media.rayleigh, media.to_rgb @ media.mie
    net = _fit_paths(params)
    target = _transmittance_rgb(media, net)
    matrix = np.zeros((3, 3))
    # Mie extinction is (nearly) grey: its white-balanced mean is kept, which also keeps the
    # fit of the other two rows from trading against it along paths where both grow together.
    matrix[1] = media.to_rgb @ media.mie_extinction
    fitted = [m for m in (0, 2) if media.extinction_matrix()[m].max() > 0]
    for c in range(3):
        keep = target[:, c] > 1e-4
        w = target[keep, c]
        rhs = (-np.log(target[keep, c]) - net[keep, 1] * matrix[1, c]) * w
        solution, *_ = np.linalg.lstsq(net[keep][:, fitted] * w[:, None], rhs, rcond=None)
        matrix[fitted, c] = np.maximum(solution, 0.0)
    return tuple(rayleigh), tuple(mie), matrix


def triple_params(params, wavelengths_nm):
    """Sample-2013-style params whose three channels are the spectral media of ``params`` at
    three wavelengths: lets three-channel code (the brute-force reference) run per wavelength."""
    lam = np.asarray(wavelengths_nm, dtype=np.float64)
    ozone = ozone_peak_absorption(params, lam)
    return dataclasses.replace(params, spectral=False,
                               rayleigh_scattering=tuple(power_law(params.rayleigh_scattering, lam)),
                               mie_scattering=tuple(power_law(params.mie_scattering, lam)),
                               ozone_absorption=tuple(ozone) if params.ozone else params.ozone_absorption)


def spectral_resample_matrix(source: Media, target: Media) -> np.ndarray:
    """(C_target, C_source): radiance at the target's wavelengths, linear in wavelength between
    the source's (the identity for equal or three-channel media)."""
    if source.wavelengths_nm == target.wavelengths_nm or not source.wavelengths_nm:
        return np.eye(source.channels)
    src = np.asarray(source.wavelengths_nm)
    return np.stack([np.interp(target.wavelengths_nm, src, row) for row in np.eye(len(src))], axis=1)
