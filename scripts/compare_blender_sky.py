"""Our sky (the numpy twin, lut_gen) next to Blender's own Sky Texture (MULTIPLE_SCATTERING).

Writes docs/sky_comparison.png (+ docs/sky_comparison.txt, a caption) and prints, per sun
elevation and for both skies, the CIE xy of the zenith and of the horizon 90 deg from the sun
and the zenith/horizon luminance ratio.

    cd /work/main && .venv/bin/python scripts/compare_blender_sky.py [--draft]

Both panels use the same view mapping, an equirectangular strip: azimuth -180..180 deg from
the sun left to right (sun in the middle), elevation +90 (top) to -10 deg (bottom); Blender's
sky is rendered with Cycles CPU through a panoramic equirectangular camera with those limits.
Each panel is divided by the median luminance of its pixels above the horizon, exposed so that
median is 0.18, tone mapped (extended Reinhard on luminance, hue kept) and sRGB encoded.
"""
from __future__ import annotations

import argparse
import contextlib
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import lut_gen  # noqa: E402
from lut_gen.model import spectrum  # noqa: E402
from lut_gen.passes import sky_view  # noqa: E402
from lut_gen.store.png import to_srgb8, write_png  # noqa: E402

SUN_ELEVATIONS = (60.0, 20.0, 5.0, 1.0, -2.0, -6.0)
CAMERA_HEIGHT_M = 2.0
WIDTH, HEIGHT = 720, 200                 # 0.5 deg per pixel
LAT_MAX, LAT_MIN = 90.0, -10.0
RGB_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
MIDDLE_GRAY = 0.18
WHITE = 12.0                             # extended-Reinhard white point (exposed units)


# -- view mapping ---------------------------------------------------------------------------
def view_grid(width=WIDTH, height=HEIGHT):
    """(elevation, azimuth-from-sun) in radians at the pixel centres, row 0 at the top; the
    same mapping as Blender's equirectangular camera with these latitude/longitude limits."""
    lat = np.radians(LAT_MAX - (np.arange(height) + 0.5) / height * (LAT_MAX - LAT_MIN))
    lon = np.radians(-180.0 + (np.arange(width) + 0.5) / width * 360.0)
    return np.meshgrid(lat, lon, indexing="ij")


# -- our sky --------------------------------------------------------------------------------
def our_panorama(luts, sun_elevation_deg, width=WIDTH, height=HEIGHT):
    el, az = view_grid(width, height)
    cos_view = np.sin(el)
    sun = math.radians(sun_elevation_deg)
    cos_sun = np.full_like(cos_view, math.sin(sun))
    cos_sun_view = np.sin(el) * math.sin(sun) + np.cos(el) * math.cos(sun) * np.cos(az)
    # The sky the world shows: the look-up and the camera's twilight correction.
    twilight = sky_view.compute(luts, CAMERA_HEIGHT_M, math.sin(sun))
    return (np.asarray(sky_view.camera_sky(luts, twilight, cos_view, cos_sun_view), np.float64)
            + luts.ground_radiance(CAMERA_HEIGHT_M, cos_view, cos_sun, cos_sun_view))


