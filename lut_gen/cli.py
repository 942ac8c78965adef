"""Command line: ``python -m lut_gen bake --out DIR`` and ``python -m lut_gen sample``."""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from .model.air_presets import AIR_PRESETS, FOG_PRESETS, air_preset_changes
from .model.atmosphere import PRESETS, AtmosphereParams, preset
from .tables.bake import RESOLUTIONS, bake
from .tables.scattering_orders import CONVERGED
from .store.cache import cached_bake, default_cache_root, key_for
from .passes.aerial import MULTIPLE_MODES, SINGLE_MODES
from .store.atomic import probe_writable
from .store.exr_header import LutError, read_key
from .store.exr_read import is_intact, load
from .store.exr_write import check_output_directory, removed_if_left_empty, save

EXIT_ERROR = 1


class TerminalProgress:
    """One self-updating line on a terminal, one line per finished stage otherwise."""

    def __init__(self, stream=sys.stderr, enabled: bool = True):
        self.stream, self.enabled = stream, enabled
        self.tty = hasattr(stream, "isatty") and stream.isatty()
        self.stage, self.start = None, time.perf_counter()

    def __call__(self, stage: str, fraction: float):
        if not self.enabled:
            return
        if stage != self.stage:
            self.stage = stage
        if self.tty:
            bar = "#" * int(fraction * 30)
            self.stream.write(f"\r  {stage:<24} [{bar:<30}] {fraction * 100:5.1f}%  {time.perf_counter() - self.start:6.1f}s")
            if fraction >= 1.0:
                self.stream.write("\n")
            self.stream.flush()
        elif fraction >= 1.0:
            self.stream.write(f"  {stage}: done at {time.perf_counter() - self.start:.1f}s\n")
            self.stream.flush()


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _add_param_options(parser: argparse.ArgumentParser):
    """One option per AtmosphereParams field, defaults from the dataclass."""
    group = parser.add_argument_group("atmosphere parameters (defaults: the clear-sky preset)")
    group.add_argument("--preset", default="clear-sky", metavar="NAME",
                       help=f"starting point for the options below: {', '.join(PRESET_NAMES)} (default clear-sky; "
                            "sample-2013 is the sample's three wavelengths as RGB, no ozone, no ground; the air "
                            "presets are the clear sky with another haze or a fog: morning-fog is visibility "
                            f"{FOG_PRESETS['morning-fog'][0]:g} m, {FOG_PRESETS['morning-fog'][1]:g} m deep)")
    defaults = AtmosphereParams()
    for f in dataclasses.fields(AtmosphereParams):
        default = getattr(defaults, f.name)
        if isinstance(default, bool):
            group.add_argument(_flag(f.name), action=argparse.BooleanOptionalAction, default=None,
                               help=f"enable/disable (default {default})")
        elif isinstance(default, tuple):
            group.add_argument(_flag(f.name), type=float, nargs=3, metavar=("R", "G", "B"), default=None,
                               help=f"1/m (default {' '.join(f'{v:.4g}' for v in default)})")
        else:
            group.add_argument(_flag(f.name), type=float, default=None, help=f"(default {default:g})")


# Atmosphere presets, then the air presets (a haze or a fog on the clear sky) the panel offers.
PRESET_NAMES = (*PRESETS, *AIR_PRESETS, *FOG_PRESETS)


def preset_params(name: str) -> AtmosphereParams:
    """The params of ``--preset NAME``; ValueError naming every preset for an unknown one."""
    if name in PRESETS:
        return preset(name)
    if name in AIR_PRESETS or name in FOG_PRESETS:
        return preset("clear-sky", **air_preset_changes(name))
    raise ValueError(f"unknown preset {name!r}; choose one of {', '.join(PRESET_NAMES)}")


