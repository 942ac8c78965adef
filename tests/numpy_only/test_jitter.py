"""Jittered march steps (lut_gen.passes.jitter): the noise itself, and what it does to the
brute-force march of a row of pillars against a low sun at 16 steps against a 256-step march
(lut_gen.verify.banding). The node group's offsets against these: test_light_shafts_pass.py."""
import numpy as np
import pytest

from lut_gen.passes import jitter
from lut_gen.verify import banding
from occluders import CAMERA, Scene, pillars, sun_at


def test_the_noise_is_fixed_spread_evenly_and_off_means_the_step_centres():
    noise = jitter.step_offsets(64, 96)
    assert noise.shape == (64, 96) and noise.min() >= 0.0 and noise.max() < 1.0
    assert np.array_equal(noise, jitter.step_offsets(64, 96))             # every frame, every chunk
    assert abs(noise.mean() - 0.5) < 0.01
    assert np.histogram(noise, bins=10, range=(0, 1))[0].min() > 0.08 * noise.size
    # Every 3 x 3 neighbourhood spans most of [0, 1): no flat patches for a band to survive in.
    windows = np.lib.stride_tricks.sliding_window_view(noise, (3, 3))
    assert (windows.max(axis=(-1, -2)) - windows.min(axis=(-1, -2))).min() > 0.5
    assert np.all(jitter.step_offsets(4, 5, enabled=False) == jitter.CENTRE)


@pytest.fixture(scope="module")
def pillar_march(draft_luts):
    """The 16-step march without and with jitter, the 256-step march and the same without
    shafts, once for the module (the bench's size: at half of it the bands span too few pixels
    for the step between neighbours to show them)."""
    scene = Scene(pillars(), CAMERA, sun_at(4.0, 5.0), 384, 216)

    def run(**settings):
        return scene.shafts(draft_luts, scattering_technique="BRUTE_FORCE", **settings)
    images = {"plain": run(num_integration_steps=16), "jittered": run(num_integration_steps=16, jitter_steps=True),
              "reference": run(num_integration_steps=256),
              "unshadowed": run(num_integration_steps=256, enable_light_shafts=False)}
    return scene, images


def _measured(images, pixels, margin=4):
    return [banding.measure(images[name], images["reference"], images["unshadowed"], pixels, margin=margin)
            for name in ("plain", "jittered")]


def test_jitter_trades_the_bands_of_16_steps_for_noise_and_its_mean_takes_the_noise_out(pillar_march):
    """The bar at 16 steps: the largest step between neighbouring pixels of the blurred
    error (the bands) falls by at least 4x, and the mean error against the 256-step march does
    not grow. Measured (fractions of the shafts' size, sky pixels): banding step 0.20 -> 0.03,
    raw neighbour step 0.94 -> 0.15, mean |error| 0.111 -> 0.068 (the noise alone, without the
    3 x 3 mean: 0.119)."""
    scene, images = pillar_march
    plain, jittered = _measured(images, ~scene.geometry)
    print("16 steps, plain:", plain, "\njittered:", jittered)
    assert jittered["banding_step"] <= plain["banding_step"] / 4
    assert jittered["banding"] <= 0.6 * plain["banding"]
    assert jittered["mean_abs"] <= plain["mean_abs"]
    assert abs(jittered["bias"]) <= abs(plain["bias"]) + 0.01


def test_the_mean_keeps_a_silhouette_from_bleeding(pillar_march):
    """Surfaces too: at 16 steps with jitter the pillars' and ground's pixels err no more than
    without (the 3 x 3 mean counts only neighbours at nearly the same ray length). Measured:
    mean |error| 0.0033 -> 0.0030."""
    scene, images = pillar_march
    plain, jittered = _measured(images, scene.geometry, margin=0)
    print("surfaces, plain:", plain, "\njittered:", jittered)
    assert jittered["mean_abs"] <= plain["mean_abs"]


def test_the_neighbourhood_mean_counts_only_rays_of_nearly_the_same_length():
    values = np.zeros((3, 4, 3))
    values[1, 1] = 9.0
    length = np.full((3, 4), 100.0)
    length[:, 2:] = 1000.0                                   # a far region on the right
    mean = jitter.neighbourhood_mean(values, length)
    assert np.allclose(mean[0, 0], 9.0 / 4) and np.allclose(mean[1, 1], 9.0 / 6)    # a corner, an edge
    assert np.all(mean[:, 2:] == 0.0)                        # nothing crossed the depth jump
    assert np.allclose(jitter.neighbourhood_mean(np.ones((5, 6, 3)), np.full((5, 6), 7.0)), 1.0)