# -- Blender's sky --------------------------------------------------------------------------
class BlenderSky:
    """A scene with only a world (Sky Texture -> Background) and a panoramic camera."""

    def __init__(self, width=WIDTH, height=HEIGHT, samples=4):
        import bpy
        self.bpy = bpy
        scene = bpy.context.scene
        for obj in list(bpy.data.objects):
            bpy.data.objects.remove(obj)
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = samples
        scene.cycles.use_denoising = False
        scene.cycles.filter_width = 0.01          # sample at the pixel centres: same mapping as ours
        scene.render.resolution_x, scene.render.resolution_y = width, height
        scene.render.resolution_percentage = 100
        scene.render.film_transparent = False
        scene.view_settings.view_transform = "Standard"
        settings = scene.render.image_settings
        settings.file_format = "OPEN_EXR"
        settings.color_depth = "32"
        settings.exr_codec = "ZIP"

        cam_data = bpy.data.cameras.new("pano")
        cam_data.type = "PANO"
        cam_data.panorama_type = "EQUIRECTANGULAR"
        cam_data.latitude_min, cam_data.latitude_max = math.radians(LAT_MIN), math.radians(LAT_MAX)
        cam_data.longitude_min, cam_data.longitude_max = -math.pi, math.pi
        cam = bpy.data.objects.new("pano", cam_data)
        scene.collection.objects.link(cam)
        cam.location = (0.0, 0.0, 0.0)
        # Looks along +Y, horizontally: with sun_rotation 0 the sun is in the middle column
        # (checked by rendering a sun disc).
        cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
        scene.camera = cam

        world = bpy.data.worlds.new("sky")
        scene.world = world
        if not getattr(world, "node_tree", None):
            world.use_nodes = True
        tree = world.node_tree
        for node in list(tree.nodes):
            tree.nodes.remove(node)
        sky = tree.nodes.new("ShaderNodeTexSky")
        background = tree.nodes.new("ShaderNodeBackground")
        output = tree.nodes.new("ShaderNodeOutputWorld")
        sky.sky_type = "MULTIPLE_SCATTERING"
        sky.sun_disc = False
        sky.sun_rotation = 0.0
        sky.altitude = CAMERA_HEIGHT_M
        sky.air_density = 1.0
        sky.aerosol_density = 1.0
        sky.ozone_density = 1.0
        tree.links.new(sky.outputs["Color"], background.inputs["Color"])
        tree.links.new(background.outputs["Background"], output.inputs["Surface"])
        self.scene, self.sky = scene, sky
        self.tmp = tempfile.TemporaryDirectory(prefix="blender_sky_")

    def panorama(self, sun_elevation_deg):
        self.sky.sun_elevation = math.radians(sun_elevation_deg)
        path = Path(self.tmp.name) / f"sky_{sun_elevation_deg:+.0f}.exr"
        self.scene.render.filepath = str(path)
        with _quiet_stdout():
            self.bpy.ops.render.render(write_still=True)
        return read_exr_rgb(path)


