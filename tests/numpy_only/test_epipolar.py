"""Epipolar sampling (lut_gen.passes.epipolar) against brute-force ray marching on scenes built here in
numpy: a ground plane with thin occluders (a row of pillars, a fence of posts) against a low
sun, the sun in front of, behind and beside the camera, odd image sizes. Both techniques use
the same shadow cascades, steps and modes; the images are compared in display values through
one fixed exposure curve."""
import numpy as np
import pytest

from lut_gen.passes import aerial, epipolar, scattering_pass, shadow_map
from lut_gen.passes.shadow_map import Camera
from occluders import CAMERA, SCALE, SUN_STRENGTH, Scene, compare, fence, look_at, pillars, sun_at

























@pytest.mark.parametrize("name, boxes", [("pillars", pillars()), ("fence", fence())])
@pytest.mark.parametrize("elevation, azimuth", [(4.0, 5.0), (12.0, -20.0)])
def test_epipolar_matches_brute_force_behind_thin_occluders(draft_luts, default_luts, name, boxes, elevation,
                                                          azimuth):
    """Low sun behind pillars or a fence: the shafts through the gaps. The bar: PSNR >= 40 dB
    at the same steps, shadow maps and modes."""
    scene = Scene(boxes, CAMERA, sun_at(elevation, azimuth), 160, 90)
    quality, _, _ = compare(scene, draft_luts, num_integration_steps=32, epipolar_slices=256,
                            samples_per_slice=128)
    # Shafts are there, in the default tables: the darkening is a small difference of two large
    # sums, and the draft's coarse sun-view axis reads it 5x too small at sun 4 deg (the fence
    # 2.9-3.7% against 17%). Measured with the default tables: pillars 22% / 41% of the air
    # light at sun 4 / 12 deg, fence 17% / 26%.
    brute = scene.shafts(default_luts, num_integration_steps=32)
    unshadowed = scene.shafts(default_luts, enable_light_shafts=False)
    camera = np.broadcast_to(scene.camera.position, scene.position.shape)
    air = aerial.segment_inscattering(default_luts, camera, scene.position, scene.sun) * SUN_STRENGTH * SCALE
    darker = (unshadowed - brute)[scene.geometry].sum()
    assert darker > 0.1 * air[scene.geometry].sum(), darker / air[scene.geometry].sum()
    print(name, elevation, azimuth, "PSNR", quality)
    assert quality >= 40.0, quality


@pytest.mark.parametrize("technique", ["EPIPOLAR_SAMPLING", "BRUTE_FORCE"])
def test_sky_pixels_darker_than_their_air_keep_their_hue(draft_luts, technique):
    """A sky pixel whose rendered light is below the air light in front of it (an antialiased
    silhouette pixel, part sky, part dark surface, whose depth says sky) loses the shadowed
    fraction of its air light per channel instead of going below zero in one channel (teal
    pixels on a peak's outline against the sun). Sky pixels brighter than their air lose the
    whole darkening, as before."""
    scene = Scene(pillars(), CAMERA, sun_at(4.0, 5.0), 96, 54)
    sky = ~scene.geometry
    settings = dict(scattering_technique=technique, num_integration_steps=16, epipolar_slices=128,
                    samples_per_slice=64)
    bright = scene.shafts(draft_luts, **settings)
    unshadowed = scene.shafts(draft_luts, enable_light_shafts=False)
    darkened = sky & ((unshadowed - bright).max(axis=-1) > 1e-3 * unshadowed.max(axis=-1))
    assert darkened.sum() >= 20                                  # the sky through the pillars is shadowed
    np.testing.assert_allclose(unshadowed[sky], scene.image[sky])        # the sky is the rendered sky
    scene.image = np.where(sky[..., None], 1e-3, scene.image)       # a sky far darker than its air
    dim = scene.shafts(draft_luts, **settings)
    assert np.isfinite(dim).all() and dim.min() >= 0.0
    # Subtracting the whole darkening would have blacked out channels of these pixels...
    subtracted = scene.image + (bright - np.where(sky[..., None], 2.0, bright))
    assert (subtracted[darkened] <= 0.0).any()
    # ... which now each lose their air light's shadowed fraction: darker, every channel alive.
    ratio = dim[darkened] / scene.image[darkened]
    assert np.all(ratio > 0.0)
    assert np.all(ratio[:, 0] < 0.99)                                  # the shafts still show
    if technique == "EPIPOLAR_SAMPLING":
        assert np.all(ratio <= 1.0 + 1e-9)
        assert np.all(ratio.min(axis=-1) >= 0.5 * ratio.max(axis=-1))  # the hue nearly kept
    # Brute force's blue can gain here (measured up to 4.8x on this 1e-3 sky): its shadowed
    # minus unshadowed light is positive in blue toward a sun 4 deg up, its lit "single" +
    # "higher" sections exceeding the unshadowed "multiple" section (geometric blending is not
    # additive). In absolute terms that is the same small gain every sky pixel got before.


