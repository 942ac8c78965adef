"""Headless rendering: build or open a scene, wire it, render it to an image file.

Run through scripts/render.py, with Blender or with the bpy module:

    blender --background sample_blend/sample.blend --python scripts/render.py -- --output out.png
    .venv/bin/python scripts/render.py --sample --output build/sample.png

Exit status 0 on success; 1 with one "error: ..." line on stderr for anything wrong.
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time
from pathlib import Path

import bpy

from .. import lut_gen
from ..lut_gen.clouds.presets import CLOUD_PRESETS
from ..lut_gen.model.air_presets import AIR_PRESETS, FOG_PRESETS
from . import baking
from .progress_lines import ProgressLines, render_progress
from .scene import names
from .scene import sun as sun_lamps
from .scene.frame import adaptation, adaptation_plan
from .scene.setup import checks, wiring
from .scene.tables import luts, packed_tables
from .settings import apply_air_preset, validated_params

ENGINES = {"CYCLES": "CYCLES", "EEVEE": "BLENDER_EEVEE"}
# Looks for the sample scene (and any scene): sun (elevation, azimuth from +Y toward +X, in degrees)
# and the tone mapping's middle gray. The sample camera looks along +Y: azimuths near 0 put the
# sun ahead, behind the ridge, so its shafts come toward the camera at a low sun.
PRESETS = {
    "noon": dict(sun_elevation=60.0, sun_azimuth=150.0, middle_gray=0.18),
    # A darker key where the sun's aureole is in view: under 1% of the frame clips.
    "golden-hour": dict(sun_elevation=8.0, sun_azimuth=40.0, middle_gray=0.12),
    "sunset": dict(sun_elevation=1.5, sun_azimuth=20.0, middle_gray=0.12),
    "blue-hour": dict(sun_elevation=-4.0, sun_azimuth=20.0, middle_gray=0.10),
}

# --output's extension picks the format; no extension writes PNG and adds ".png".
FORMATS = {"": "PNG", ".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG", ".tif": "TIFF", ".tiff": "TIFF",
           ".exr": "OPEN_EXR"}


class BatchError(Exception):
    pass


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _finite_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def parse_args(argv):
    parser = argparse.ArgumentParser(prog="render.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--blend", type=Path, help="open this .blend first (default: the open file)")
    parser.add_argument("--sample", action="store_true", help="build the sample terrain scene first")
    parser.add_argument("--engine", choices=sorted(ENGINES), default="CYCLES")
    parser.add_argument("--resolution", default=None, help="WIDTHxHEIGHT (default: the scene's)")
    parser.add_argument("--samples", type=_positive_int, default=None, help="render samples (default: the scene's)")
    parser.add_argument("--preset", choices=sorted(PRESETS) + sorted(AIR_PRESETS) + sorted(FOG_PRESETS), default=None,
                        help="a look: sun and exposure (explicit --sun-elevation / --sun-azimuth win); or an "
                             "air preset: the day's haze (aerosol optical depth 0.3 or 0.03 at 550 nm, no fog) "
                             "or morning fog (300 m visibility, 50 m deep)")
    parser.add_argument("--clouds", choices=sorted(CLOUD_PRESETS), default=None,
                        help="turn the cloud layer on with this preset")
    parser.add_argument("--cloud-coverage", type=_finite_float, default=None,
                        help="turn the cloud layer on with this coverage (0-1; with --clouds: overrides it)")
    parser.add_argument("--sun-elevation", type=_finite_float, default=None, help="degrees above the horizon")
    parser.add_argument("--sun-azimuth", type=_finite_float, default=None, help="degrees from +Y toward +X")
    parser.add_argument("--pack", action="store_true",
                        help="store the tables in the .blend given with --blend and save it (for render "
                             "farms: workers then render without baking); --output is then optional")
    parser.add_argument("--output", type=Path, default=None,
                        help="image path; its extension picks the format (.png, .jpg, .tif, .exr: "
                             "scene-linear OpenEXR); with --frames, '#' characters are replaced by "
                             "the frame, and without '#' '_####' is added before the extension")
    parser.add_argument("--frames", default=None, help="START-END: render an animation's frames")
    parser.add_argument("--tables", choices=["default", "draft"], default="default")
    parser.add_argument("--atmosphere-model", choices=["precomputed", "analytic"], default=None,
                        help="the scene's Atmosphere Model (default: the file's); analytic needs no tables")
    parser.add_argument("--compositor-device", choices=["CPU", "GPU"], default=None,
                        help="where Blender's compositor runs our passes (default: the scene's setting); "
                             "GPU needs an OpenGL context (EGL in background mode)")
    args = parser.parse_args(argv)
    if args.output is None and not args.pack:
        parser.error("the following arguments are required: --output")
    if args.pack and not args.blend:
        parser.error("--pack stores the tables in the file given with --blend")
    return args


EGL_NOTE = ("EGL probe: using EGL for EEVEE's headless GPU context; Blender may print "
            "'EGL Error (0x3009): EGL_BAD_MATCH' while it tries configurations: harmless")


def egl_available() -> bool:
    """EEVEE aborts the whole process without EGL: probe it in a throw-away process."""
    probe = ("import bpy; s=bpy.context.scene; s.render.engine='BLENDER_EEVEE'; "
             "s.render.resolution_x=s.render.resolution_y=8; bpy.ops.render.render()")
    try:
        result = subprocess.run([sys.executable, "-c", probe], capture_output=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return result.returncode == 0


def prepare(args):
    if args.blend:
        if not args.blend.exists():
            raise BatchError(f"{args.blend} does not exist")
        bpy.ops.wm.open_mainfile(filepath=str(args.blend))
    if args.sample:
        print("scene: building the sample terrain", flush=True)
        from importlib import util
        path = Path(__file__).resolve().parent.parent / "sample_blend" / "build_sample.py"
        spec = util.spec_from_file_location("ols_build_sample", path)
        module = util.module_from_spec(spec)
        spec.loader.exec_module(module)
        bpy.ops.wm.read_factory_settings(use_empty=True)
        objects = module.build_sample_scene(bpy.context.scene)
        for obj in bpy.context.scene.objects:
            obj.select_set(obj == objects["terrain"])
        bpy.context.view_layer.objects.active = objects["terrain"]
    scene = bpy.context.scene
    if scene.camera is None:
        raise BatchError("the scene has no camera: add one and make it the scene camera")
    if sun_lamps.find_sun(scene) is None:
        raise BatchError("the scene has no Sun lamp: add one (or run Set Up Scene in Blender)")
    return scene


def apply_options(scene, args):
    scene.render.engine = ENGINES[args.engine]
    if args.resolution:
        try:
            width, height = (int(v) for v in args.resolution.lower().split("x"))
        except ValueError:
            raise BatchError(f"--resolution must be WIDTHxHEIGHT, got {args.resolution!r}") from None
        if not (4 <= width <= 65536 and 4 <= height <= 65536):
            raise BatchError(f"--resolution must be from 4x4 to 65536x65536 pixels, got {args.resolution!r}")
        scene.render.resolution_x, scene.render.resolution_y = width, height
        scene.render.resolution_percentage = 100
    if args.samples is not None:
        if args.engine == "CYCLES":
            scene.cycles.samples = args.samples
        else:
            scene.eevee.taa_render_samples = args.samples
    if getattr(args, "compositor_device", None):
        scene.render.compositor_device = args.compositor_device
    if getattr(args, "atmosphere_model", None):
        scene.ols.atmosphere_model = args.atmosphere_model.upper()
        if baking.needs_settling(scene):    # a file on the analytic model asked for the tables: bake them now
            baking.settle(scene, validated_params(scene.ols))
    sun = sun_lamps.find_sun(scene)
    if args.preset in AIR_PRESETS or args.preset in FOG_PRESETS:
        apply_air_preset(scene.ols, args.preset)
    elif args.preset:
        look = PRESETS[args.preset]
        scene.ols.middle_gray = look["middle_gray"]
        if args.sun_elevation is None:
            args.sun_elevation = look["sun_elevation"]
        if args.sun_azimuth is None:
            args.sun_azimuth = look["sun_azimuth"]
    if args.clouds or args.cloud_coverage is not None:
        settings = scene.ols
        if args.clouds:
            for name, value in CLOUD_PRESETS[args.clouds].items():
                setattr(settings, f"cloud_{name}", value)
        if args.cloud_coverage is not None:
            if not 0.0 <= args.cloud_coverage <= 1.0:
                raise BatchError(f"--cloud-coverage must be from 0 to 1, got {args.cloud_coverage}")
            settings.cloud_coverage = args.cloud_coverage
        settings.clouds_enabled = True
    if args.sun_elevation is not None or args.sun_azimuth is not None:
        direction = sun_lamps.direction_to_sun(sun)
        elevation = math.degrees(math.asin(max(-1.0, min(1.0, direction[2]))))
        azimuth = math.degrees(math.atan2(direction[0], direction[1]))
        sun_lamps.set_sun_angles(sun, args.sun_elevation if args.sun_elevation is not None else elevation,
                                 args.sun_azimuth if args.sun_azimuth is not None else azimuth)


def output_format(output: Path) -> str:
    try:
        return FORMATS[output.suffix.lower()]
    except KeyError:
        raise BatchError(f"cannot write {output.name}: --output must end in .png, .jpg, .tif or .exr") from None


def set_output_format(scene, file_format: str):
    settings = scene.render.image_settings
    settings.media_type = "IMAGE"           # Blender 5.0: a multilayer scene would refuse the format
    settings.file_format = file_format
    if file_format == "OPEN_EXR":
        settings.color_depth = "32"         # scene-linear radiance, full float
        settings.exr_codec = "ZIP"
    elif file_format == "JPEG":
        settings.color_mode = "RGB"
        settings.quality = 95
    scene.render.use_file_extension = True


def frame_pattern(output: Path) -> Path:
    """An animation's output path with '#' for the frame number: '_####' goes before the
    extension of a path that has none (Blender would append the number after the extension)."""
    if "#" in output.name:
        return output
    return output.with_name(f"{output.stem}_####{output.suffix}")


def parse_frames(text):
    try:
        start, end = (int(v) for v in text.split("-"))
    except ValueError:
        raise BatchError(f"--frames must be START-END, got {text!r}") from None
    if start > end:
        raise BatchError(f"--frames must run forward (START <= END), got {text!r}")
    return start, end


def render(scene, args):
    """Render the still or the frames; returns the files written."""
    wiring.match_engine(scene)
    output = args.output.resolve()
    file_format = output_format(output)
    frames = parse_frames(args.frames) if args.frames else None
    try:
        lut_gen.store.atomic.probe_writable(output)
    except OSError as exc:
        raise BatchError(f"cannot write {output}: {exc.strerror or exc}") from None
    set_output_format(scene, file_format)
    for problem in checks.ensure_passes(scene) + checks.camera_problems(scene, bpy.context.evaluated_depsgraph_get()):
        print(f"warning: {problem}", file=sys.stderr)
    if frames:
        if adaptation_plan.wanted(scene):
            # Measured from the animation's first frame, so this job's frames equal those of one
            # job over the whole range, whichever chunk it renders.
            try:
                adaptation_plan.ensure(scene, adaptation_plan.first_frame_needed(scene, frames[0]), frames[1])
            except adaptation_plan.PlanError as exc:
                raise BatchError(f"cannot measure the light adaptation: {exc}") from None
        scene.frame_start, scene.frame_end = frames
        scene.render.filepath = str(frame_pattern(output))
        if adaptation_plan.wanted(scene):
            print("render: light adaptation reads each frame's luminance back through a 1-pixel EXR "
                  "(the 'Saved: ...adapted_luminance_.exr' lines)")
        with render_progress():
            bpy.ops.render.render(animation=True)
        return [Path(scene.render.frame_path(frame=f)) for f in range(frames[0], frames[1] + 1)]
    scene.render.filepath = str(output)
    with render_progress(), adaptation.without_read_back():
        bpy.ops.render.render(write_still=True)
    return [output if output.suffix else output.with_name(output.name + ".png")]


def wire(scene, args):
    terrain = [o for o in scene.objects if o.select_get() and o.type == "MESH"]
    if wiring.wants_analytic(scene):
        print("scene: wiring it to the analytic model (no tables)", flush=True)
        wiring.wire_scene(scene, None, terrain, resolution=args.tables)
        return
    print("scene: baking or finding the tables", flush=True)
    directory = baking.bake_if_needed(validated_params(scene.ols), args.tables,
                                   progress=ProgressLines("bake"))
    print(f"scene: wiring it to the tables in {directory} (node groups, images, compositor)", flush=True)
    wiring.wire_scene(scene, directory, terrain, resolution=args.tables)
    print("scene: wired; preparing the render", flush=True)


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    start = time.perf_counter()
    try:
        if args.engine == "EEVEE":
            if not egl_available():
                raise BatchError("EEVEE needs EGL, which is missing here (Debian: apt install libegl1 "
                                 "libegl-mesa0 libgl1-mesa-dri); use --engine CYCLES")
            print(EGL_NOTE, flush=True)
        scene = prepare(args)
        if scene.get(names.WIRED_KEY) and scene[names.WIRED_KEY] != names.ANALYTIC_WIRED:
            # A wired file: its tables were re-baked on load where they were missing or damaged
            # (handlers.on_file_loaded); never touch, let alone render, tables that still fail.
            luts.verify_wired(scene[names.WIRED_KEY])
        if args.pack:
            if not scene.get(names.WIRED_KEY):
                wire(scene, args)           # with the file's own settings: the render options are not saved
            if scene[names.WIRED_KEY] == names.ANALYTIC_WIRED:
                raise BatchError("--pack: the scene uses the analytic atmosphere model, which has no tables "
                                 "to pack (a worker renders it without any)")
            size = packed_tables.pack(scene[names.WIRED_KEY])
            try:
                bpy.ops.wm.save_mainfile()
            except RuntimeError as exc:
                raise BatchError(f"cannot save {bpy.data.filepath}: {exc}") from None
            print(f"packed {size / 2**20:.0f} MiB of tables into {bpy.data.filepath}")
            if args.output is None:
                return 0
        apply_options(scene, args)
        if not scene.get(names.WIRED_KEY):
            wire(scene, args)
        written = render(scene, args)
    except (BatchError, wiring.SetupError, lut_gen.LutError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    missing = [str(path) for path in written if not path.exists()]
    if missing:
        print(f"error: Blender reported no error but did not write {', '.join(missing)}", file=sys.stderr)
        return 1
    print(f"total time {time.perf_counter() - start:.0f} s")
    print("rendered " + " ".join(str(path) for path in written))
    return 0