@contextlib.contextmanager
def _quiet_stdout():
    """Silence Cycles' progress lines (written to file descriptor 1 by C code)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def read_exr_rgb(path):
    """(height, width, 3) float64, row 0 at the top."""
    import OpenEXR
    channels = OpenEXR.File(str(path)).parts[0].channels
    if "RGBA" in channels:
        return np.asarray(channels["RGBA"].pixels, np.float64)[..., :3]
    if "RGB" in channels:
        return np.asarray(channels["RGB"].pixels, np.float64)
    return np.stack([np.asarray(channels[c].pixels, np.float64) for c in "RGB"], axis=-1)


# -- measures -------------------------------------------------------------------------------
def chromaticity(rgb):
    return np.asarray(spectrum.chromaticity(rgb))


def luminance(rgb):
    return np.asarray(rgb) @ RGB_LUMINANCE


def probes(width=WIDTH, height=HEIGHT):
    """Pixel masks: zenith (elevation > 89 deg), horizon 90 deg from the sun (elevation
    0.5..1.5 deg, azimuth 90 +- 1 deg on both sides), sun-side and anti-sun horizon."""
    el, az = np.degrees(view_grid(width, height))
    band = (el > 0.5) & (el < 1.5)
    return {
        "zenith": el > 89.0,
        "horizon90": band & (np.abs(np.abs(az) - 90.0) < 1.0),
        "horizon_sun": band & (np.abs(az) < 1.0),
        "horizon_anti": band & (np.abs(az) > 179.0),
    }


def measure(rgb, masks):
    mean = {name: rgb[mask].mean(axis=0) for name, mask in masks.items()}
    zen, hor = mean["zenith"], mean["horizon90"]
    return {
        "zenith_xy": chromaticity(zen),
        "horizon_xy": chromaticity(hor),
        "zen_over_hor": luminance(zen) / max(luminance(hor), 1e-30),
        "sun_over_anti": luminance(mean["horizon_sun"]) / max(luminance(mean["horizon_anti"]), 1e-30),
    }


# -- display --------------------------------------------------------------------------------
def display(rgb):
    """Median of the sky above the horizon -> 0.18, extended Reinhard on luminance (hue kept),
    clip, then the sRGB encoding of to_srgb8 (returns linear display values)."""
    el, _ = view_grid(rgb.shape[1], rgb.shape[0])
    lum = luminance(rgb)
    median = np.median(lum[el > 0])
    scaled = rgb * (MIDDLE_GRAY / max(median, 1e-30))
    y = np.maximum(luminance(scaled), 1e-30)
    mapped = y * (1.0 + y / WHITE ** 2) / (1.0 + y)
    out = scaled * (mapped / y)[..., None]
    # Spill channels above 1 into white rather than clip the hue away.
    excess = np.maximum(out.max(axis=-1, keepdims=True) - 1.0, 0.0)
    return np.clip(out + excess * 0.5, 0.0, 1.0)


# -- tiny 5x7 bitmap font for the labels -----------------------------------------------------
_FONT = {
    "A": ".###.#...##...#######...##...##...#", "B": "####.#...##...#####.#...##...#####.",
    "C": ".###.#...##....#....#....#...#.###.", "D": "####.#...##...##...##...##...#####.",
    "E": "######....#....####.#....#....#####", "F": "######....#....####.#....#....#....",
    "G": ".###.#...##....#.####...##...#.####", "H": "#...##...##...#######...##...##...#",
    "I": ".###...#....#....#....#....#...###.", "J": "..###...#....#....#....#.#..#..##..",
    "K": "#...##..#.#.#..##...#.#..#..#.#...#", "L": "#....#....#....#....#....#....#####",
    "M": "#...###.###.#.##...##...##...##...#", "N": "#...##...###..##.#.##..###...##...#",
    "O": ".###.#...##...##...##...##...#.###.", "P": "####.#...##...#####.#....#....#....",
    "Q": ".###.#...##...##...##.#.##..#..##.#", "R": "####.#...##...#####.#.#..#..#.#...#",
    "S": ".####.....#.....###.....#....#####.", "T": "#####..#....#....#....#....#....#..",
    "U": "#...##...##...##...##...##...#.###.", "V": "#...##...##...##...##...#.#.#...#..",
    "W": "#...##...##...##.#.##.#.##.#.#.#.#.", "X": "#...##...#.#.#...#...#.#.#...##...#",
    "Y": "#...##...#.#.#...#....#....#....#..", "Z": "#####....#...#...#...#...#....#####",
    "0": ".###.#...##..###.#.###..##...#.###.", "1": "..#...##....#....#....#....#...###.",
    "2": ".###.#...#....#...#...#...#...#####", "3": "#####...#...#.....#.....##...#.###.",
    "4": "...#...##..#.#.#..#.#####...#....#.", "5": "######....####.....#....##...#.###.",
    "6": "..##..#...#....####.#...##...#.###.", "7": "#####....#...#...#...#....#....#...",
    "8": ".###.#...##...#.###.#...##...#.###.", "9": ".###.#...##...#.####....#...#..##..",
    "-": "................###................", ".": "..............................##...",
    "(": "...#...#...#....#....#.....#.....#.", ")": ".#.....#.....#....#....#...#...#...",
    ":": ".......##...##.........##...##.....", "_": "..............................#####",
    "+": "........#....#..#####..#....#......", " ": "." * 35, "/": ".........#...#...#...#...#.........",
    "|": "..#....#....#....#....#....#....#..",
}


def draw_text(image, text, row, col, scale=2, colour=(0.85, 0.85, 0.85)):
    for ch in text.upper():
        glyph = _FONT.get(ch, _FONT[" "]).ljust(35, ".")[:35]
        bits = np.array([c == "#" for c in glyph]).reshape(7, 5)
        block = np.kron(bits, np.ones((scale, scale), bool))
        h, w = block.shape
        region = image[row:row + h, col:col + w]
        region[block[:region.shape[0], :region.shape[1]]] = colour
        col += 6 * scale
    return image


def compose(panels, elevations, gap=6, label_width=104, header=34):
    """panels: list of (ours, blender) display images (linear display values)."""
    h, w = panels[0][0].shape[:2]
    height = header + len(panels) * (h + gap)
    width = label_width + 2 * w + 3 * gap
    canvas = np.full((height, width, 3), 0.03)
    x_ours, x_blender = label_width + gap, label_width + 2 * gap + w
    draw_text(canvas, "OURS (LUT_GEN NUMPY TWIN)", 10, x_ours)
    draw_text(canvas, "BLENDER 5.0 SKY TEXTURE MULTIPLE_SCATTERING", 10, x_blender)
    horizon_row = int(round(LAT_MAX / (LAT_MAX - LAT_MIN) * h))
    for i, ((ours, blender), elevation) in enumerate(zip(panels, elevations)):
        top = header + i * (h + gap)
        canvas[top:top + h, x_ours:x_ours + w] = ours
        canvas[top:top + h, x_blender:x_blender + w] = blender
        draw_text(canvas, "SUN", top + h // 2 - 18, 8)
        draw_text(canvas, f"{elevation:+.0f} DEG", top + h // 2 + 2, 8)
        # horizon ticks in the gutters
        for x in (x_ours - gap, x_blender - gap, x_blender + w):
            canvas[top + horizon_row, x:x + gap] = 0.9
    return canvas


CAPTION = """\
docs/sky_comparison.png -- written by scripts/compare_blender_sky.py