@pytest.mark.parametrize("elevation, azimuth, what", [
    (20.0, 180.0, "sun behind the camera"),
    (-3.0, 0.0, "sun below the horizon"),
    (8.0, 30.0, "sun on the screen's right edge"),
    (8.0 + 30.0 * 9 / 16, 30.0, "sun near the screen's corner"),
    (60.0, 0.0, "sun above the screen"),
])
def test_every_epipole_position_works_without_seams(draft_luts, elevation, azimuth, what):
    scene = Scene(pillars(), CAMERA, sun_at(elevation, azimuth), 96, 54)
    quality, _, epi = compare(scene, draft_luts, num_integration_steps=16, epipolar_slices=128, samples_per_slice=64)
    assert np.isfinite(epi).all(), what
    assert quality >= 36.0, (what, quality)


@pytest.mark.parametrize("size, slices, samples", [((16, 16), 32, 32), ((16, 16), 2048, 32), ((16, 16), 32, 2048),
                                                   ((4000, 200), 512, 256)])
def test_odd_sizes_and_extreme_settings_stay_finite(draft_luts, size, slices, samples):
    scene = Scene(pillars(), CAMERA, sun_at(6.0, 10.0), *size)
    epi = scene.shafts(draft_luts, scattering_technique="EPIPOLAR_SAMPLING", num_integration_steps=8,
                       epipolar_slices=slices, samples_per_slice=samples)
    assert epi.shape == (size[1], size[0], 3) and np.isfinite(epi).all() and epi.min() >= 0.0


@pytest.mark.parametrize("elevation", [5.0, 30.0])
def test_without_occluders_epipolar_equals_the_unshadowed_result(draft_luts, elevation):
    """Nothing lit short of a ray's end: the shafts add exactly nothing (the lit section's
    in-scattering is the whole ray's, read from the same tables), and the technique's aerial
    perspective, also read from its tables, is the per-pixel one within the tables' accuracy
    (measured on this ground plane: median 0.02-0.04%, the worst pixels 5-14% on the one
    row along the plain's horizon)."""
    scene = Scene([], CAMERA, sun_at(elevation, 0.0), 64, 36)
    settings = scattering_pass.PassSettings(scattering_technique="EPIPOLAR_SAMPLING", num_integration_steps=16)
    directions = scene.camera.view_directions(64, 36)
    end, _ = scattering_pass.march_ends(scene.camera, directions, scene.position, scene.depth,
                                        scene.cascades.far_depths[-1])
    _, difference, _ = scattering_pass.epipolar_pass(draft_luts, scene.camera, end, scene.sun, scene.cascades,
                                                     settings, 64, 36)
    assert np.abs(difference).max() < 1e-9
    epi = scene.shafts(draft_luts, scattering_technique="EPIPOLAR_SAMPLING", num_integration_steps=16)
    plain = scene.shafts(draft_luts, enable_light_shafts=False)
    np.testing.assert_array_equal(epi[~scene.geometry], plain[~scene.geometry])
    error = (np.abs(epi - plain).sum(-1) / plain.sum(-1))[scene.geometry]
    print(elevation, "median", np.median(error), "p99", np.percentile(error, 99), "max", error.max())
    assert np.median(error) < 0.002 and np.percentile(error, 90) < 0.01 and error.max() < 0.2


def test_in_full_shadow_only_the_multiple_scattering_share_remains(draft_luts):
    """A roof over the whole view: with the single scattering in LUT mode and the multiple
    scattering UNOCCLUDED, only the higher orders' in-scattering is left in the air, as for
    brute force."""
    roof = [(np.array([-5000.0, -5000.0, 300.0]), np.array([5000.0, 5000.0, 310.0]))]
    scene = Scene(roof, look_at([0.0, 0.0, 2.0], [0.0, 30.0, -20.0]), sun_at(30.0, 0.0), 64, 36)
    for technique in ("EPIPOLAR_SAMPLING", "BRUTE_FORCE"):
        shadowed = scene.shafts(scene_luts := draft_luts, scattering_technique=technique, num_integration_steps=16)
        camera = np.broadcast_to(scene.camera.position, scene.position.shape)
        higher = aerial.segment_inscattering(scene_luts, camera, scene.position, scene.sun, table="higher")
        expected = scene.image * aerial.segment_transmittance(scene_luts, camera, scene.position) + higher * SUN_STRENGTH * SCALE
        geometry = scene.geometry
        np.testing.assert_allclose(shadowed[geometry], expected[geometry], rtol=2e-3, atol=1e-7, err_msg=technique)


