"""Light shafts under broken clouds (lut_gen.clouds.shafts): the sample at a low sun with the
cloud layer on, composited by Cycles with both techniques, against the numpy twin; the shafts
must show (lit and shadowed air differ by at least 10% of the air light) and epipolar sampling
stays within 40 dB of brute force."""
import numpy as np
import pytest

from render_util import render_rgb, save_png
from scenes import Twin, render_passes, shaft_layout
from extension import extension_module

bpy = pytest.importorskip("bpy")

from test_light_shafts_pass import low_sun_scene, relative_error  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
STEPS = 30          # the panel's default


def cloudy_low_sun(pkg, tmp_path, monkeypatch):
    scene = low_sun_scene(pkg, tmp_path, monkeypatch, steps=STEPS)
    sun_mod = extension_module("addon.scene.sun")
    sun_mod.set_sun_angles(sun_mod.find_sun(scene), 9.0, 25.0)
    settings = scene.ols
    settings.clouds_enabled = True
    settings.cloud_coverage, settings.cloud_base, settings.cloud_thickness = 0.5, 1200.0, 400.0
    settings.cloud_scale, settings.cloud_seed, settings.cloud_offset = 1200.0, 7, (300.0, -800.0)
    settings.single_scattering_mode, settings.multiple_scattering_mode = "LUT", "UNOCCLUDED"
    return scene


def test_shafts_fan_from_cloud_gaps_in_both_techniques(addon_package, tmp_path, monkeypatch):
    scene = cloudy_low_sun(addon_package, tmp_path, monkeypatch)
    passes = render_passes(addon_package, scene, tmp_path)
    twin = Twin(addon_package, scene, passes)
    _, _, depth = passes
    sky = depth >= 1e9
    seen, expected = {}, {}
    for technique in ("BRUTE_FORCE", "EPIPOLAR_SAMPLING"):
        scene.ols.scattering_technique = technique
        seen[technique] = render_rgb(scene, tmp_path / f"{technique}.exr", composite=True)[::-1]
        layout = shaft_layout(scene.compositing_node_group.nodes["OLS Light Shafts"].node_tree)
        assert layout["clouds"], layout                 # the groups were built with the clouds
        expected[technique] = twin(scattering_technique=technique)
        error = relative_error(seen[technique], expected[technique])
        print(technique, "vs twin: median", np.median(error), "p99", np.percentile(error, 99))
        # Measured: median 5e-7 (brute force) and 5e-6 (epipolar), p99 about 1e-4 (float32
        # against float64, the cloud map read bilinearly on both sides).
        assert np.median(error) <= 1e-4
        assert np.percentile(error, 99) <= 5e-3
        # The clouds make a difference: the twin without them in the shafts is far off.
        without = relative_error(seen[technique], twin(scattering_technique=technique, clouds_enabled=False))
        assert np.median(without[sky]) > 0.02
    save_png(tmp_path / "cloud_shafts.png", seen["BRUTE_FORCE"][::-1], 1.0)

    # Shafts show: the air's darkening by the clouds, per sky pixel, against the air light the
    # pixel's unshadowed march holds (no geometry casts into these rays above the ridge).
    brute = expected["BRUTE_FORCE"]
    open_air = twin(scattering_technique="BRUTE_FORCE", enable_light_shafts=False)
    frame_update = extension_module("addon.scene.frame.frame_update")
    settings = frame_update.pass_settings(scene, 10.0)
    lut_passes = extension_module("lut_gen.passes")
    camera, luts = twin.camera, twin.luts
    cascades = twin.cascades()
    directions = camera.view_directions(*passes[0].shape[1::-1])
    clouds = extension_module("lut_gen.clouds.shafts").of_settings(settings)
    end, _ = lut_passes.scattering_pass.march_ends(camera, directions, passes[1], depth, cascades.far_depths[-1],
                                                   clouds, luts.params.earth_radius)
    air = lut_passes.aerial.segment_inscattering(luts, camera.position, end, twin.sun) * (
        settings.sun_strength * settings.scattering_scale)
    darkening = ((open_air - brute) @ LUMINANCE) / np.maximum(air @ LUMINANCE, 1e-9)
    spread = np.percentile(darkening[sky], [5, 50, 95])
    print("darkening of the sky's air light by the clouds, p5 / p50 / p95:", spread)
    assert spread[2] - spread[0] >= 0.10
    assert darkening[sky].min() > -1e-3               # clouds only take light out of the air

    display = [np.clip(x * 4.0 / (1 + x * 4.0), 0, 1) for x in (expected["EPIPOLAR_SAMPLING"], brute)]
    psnr = 10 * np.log10(1 / np.mean((display[0] - display[1]) ** 2))
    print("epipolar vs brute force under clouds, PSNR", psnr)
    assert psnr >= 40.0
