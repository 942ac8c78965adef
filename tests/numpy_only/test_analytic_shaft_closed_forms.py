"""Light shafts under the analytic model (lut_gen.passes.analytic_shafts): the closed forms of
every mode against a brute-force march of the same constant-density medium through the same
shadows (quadrature of E_sun beta_sc exp(-beta t) lit(t) over a fine grid, not
Hoffman & Preetham Eq. 4), the epipolar INTEGRATION table against the same, and no occluder =
the analytic aerial perspective."""
import math

import numpy as np
import pytest

import lut_gen
from lut_gen.model import analytic
from lut_gen.passes import aerial, analytic_shafts

CLOSED_FORM_RTOL = 0.005
MODES = [(s, m) for s in ("NONE", "INTEGRATION", "LUT") for m in ("NONE", "OCCLUDED", "UNOCCLUDED")]
CAMERA = np.array([0.0, 0.0, 2.0])
SUN = np.array([0.0, 0.5, math.sqrt(0.75)])             # 60 deg up, ahead: toward the haze's forward peak


@pytest.fixture(params=["clear-sky", "sample-2013"])
def media(request):
    m = analytic.media(lut_gen.preset(request.param))
    # A dense haze, so the extinction along a ray of kilometres is far from linear and a wrong
    # transmittance to the lit section would show.
    return analytic.AnalyticMedia(m.rayleigh, m.haze_scattering * 20, m.haze_extinction * 20, m.g,
                                  m.air_length, m.haze_length, m.ground_albedo)


def _ends():
    """Rays from the camera: level ahead, across the sun, up a hill, 300 m to 8 km."""
    return np.array([[0.0, 3000.0, 2.0], [2500.0, 500.0, 40.0], [0.0, 8000.0, 400.0], [-100.0, 300.0, 10.0]])


def _quadrature(m, camera, end, sun, lit_of_t, steps=200_000):
    """int_0^|end - camera| E_sun beta_sc exp(-beta t) lit(t) dt by the midpoint rule, the media at
    the densities of the segment's middle height (analytic.segment_densities)."""
    ray = end - camera
    length = np.linalg.norm(ray)
    direction = ray / length
    air, haze = analytic.segment_densities(m, camera, end)
    beta = m.rayleigh * air + m.haze_extinction * haze
    e_sun = analytic.sun_transmittance(m, sun[2], camera[2])
    source = e_sun * (m.rayleigh * air * analytic.rayleigh_phase(direction @ sun)
                      + m.haze_scattering * haze * analytic.hg_phase(direction @ sun, m.g))
    dt = length / steps
    t = (np.arange(steps) + 0.5) * dt
    return source * (np.exp(-beta * t[:, None]) * lit_of_t(t)[:, None]).sum(axis=0) * dt


def _along(end):
    """is_lit for a wall's shadow: points nearer the camera than 40% of the way to ``end`` are
    in shadow, the rest lit (one lit section, from an edge between march samples)."""
    direction = (end - CAMERA) / np.linalg.norm(end - CAMERA)
    edge = 0.4 * np.linalg.norm(end - CAMERA)
    return (lambda points: (((points - CAMERA) @ direction) > edge).astype(float)), (lambda t: (t > edge).astype(float))


def _stripes(end, period=0.13):
    """is_lit for a forest's shadows: lit and shadowed stripes along the ray (many sections).
    With 2000 steps their edges fall on step boundaries (0.13 x 2000 = 260 steps a period, 117
    shadowed), so the march's held samples see them exactly and the comparison measures the
    closed forms alone."""
    direction = (end - CAMERA) / np.linalg.norm(end - CAMERA)
    length = np.linalg.norm(end - CAMERA)

    def lit_of_t(t):
        return (np.mod(t / (period * length), 1.0) > 0.45).astype(float)
    return (lambda points: lit_of_t((points - CAMERA) @ direction)), lit_of_t


def test_a_lit_section_in_closed_form_matches_quadrature(media):
    """LUT: one lit section behind a wall's shadow, its edge refined between samples."""
    for end in _ends():
        is_lit, lit_of_t = _along(end)
        closed = analytic_shafts.light_shafts(media, CAMERA, end, SUN, is_lit, 256, "LUT", "UNOCCLUDED")
        brute = _quadrature(media, CAMERA, end, SUN, lit_of_t)
        np.testing.assert_allclose(closed, brute, rtol=CLOSED_FORM_RTOL)
        unshadowed = _quadrature(media, CAMERA, end, SUN, np.ones_like)
        assert (closed < 0.9 * unshadowed).all()          # the shadow took light out