def params_from_args(args) -> AtmosphereParams:
    changes = {}
    for f in dataclasses.fields(AtmosphereParams):
        value = getattr(args, f.name)
        if value is not None:
            changes[f.name] = tuple(value) if isinstance(value, list) else value
    return dataclasses.replace(preset_params(args.preset), **changes).validate()


def parse_resolution(text: str):
    if text in RESOLUTIONS:
        return text
    try:
        dims = tuple(int(v) for v in text.lower().split("x"))
    except ValueError:
        dims = ()
    if len(dims) != 4:
        raise argparse.ArgumentTypeError(
            f"resolution must be {' or '.join(RESOLUTIONS)} or HxVxSxT table sizes (e.g. 32x128x64x16), got {text!r}")
    return dims


def parse_orders(text: str):
    if text == CONVERGED:
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"orders must be a whole number or {CONVERGED!r}, got {text!r}") from None


def _common(parser):
    parser.add_argument("--resolution", type=parse_resolution, default="default",
                        help="draft, default (32x128x64x16) or HxVxSxT")
    parser.add_argument("--orders", type=parse_orders, default=None,
                        help="scattering orders: a count, or 'converged' (until the next adds under 0.5%%); "
                             "default 4 and a geometric tail, converged with fog")
    parser.add_argument("--quiet", action="store_true", help="no progress display")
    _add_param_options(parser)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m lut_gen", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p_bake = sub.add_parser("bake", help="bake the tables into a directory of EXR files")
    p_bake.add_argument("--out", required=True, type=path_argument, help="output directory")
    p_bake.add_argument("--overwrite", action="store_true", help="replace a different bake already in --out")
    _common(p_bake)
    p_sample = sub.add_parser("sample", help="bake (cached) and write a PNG preview of the sky")
    p_sample.add_argument("--out", type=path_argument, default=Path("build/sky_preview.png"),
                          help="PNG path (default build/sky_preview.png; a file this command did not write "
                               "is never replaced)")
    p_sample.add_argument("--luts", type=path_argument, default=None,
                          help=f"bake directory (default: cache under {default_cache_root()})")
    _common(p_sample)
    p_pass = sub.add_parser("pass", help="the light-scattering pass in numpy on render passes saved to EXR")
    p_pass.add_argument("--luts", required=True, type=path_argument, help="bake directory of the scene's tables")
    p_pass.add_argument("--passes", required=True, type=path_argument,
                        help="OpenEXR MultiLayer render with the Combined, Position and Depth passes")
    p_pass.add_argument("--inputs", required=True, type=path_argument,
                        help="camera, sun, shadow cascades and settings saved by the add-on (.npz)")
    p_pass.add_argument("--out", required=True, type=path_argument, help="output EXR (linear RGB)")
    p_pass.add_argument("--steps", type=int, help="override Num integration steps")
    p_pass.add_argument("--single", choices=SINGLE_MODES, help="override the single scattering mode")
    p_pass.add_argument("--multiple", choices=MULTIPLE_MODES, help="override the multiple scattering mode")
    p_pass.add_argument("--no-shafts", action="store_true", help="aerial perspective only")
    p_pass.add_argument("--technique", choices=sorted(TECHNIQUES),
                        help="override the scattering technique (epipolar sampling or brute-force ray marching)")
    return parser


def check_writable(path: Path):
    """Fail at once, naming ``path``, when it cannot be written (not after a long computation,
    naming a temporary file)."""
    if path.is_dir():
        raise ValueError(f"--out {path} is a folder; give a file name")
    try:
        probe_writable(path)
    except OSError as exc:
        raise ValueError(f"cannot write {path}: {exc.strerror or exc}") from None