def test_sampling_controls_change_the_tables():
    """Initial sample step and epipole density choose the marched samples; the threshold adds
    refined ones between marched neighbours that disagree."""
    coarse = epipolar.initial_samples(256, 16, 1)
    dense = epipolar.initial_samples(256, 16, 4)
    assert coarse[0] == 0 and coarse[-1] == 255 and np.all(np.diff(coarse) <= 16)
    assert len(dense) > len(coarse) and np.all(np.diff(dense[dense < 32]) == 4)
    scene = Scene(fence(), CAMERA, sun_at(6.0, 0.0), 64, 36)
    frame = epipolar.frame_for(scene.camera, scene.sun, 64, 36, float(scene.cascades.far_depths[-1]),
                               epipolar.EpipolarSettings(slices=64, samples=64, steps=16))
    counts = {}
    for threshold in (0.0, 0.2, 0.01):
        settings = epipolar.EpipolarSettings(slices=64, samples=64, steps=16, initial_sample_step=16,
                                             refinement_threshold=threshold)
        counts[threshold] = epipolar.build_tables(frame, scene.cascades, scene.camera, settings).marched.sum()
    assert counts[0.0] < counts[0.2] < counts[0.01], counts


def test_bad_settings_are_refused_with_a_message():
    with pytest.raises(ValueError, match="slices"):
        epipolar.EpipolarSettings(slices=0).checked()
    with pytest.raises(ValueError, match="refinement threshold"):
        epipolar.EpipolarSettings(refinement_threshold=float("nan")).checked()


def test_each_epipolar_control_changes_the_picture(draft_luts):
    """Slices, samples, initial step, epipole density and refinement threshold each change the
    picture (a little); Show Sampling paints red dots."""
    scene = Scene(fence(), CAMERA, sun_at(6.0, 5.0), 96, 54)
    base = dict(scattering_technique="EPIPOLAR_SAMPLING", num_integration_steps=16, epipolar_slices=128,
                samples_per_slice=64, initial_sample_step=16, epipole_sampling_density=2, refinement_threshold=0.5)
    reference = scene.shafts(draft_luts, **base)
    for name, value in (("epipolar_slices", 64), ("samples_per_slice", 128), ("initial_sample_step", 4),
                        ("epipole_sampling_density", 8), ("refinement_threshold", 0.01)):
        changed = scene.shafts(draft_luts, **{**base, name: value})
        assert np.abs(changed - reference).max() > 1e-7, name
    dotted = scene.shafts(draft_luts, **base, show_sampling=True)
    red = (dotted[..., 1:].max(axis=-1) == 0.0) & (dotted[..., 0] > reference.max(axis=-1))
    assert 0.01 < red.mean() < 0.9
    assert np.array_equal(dotted[~red], reference[~red])


@pytest.mark.parametrize("resolution", [256, 250])        # 250: blocks padded at the edge
@pytest.mark.parametrize("smooth", [True, False])
def test_min_max_maps_give_the_same_shadow_test(smooth, resolution):
    """lut_gen.passes.min_max skips decided points' taps; its answer is shadow_map.visibility's."""
    from lut_gen.passes import min_max
    scene = Scene(pillars() + fence(), CAMERA, sun_at(7.0, 10.0), 32, 18, resolution=resolution)
    rng = np.random.default_rng(4)
    points = rng.uniform([-400.0, 0.0, 0.0], [400.0, 600.0, 150.0], (20_000, 3))
    want = shadow_map.visibility(scene.cascades, points, scene.camera, smooth, True, 1)
    got = min_max.visibility(scene.cascades, min_max.build(scene.cascades, smooth), points, scene.camera, True, 1)
    assert 0.05 < want.mean() < 0.95
    # The same taps and weights; the bilinear weights' products may round in another order.
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_min_max_optimization_changes_speed_not_the_picture(draft_luts):
    scene = Scene(fence(), CAMERA, sun_at(6.0, 5.0), 96, 54)
    settings = dict(scattering_technique="EPIPOLAR_SAMPLING", num_integration_steps=16, epipolar_slices=128,
                    samples_per_slice=64)
    on = scene.shafts(draft_luts, use_min_max_optimization=True, **settings)
    off = scene.shafts(draft_luts, use_min_max_optimization=False, **settings)
    np.testing.assert_allclose(on, off, rtol=0, atol=1e-6)


def ground_distance(radius, camera, directions):
    """Distance from the camera to the (spherical) ground along ``directions``, inf where they miss it."""
    from lut_gen.model import geometry
    from lut_gen.tables import parameterization
    centre = camera + np.array([0.0, 0.0, radius])
    r = np.linalg.norm(centre)
    cos_zenith = directions @ (centre / r)
    hits = cos_zenith < parameterization.cos_horizon(r - radius, radius)
    return np.where(hits, geometry.distance_to_ground(r, cos_zenith, radius), np.inf)