Left column: our sky (lut_gen numpy twin, default AtmosphereParams, "default" bake resolution,
table "multiple" = single + higher orders with the camera's twilight correction
(lut_gen.passes.sky_view), plus ground_radiance below the horizon when the Luts
provide it). Right column: Blender {blender} Sky Texture, sky_type MULTIPLE_SCATTERING, sun disc off,
altitude 2 m, air/aerosol/ozone density 1 (defaults), rendered with Cycles CPU through a
panoramic equirectangular camera. Rows, top to bottom: sun elevation {elevations} deg.

Every panel is the same equirectangular strip: azimuth from the sun -180..+180 deg left to
right (the sun's azimuth in the middle, the anti-sun direction at both edges), elevation +90 deg
(top row, the zenith) down to -10 deg (bottom), 0.5 deg per pixel ({w} x {h}). The white ticks in
the gutters mark the horizon (elevation 0). Viewer height 2 m, no sun disc.

Display: each panel divided by the median luminance of its pixels above the horizon (so only
colour and distribution are compared, not absolute level), exposed so that median = 0.18,
extended Reinhard on luminance with white point {white} (hue kept, channels over 1 spill to
white), sRGB encoding.
"""


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draft", action="store_true", help="use the draft bake resolution")
    parser.add_argument("--output", default=str(ROOT / "docs" / "sky_comparison.png"))
    parser.add_argument("--samples", type=int, default=4, help="Cycles samples per pixel")
    args = parser.parse_args(argv)

    t0 = time.time()
    resolution = "draft" if args.draft else "default"
    luts, directory, hit = lut_gen.cached_bake(lut_gen.AtmosphereParams(), resolution=resolution)
    print(f"luts: {directory} ({'cached' if hit else 'baked'}, {time.time() - t0:.1f} s)")

    blender = BlenderSky(samples=args.samples)
    masks = probes()
    panels, rows = [], []
    for elevation in SUN_ELEVATIONS:
        ours = our_panorama(luts, elevation)
        theirs = blender.panorama(elevation)
        panels.append((display(ours), display(theirs)))
        rows.append((elevation, measure(ours, masks), measure(theirs, masks)))

    print()
    print("zenith = mean over elevation > 89 deg; horizon = elevation 0.5..1.5 deg, 90 deg from the sun;")
    print("Y = Rec.709 luminance; sun/anti = horizon luminance toward the sun / away from it")
    print(f"{'sun el':>6}  {'sky':<8} {'zenith x':>8} {'zenith y':>8}  {'horiz x':>8} {'horiz y':>8}"
          f"  {'Yzen/Yhor':>9}  {'sun/anti':>9}")
    for elevation, m_ours, m_theirs in rows:
        for name, m in (("ours", m_ours), ("blender", m_theirs)):
            print(f"{elevation:+6.0f}  {name:<8} {m['zenith_xy'][0]:8.4f} {m['zenith_xy'][1]:8.4f}  "
                  f"{m['horizon_xy'][0]:8.4f} {m['horizon_xy'][1]:8.4f}  {m['zen_over_hor']:9.3f}"
                  f"  {m['sun_over_anti']:9.2f}")

    canvas = compose(panels, SUN_ELEVATIONS)
    output = Path(args.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    write_png(output, to_srgb8(canvas))
    import bpy
    caption = CAPTION.format(blender=bpy.app.version_string,
                             elevations=", ".join(f"{e:g}" for e in SUN_ELEVATIONS),
                             w=WIDTH, h=HEIGHT, white=WHITE)
    output.with_suffix(".txt").write_text(caption)
    print(f"\nwrote {output} and {output.with_suffix('.txt')} in {time.time() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