def test_summed_lit_sections_match_quadrature_through_many_shafts(media):
    """INTEGRATION: every step's lit section in closed form, through stripes of light and shadow
    (the LUT mode's single section cannot hold them: it is measured off, as the tables' is)."""
    for end in _ends():
        is_lit, lit_of_t = _stripes(end)
        closed = analytic_shafts.light_shafts(media, CAMERA, end, SUN, is_lit, 2000, "INTEGRATION", "NONE")
        brute = _quadrature(media, CAMERA, end, SUN, lit_of_t)
        np.testing.assert_allclose(closed, brute, rtol=CLOSED_FORM_RTOL)
        one_section = analytic_shafts.light_shafts(media, CAMERA, end, SUN, is_lit, 2000, "LUT", "NONE")
        assert np.abs(one_section / brute - 1).max() > 0.02


def test_with_no_occluder_every_mode_gives_the_analytic_aerial_perspective(media):
    ends = _ends()
    _, _, aerial_light = analytic.aerial_perspective(media, CAMERA, ends, np.zeros((len(ends), 3)), SUN)
    quadrature = np.array([_quadrature(media, CAMERA, end, SUN, np.ones_like) for end in ends])
    np.testing.assert_allclose(aerial_light, quadrature, rtol=CLOSED_FORM_RTOL)
    offsets = np.array([0.1, 0.5, 0.9, 0.3])                 # jittered samples change nothing here
    for single, multiple in MODES:
        light = analytic_shafts.light_shafts(media, CAMERA, ends, SUN, lambda p: np.ones(p.shape[:-1]), 7, single,
                                             multiple, offsets)
        want = np.zeros_like(aerial_light) if single == "NONE" else aerial_light
        np.testing.assert_allclose(light, want, rtol=1e-9, atol=1e-15)
    # In full shadow nothing is left: the model has no multiple scattering to stay.
    for single, multiple in MODES:
        dark = analytic_shafts.light_shafts(media, CAMERA, ends, SUN, lambda p: np.zeros(p.shape[:-1]), 7, single,
                                            multiple)
        np.testing.assert_array_equal(dark, 0.0)


def test_the_epipolar_integral_table_matches_quadrature(media):
    """The epipolar INTEGRATION table at each distance node: the intervals' lit fractions held,
    the extinction of the segment to that node."""
    directions = _ends() - CAMERA
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    t = 8000.0 * np.expm1(np.arange(24) / 23 * np.log1p(800.0)) / 800.0       # the tables' geometric grid
    rng = np.random.default_rng(4)
    lit = (rng.random((len(directions), len(t) - 1)) > 0.4).astype(float)
    table = analytic_shafts.epipolar_integral(media, CAMERA, SUN)(directions, t, lit)
    assert table.shape == (len(directions), len(t), 3)
    np.testing.assert_array_equal(table[:, 0], 0.0)
    for i, direction in enumerate(directions):
        for k in (5, 14, 23):
            end = CAMERA + direction * t[k]

            def held(s, i=i):
                return lit[i][np.clip(np.searchsorted(t, s, side="right") - 1, 0, len(t) - 2)]
            ray = analytic_shafts.RayMedia.of(media, CAMERA, end, SUN)
            np.testing.assert_allclose(ray.source * table[i, k], _quadrature(media, CAMERA, end, SUN, held),
                                       rtol=CLOSED_FORM_RTOL)


def test_the_march_is_the_tables_march():
    """The analytic shafts share the tables' shadow tests: the same lit length and first lit
    distance for the same rays (aerial.march is what aerial.light_shafts runs)."""
    end = _ends()[0]
    is_lit, _ = _along(end)
    marched = aerial.march(CAMERA, end, is_lit, 32)
    assert math.isclose(float(marched.lit_length), 0.6 * np.linalg.norm(end - CAMERA), rel_tol=2e-3)
    assert math.isclose(float(marched.first_lit), 0.4 * np.linalg.norm(end - CAMERA), rel_tol=2e-3)


def test_the_multiple_scattering_modes_change_nothing_under_the_model(media):
    """The model has single scattering only: through shadows, every single-scattering mode gives
    the same light whatever the multiple-scattering mode (the tables' OCCLUDED and UNOCCLUDED
    differ by their higher orders, here 0), and the modes differ from each other."""
    end = _ends()[0]
    is_lit, _ = _stripes(end)
    light = {(s, m): analytic_shafts.light_shafts(media, CAMERA, end, SUN, is_lit, 40, s, m) for s, m in MODES}
    for single in ("NONE", "INTEGRATION", "LUT"):
        for multiple in ("OCCLUDED", "UNOCCLUDED"):
            np.testing.assert_array_equal(light[single, multiple], light[single, "NONE"])
    assert light["LUT", "NONE"].sum() > light["NONE", "NONE"].sum() == 0.0
    assert not np.allclose(light["LUT", "NONE"], light["INTEGRATION", "NONE"], rtol=0.01)
