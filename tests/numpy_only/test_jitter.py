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
    scene = Scene(pillars(), CAMERA, sun_at(4.0, 5.0), 192, 108)

    def run(**settings):
        return scene.shafts(draft_luts, scattering_technique="BRUTE_FORCE", **settings)
    return scene, run


def test_jitter_trades_the_bands_of_16_steps_for_noise(pillar_march):
    """Measured (fractions of the shafts' size, sky pixels): the blurred error (banding) 0.46
    -> 0.24, its largest neighbour step unchanged (0.045), the raw neighbour step 0.17 -> 0.94
    (the noise), mean |error| 0.051 -> 0.058, mean signed error within 0.01 either way."""
    scene, run = pillar_march
    reference = run(num_integration_steps=256)
    unshadowed = run(num_integration_steps=256, enable_light_shafts=False)
    sky = ~scene.geometry
    plain = banding.measure(run(num_integration_steps=16), reference, unshadowed, sky)
    jittered = banding.measure(run(num_integration_steps=16, jitter_steps=True), reference, unshadowed, sky)
    print("16 steps, plain:", plain, "\njittered:", jittered)
    assert jittered["banding"] <= 0.6 * plain["banding"]
    assert jittered["pixel_step"] > plain["pixel_step"]           # the bands became noise
    assert abs(jittered["bias"]) <= abs(plain["bias"]) + 0.01
    assert jittered["mean_abs"] <= 1.25 * plain["mean_abs"]
