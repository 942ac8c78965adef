"""Blender's factory-default scene, then Set Up Scene, then a render: a shaded cube over lit
ground. The three-wavelength tables with a black ground gave a solid white cube: auto
exposure was set by the dark world below the horizon. Each engine renders in a subprocess (a
fresh factory scene; EEVEE aborts the process without EGL)."""
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from extension import ROOT

pytest.importorskip("bpy")

SCRIPT = textwrap.dedent("""
    import json, sys
    sys.path.insert(0, {scripts!r})
    import render as launcher
    package = launcher.import_extension()
    package.register()
    import bpy
    args = json.loads({args!r})
    bpy.ops.wm.read_factory_settings(use_empty=False)       # cube, point light, camera
    package.register()
    scene = bpy.context.scene
    scene.render.engine = args["engine"]
    bpy.ops.object.select_all(action="DESELECT")             # keep the cube's own material
    result = bpy.ops.ols.setup_scene(resolution="draft")
    assert result == {{"FINISHED"}}, result
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    scene.render.resolution_percentage = 100
    scene.cycles.samples = 16
    scene.eevee.taa_render_samples = 8
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = args["out"]
    bpy.ops.render.render(write_still=True)
    mask_path = args["out"] + ".mask.npy"
    # The cube's pixels: a holdout render of everything else is not needed, project its corners.
    import numpy as np
    from bpy_extras.object_utils import world_to_camera_view
    cube = bpy.data.objects["Cube"]
    corners = [cube.matrix_world @ v.co for v in cube.data.vertices]
    uv = np.array([tuple(world_to_camera_view(scene, scene.camera, c))[:2] for c in corners])
    np.save(mask_path, uv)
""")


def render_default_cube(tmp_path, engine):
    out = tmp_path / f"cube_{engine}.png"
    env = dict(__import__("os").environ, OLS_CACHE_DIR=str(tmp_path / "cache"))
    script = SCRIPT.format(scripts=str(ROOT / "scripts"), args=json.dumps({"engine": engine, "out": str(out)}))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=900, env=env)
    return result, out


def cube_pixels(png, corners_uv):
    """sRGB pixels inside the convex hull of the cube's projected corners (rows top to bottom)."""
    import bpy
    image = bpy.data.images.load(str(png))
    width, height = image.size
    pixels = np.array(image.pixels[:], dtype=np.float32).reshape(height, width, 4)[::-1, :, :3]
    bpy.data.images.remove(image)
    points = corners_uv * [width, height]
    points[:, 1] = height - points[:, 1]
    hull = convex_hull(points)
    yy, xx = np.mgrid[0:height, 0:width] + 0.5
    sides = np.stack([(b[0] - a[0]) * (yy - a[1]) - (b[1] - a[1]) * (xx - a[0])
                      for a, b in zip(hull, np.roll(hull, -1, axis=0))])
    inside = np.all(sides >= 0, axis=0) | np.all(sides <= 0, axis=0)
    return pixels, inside


def convex_hull(points):
    """Andrew's monotone chain: the hull's corners in order around it."""
    pts = sorted(map(tuple, points))
    cross = lambda o, a, b: (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def egl_available():
    probe = ("import bpy; s=bpy.context.scene; s.render.engine='BLENDER_EEVEE'; "
             "s.render.resolution_x=s.render.resolution_y=8; bpy.ops.render.render()")
    return subprocess.run([sys.executable, "-c", probe], capture_output=True, timeout=300).returncode == 0


@pytest.mark.parametrize("engine", ["CYCLES", "BLENDER_EEVEE"])
def test_default_cube_is_shaded_over_lit_ground(tmp_path, engine):
    if engine == "BLENDER_EEVEE" and not egl_available():
        pytest.skip("EEVEE cannot render here (no EGL: install libegl1 libegl-mesa0 libgl1-mesa-dri)")
    result, out = render_default_cube(tmp_path, engine)
    assert result.returncode == 0, result.stderr[-2000:]
    pixels, inside = cube_pixels(out, np.load(str(out) + ".mask.npy"))
    # Shrink the mask by a pixel so edges blended with the background do not count.
    core = inside & np.roll(inside, 1, 0) & np.roll(inside, -1, 0) & np.roll(inside, 1, 1) & np.roll(inside, -1, 1)
    cube = pixels[core]
    assert core.sum() > 500
    clipped = (cube.max(axis=1) >= 254.5 / 255).mean()
    assert clipped < 0.05
    # Lit and shadowed faces: the brightest and the darkest tenth of the cube differ clearly.
    luminance = cube @ np.array([0.2126, 0.7152, 0.0722])
    assert np.percentile(luminance, 90) - np.percentile(luminance, 10) > 0.25
    # The world behind the cube is the lit ground (the factory camera looks down), not black.
    background = pixels[~inside]
    assert np.median(background @ np.array([0.2126, 0.7152, 0.0722])) > 0.2