@pytest.mark.parametrize("elevation, azimuth", [(5.0, 0.0), (25.0, 150.0)])
def test_in_scattering_tables_match_eq8_per_pixel(draft_luts, elevation, azimuth):
    """lut_gen.passes.epipolar_air: a lit section's in-scattering I(b) - I(a) read from the coarse
    tables against Yusov 2013 eq. (8) evaluated per pixel (lut_gen.passes.aerial, what brute force
    applies), for the single scattering (Rayleigh and Mie) and the higher orders, on random rays
    across the screen and random sections along them up to 20 km or the ground. Measured (draft
    tables): 1.2-1.5% of the in-scattering to b, 2.3-2.8% of the sections' (weighted by their
    radiance)."""
    from lut_gen.passes import epipolar_air
    camera, sun = CAMERA, sun_at(elevation, azimuth)
    frame = epipolar.frame_for(camera, sun, 160, 90, 3000.0, epipolar.EpipolarSettings())
    air = epipolar_air.air_frame(frame, Camera(camera.position, camera.rotation, camera.tan_half_fov, 30e3))
    tables = epipolar_air.build(draft_luts, air, camera.position)
    rng = np.random.default_rng(7)
    directions = camera.view_directions(160, 90).reshape(-1, 3)[rng.choice(160 * 90, 2000, replace=False)]
    b = np.minimum(20e3 * rng.uniform(0.0, 1.0, 2000) ** 2 + 1.0,
                   ground_distance(draft_luts.params.earth_radius, camera.position, directions))
    a = b * rng.uniform(0.0, 1.0, 2000)
    position = np.broadcast_to(camera.position, directions.shape)
    start, end = position + directions * a[:, None], position + directions * b[:, None]
    for part in ("single", "higher"):
        to_b = epipolar_air.inscattering(draft_luts, air, tables, part, directions, b)
        section = to_b - epipolar_air.inscattering(draft_luts, air, tables, part, directions, a)
        expected_to_b = aerial._section(draft_luts, position, position, end, directions, sun, part)
        expected = aerial._section(draft_luts, position, start, end, directions, sun, part)
        error_to_b = np.abs(to_b - expected_to_b).sum() / expected_to_b.sum()
        error = np.abs(section - expected).sum() / expected.sum()
        print(part, elevation, azimuth, f"to b {error_to_b:.4f}, sections {error:.4f}")
        assert error_to_b < 0.03 and error < 0.05, (part, error_to_b, error)


@pytest.mark.parametrize("elevation, azimuth", [(6.0, 0.0), (25.0, 150.0), (40.0, 180.0)])
def test_tables_of_the_screen_nodes_give_every_pixel_the_same_values(draft_luts, elevation, azimuth):
    """epipolar.screen_nodes: building only the nodes the pixels read (the add-on's frame update)
    leaves every pixel's look-up of the lit-length and the in-scattering tables as the whole
    grid's build gives it."""
    from lut_gen.passes import epipolar_air
    width, height = 64, 36
    scene = Scene(fence(), CAMERA, sun_at(elevation, azimuth), width, height)
    settings = epipolar.EpipolarSettings(slices=64, samples=64, steps=16)
    frame = epipolar.frame_for(scene.camera, scene.sun, width, height, float(scene.cascades.far_depths[-1]), settings)
    needed = epipolar.screen_nodes(frame, scene.camera, width, height)
    whole = epipolar.build_tables(frame, scene.cascades, scene.camera, settings)
    part = epipolar.build_tables(frame, scene.cascades, scene.camera, settings, needed=needed)
    directions = scene.camera.view_directions(width, height)
    distances = np.random.default_rng(3).uniform(0.0, 1.2 * frame.t_max, directions.shape[:2])
    for a, b in zip(epipolar.look_up(frame, whole, directions, distances)[:2],
                    epipolar.look_up(frame, part, directions, distances)[:2]):
        np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-6 * frame.t_max)
    air = epipolar_air.air_frame(frame, scene.camera)
    air_needed = epipolar.screen_nodes(air, scene.camera, width, height)
    whole_air = epipolar_air.build(draft_luts, air, scene.camera.position)
    part_air = epipolar_air.build(draft_luts, air, scene.camera.position, air_needed)
    for name in ("rayleigh", "mie", "higher"):
        a = epipolar.trilinear(air, getattr(whole_air, name), directions, distances)
        b = epipolar.trilinear(air, getattr(part_air, name), directions, distances)
        np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-9 * np.abs(a).max())
    assert needed.any() and air_needed.any()