def path_argument(text: str) -> Path:
    """A path option: an empty one is an error (Path("") would mean the current directory)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path is not allowed")
    return Path(text)


MAX_PASS_STEPS = 256
TECHNIQUES = {"epipolar": "EPIPOLAR_SAMPLING", "brute-force": "BRUTE_FORCE"}


def cmd_bake(args) -> int:
    params = params_from_args(args)
    key = key_for(params, args.resolution, args.orders)
    if is_intact(args.out, key):
        print(f"cache hit: {args.out} already holds this bake ({key}), verified; nothing to do")
        return 0
    with removed_if_left_empty(args.out):
        check_output_directory(args.out, key, overwrite=args.overwrite)
        if read_key(args.out) == key:
            print(f"{args.out} holds this bake damaged or incomplete; baking it again")
        progress = TerminalProgress(enabled=not args.quiet)
        start = time.perf_counter()
        luts = bake(params, resolution=args.resolution, orders=args.orders, progress=progress)
        save(luts, args.out, overwrite=args.overwrite)
    print(f"baked {key} in {time.perf_counter() - start:.1f}s ({luts.orders_used} scattering orders) -> {args.out}")
    return 0


PREVIEW_SOFTWARE = "lut_gen sample"


def cmd_sample(args) -> int:
    from .store.png import to_srgb8, write_png, written_by
    from .passes.preview import DEFAULT_SUN_ELEVATIONS, preview_image

    params = params_from_args(args)
    if args.out.exists() and not written_by(args.out, PREVIEW_SOFTWARE):
        raise ValueError(f"{args.out} exists and was not written by python -m lut_gen sample; not replacing "
                         "it (pass another --out, or delete the file)")
    key = key_for(params, args.resolution, args.orders)
    if args.luts is not None and args.luts.is_dir() and not is_intact(args.luts, key):
        # Before the bake, and in this command's words: sample has no --overwrite. (A folder
        # holding this bake intact is only read: it may be a read-only shared one.)
        check_output_directory(args.luts, key, option="--luts", can_overwrite=False)
    if not args.out.parent.exists():
        args.out.parent.mkdir(parents=True)
    luts, directory, hit = cached_bake(params, resolution=args.resolution, orders=args.orders,
                                       directory=args.luts, progress=TerminalProgress(enabled=not args.quiet))
    print(("cache hit: " if hit else "baked: ") + str(directory))
    write_png(args.out, to_srgb8(preview_image(luts)), software=PREVIEW_SOFTWARE)
    print(f"wrote {args.out} (sky at sun elevations {', '.join(f'{e:g}' for e in DEFAULT_SUN_ELEVATIONS)} deg)")
    return 0


def cmd_pass(args) -> int:
    from .store.exr_write import write_rgb
    from .passes.scattering_pass import check_passes_match, load_inputs, load_render_passes, scattering_pass

    check_writable(args.out)            # before the work, naming the file asked for
    passes = load_render_passes(args.passes)
    camera, sun, cascades, settings, resolution = load_inputs(args.inputs)
    check_passes_match(passes, resolution, args.passes, args.inputs)
    overrides = {"num_integration_steps": args.steps, "single_scattering_mode": args.single,
                 "multiple_scattering_mode": args.multiple, "enable_light_shafts": False if args.no_shafts else None,
                 "scattering_technique": TECHNIQUES.get(args.technique)}
    settings = dataclasses.replace(settings, **{k: v for k, v in overrides.items() if v is not None})
    if not 1 <= settings.num_integration_steps <= MAX_PASS_STEPS:
        # Memory grows as width x height x steps; the panel allows 5-100.
        raise ValueError(f"--steps must be from 1 to {MAX_PASS_STEPS}, got {settings.num_integration_steps}")
    start = time.perf_counter()
    radiance = scattering_pass(load(args.luts), passes["image"], passes["position"], passes["depth"],
                               camera, sun, cascades, settings)
    write_rgb(args.out, radiance)
    print(f"wrote {args.out} ({radiance.shape[1]}x{radiance.shape[0]}, {time.perf_counter() - start:.1f}s)")
    return 0


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return {"bake": cmd_bake, "sample": cmd_sample, "pass": cmd_pass}[args.command](args)
    except (LutError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("interrupted; nothing was written", file=sys.stderr)
        return 130
