"""The whole light-scattering compositor pass in numpy, per pixel: camera, render passes
(image, position, depth), sun shadow cascades and the baked tables -> radiance.

This is the twin the "OLS Aerial Perspective" and "OLS Light Shafts" compositor groups are
tested against, and the brute-force per-pixel reference the epipolar technique is measured
against. It runs on render passes saved to a multilayer EXR (``load_render_passes``).

Per pixel, with E the surface point (geometry) or the point where the view ray leaves the last
shadow cascade (sky):
    geometry: L_surface T(C->P) + S(C->E) x sun x scale
    sky:      L_sky + (S(C->E) - S_unshadowed(C->E)) x sun x scale
where S is the light-shaft in-scattering (lut_gen.passes.aerial.light_shafts, the sample's modes) and
S_unshadowed is Yusov 2013 eq. (8) over the multiple-scattering table, which the rendered sky
already holds. Without light shafts S = S_unshadowed (aerial perspective only). With the epipolar
technique both S and S_unshadowed come from its tables (lut_gen.passes.epipolar_air), not from
Yusov 2013 eq. (8) per pixel.
"""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import aerial, epipolar, epipolar_air, jitter
from ..clouds import shafts as cloud_shafts
from ..clouds import veil as cloud_veil
from ..clouds.layer import RANGES as CLOUD_RANGES
from ..store.atomic import atomic_path
from ..tables.lookup import Luts
from .shadow_map import CASCADE_COLORS, MIN_FORWARD_COSINE, Camera, ShadowCascades, select_cascade, visibility

SKY_DEPTH = 1e9                 # Cycles' depth pass holds 1e10 for the sky
SKY_CLIP_FRACTION = 0.95        # EEVEE's holds about the clip end (0.987 x clip end measured)


def sky_depth(clip_end: float) -> float:
    """Depth-pass values at or beyond this are sky (no geometry), for either engine."""
    return min(SKY_DEPTH, SKY_CLIP_FRACTION * clip_end)


@dataclass
class PassSettings:
    """The scene.ols controls the pass reads (the sample's names)."""
    enable_light_scattering: bool = True
    enable_light_shafts: bool = True
    num_integration_steps: int = 30
    single_scattering_mode: str = "LUT"
    multiple_scattering_mode: str = "UNOCCLUDED"
    smooth_shadows: bool = True
    jitter_steps: bool = False
    best_cascade_search: bool = True
    first_cascade_to_ray_march: int = 0
    show_cascades: bool = False
    scattering_scale: float = 0.5
    lighting_only: bool = False
    sun_strength: float = 10.0
    scattering_technique: str = "BRUTE_FORCE"        # or "EPIPOLAR_SAMPLING" (lut_gen.passes.epipolar)
    epipolar_slices: int = 512
    samples_per_slice: int = 256
    initial_sample_step: int = 16
    epipole_sampling_density: int = 2
    refinement_threshold: float = 0.03
    show_sampling: bool = False
    use_min_max_optimization: bool = True
    # The cloud layer (lut_gen.clouds.layer.RANGES): with Clouds on it shadows the air
    # (lut_gen.clouds.shafts).
    clouds_enabled: bool = False
    cloud_coverage: float = CLOUD_RANGES["coverage"][0]
    cloud_base: float = CLOUD_RANGES["base"][0]
    cloud_thickness: float = CLOUD_RANGES["thickness"][0]
    cloud_density: float = CLOUD_RANGES["density"][0]
    cloud_scale: float = CLOUD_RANGES["scale"][0]
    cloud_seed: int = 0
    cloud_offset: tuple = (0.0, 0.0)


def march_ends(camera: Camera, directions, position, depth, far: float, clouds=None, earth_radius=None):
    """(end points (..., 3), geometry mask): the surface where there is one, else the point at
    view depth ``far`` along the pixel's ray, or with ``clouds`` ((layer, map) of
    lut_gen.clouds.shafts.of_settings) the cloud it meets if that lies farther."""
    geometry = np.asarray(depth) < sky_depth(camera.clip_end)
    along = far / np.maximum(directions @ camera.forward, MIN_FORWARD_COSINE)
    if clouds is not None:
        along = np.maximum(along, cloud_shafts.march_distance(clouds[0], camera.position, directions, earth_radius))
    sky_end = camera.position + directions * along[..., None]
    return np.where(geometry[..., None], position, sky_end), geometry


def pixel_rays(image, sun_direction, camera: Camera):
    """(unit sun, width, height, (H, W, 3) view directions) of a pass over ``image``."""
    height, width = image.shape[:2]
    return (np.asarray(sun_direction, dtype=np.float64) / np.linalg.norm(sun_direction), width, height,
            camera.view_directions(width, height))


def scattering_pass(luts: Luts, image, position, depth, camera: Camera, sun_direction,
                    cascades: ShadowCascades | None, settings: PassSettings) -> np.ndarray:
    """(H, W, 3) radiance; arrays are (H, W, ...) with rows bottom to top, as Blender's."""
    image = np.asarray(image, dtype=np.float64)[..., :3]
    if not settings.enable_light_scattering:
        return image.copy()
    sun, width, height, directions = pixel_rays(image, sun_direction, camera)
    if settings.clouds_enabled:
        image = veil_surfaces(luts, image, position, depth, camera, sun, settings)
    far = cascades.far_depths[-1] if cascades is not None else None
    shafts = settings.enable_light_shafts and cascades is not None
    clouds = cloud_shafts.of_settings(settings) if shafts else None
    end, geometry = march_ends(camera, directions, position, depth, far if far is not None else 1.0, clouds,
                               luts.params.earth_radius)
    scale = settings.sun_strength * settings.scattering_scale
    transmittance = aerial.segment_transmittance(luts, camera.position, end)
    surface = image * transmittance * (0.0 if settings.lighting_only else 1.0)
    overlay = None
    if shafts and settings.scattering_technique == "EPIPOLAR_SAMPLING":
        # The aerial perspective's in-scattering and the shafts, both from the epipolar tables.
        unshadowed, difference, overlay = epipolar_pass(luts, camera, end, sun, cascades, settings, width, height,
                                                        clouds)
    else:
        unshadowed = aerial.segment_inscattering(luts, camera.position, end, sun)
        difference = light_shafts(luts, camera, end, sun, cascades, settings, unshadowed, clouds) if shafts else 0.0
    # No negative light: the shafts cannot take out more than a pixel holds (a render cropped to
    # 1 x 1). The light-shaft pass nodes: sky_shadow_share.
    share = sky_shadow_share(image, unshadowed * scale, geometry)
    out = np.maximum(np.where(geometry[..., None], surface + unshadowed * scale, image) + difference * scale * share,
                     0.0)
    if settings.show_cascades and cascades is not None:
        out = np.where(geometry[..., None], out * cascade_tint(cascades, end, camera, settings), out)
    if overlay is not None:
        out = np.where(overlay[..., None] > 0.5, sampling_red(out), out)
    return out


def veil_surfaces(luts: Luts, image, position, depth, camera: Camera, sun, settings: PassSettings):
    """The render's surfaces behind the cloud layer's veil ("OLS Cloud Veil", lut_gen.clouds.veil),
    before the air hazes them."""
    layer, cloud = cloud_shafts.of_settings(settings)
    light = cloud_veil.VeilLight.of(luts, layer, sun)
    through, glow = cloud_veil.veil(layer, cloud, light, camera.position, position, sun)
    geometry = np.asarray(depth) < sky_depth(camera.clip_end)
    return cloud_veil.veiled(image, through, glow, settings.sun_strength, geometry)


def sky_shadow_share(image, unshadowed, geometry):
    """(..., 3) the share of the shafts' darkening a pixel takes: 1 on surfaces; on the sky the
    rendered sky over the unshadowed air light in front of it, at most 1. A sky pixel holds at
    least that air light, so it takes the whole darkening; an antialiased pixel on a silhouette
    holds part sky, part a dark surface, yet its depth says sky, and the whole darkening left it
    below zero, clamped per channel to teal (EEVEE, sun behind a peak). Each channel now loses
    the shadowed fraction of its air light, as a darker sky seen through the same air would: the
    pixel darkens with every channel kept, its hue nearly so (the fractions differ by channel)."""
    share = np.clip(np.asarray(image) / np.maximum(unshadowed, 1e-20), 0.0, 1.0)     # >= 0: filter ringing
    return np.where(np.asarray(geometry)[..., None], 1.0, share)


def sampling_red(radiance):
    """Show Sampling's red, bright enough to read as red through any exposure: four times the
    pixel's largest channel (plus a floor for black pixels) in red, nothing in green and blue."""
    red = 4.0 * np.max(radiance, axis=-1) + 1e-3
    return np.stack([red, np.zeros_like(red), np.zeros_like(red)], axis=-1)


def epipolar_pass(luts: Luts, camera: Camera, end, sun, cascades: ShadowCascades, settings: PassSettings,
                  width: int, height: int, clouds=None):
    """(unshadowed in-scattering, shadowed minus unshadowed, Show Sampling's overlay or None)
    per unit sun of every pixel, from the epipolar tables (lut_gen.passes.epipolar, epipolar_air)."""
    wanted = epipolar.for_render(epipolar.settings_from(settings), width, height)
    frame = epipolar.frame_for(camera, sun, width, height, float(cascades.far_depths[-1]), wanted,
                               epipolar.cloud_reach(clouds, camera, width, height, luts.params.earth_radius))
    tables = epipolar.build_tables(frame, cascades, camera, wanted, settings.smooth_shadows,
                                   settings.best_cascade_search, settings.first_cascade_to_ray_march, luts,
                                   settings.single_scattering_mode == "INTEGRATION", clouds)
    overlay = (epipolar.sampling_overlay(frame, tables.marched, camera, width, height)
               if settings.show_sampling else None)
    air = epipolar_air.air_frame(frame, camera)
    air_tables = epipolar_air.build(luts, air, camera.position)
    unshadowed, difference = epipolar_air.light_shaft_difference(
        luts, camera, end, frame, tables, air, air_tables, settings.single_scattering_mode,
        settings.multiple_scattering_mode)
    return unshadowed, difference, overlay


def light_shafts(luts: Luts, camera: Camera, end, sun, cascades: ShadowCascades, settings: PassSettings,
                 unshadowed, clouds=None):
    """Shadowed minus ``unshadowed`` in-scattering per unit sun of every pixel by brute-force
    ray marching (Yusov 2013 eq. 8 per pixel); ``clouds`` shadow the air too
    (lut_gen.clouds.shafts)."""
    def is_lit(points):
        return visibility(cascades, points, camera, settings.smooth_shadows,
                          settings.best_cascade_search, settings.first_cascade_to_ray_march)
    if clouds is not None:
        is_lit = cloud_shafts.sun_visibility(is_lit, *clouds, sun)
    offsets = jitter.step_offsets(*np.shape(end)[:2], settings.jitter_steps)      # end: (H, W, 3)
    shadowed = aerial.light_shafts(luts, camera.position, end, sun, is_lit, settings.num_integration_steps,
                                   settings.single_scattering_mode, settings.multiple_scattering_mode, offsets)
    if not settings.jitter_steps:
        return shadowed - unshadowed
    return jitter.neighbourhood_mean(shadowed - unshadowed, np.linalg.norm(end - camera.position, axis=-1))


def cascade_tint(cascades: ShadowCascades, points, camera: Camera, settings: PassSettings):
    """(..., 3) colour of the cascade each point falls in (white outside all cascades)."""
    light_xy = np.asarray(points) @ cascades.frame[:2].T
    view_depth = (np.asarray(points) - camera.position) @ camera.forward
    index = select_cascade(cascades, light_xy, view_depth, settings.best_cascade_search)
    colors = np.vstack([CASCADE_COLORS[:cascades.count], [(1.0, 1.0, 1.0)]])
    return colors[index]


PASS_CHANNELS = {"image": ("Combined", "RGB"), "position": ("Position", "XYZ"), "depth": ("Depth", "Z")}


def load_render_passes(path) -> dict:
    """Image (H, W, 3), position (H, W, 3) and depth (H, W) from an OpenEXR MultiLayer file
    saved by Blender (channels "<layer>.Combined.R", "<layer>.Position.X", "<layer>.Depth.Z"),
    rows bottom to top. ValueError naming the missing passes."""
    import OpenEXR
    path = Path(path)
    try:
        with OpenEXR.File(str(path), separate_channels=True) as exr:
            # Blender writes each pass as a part of a multi-part file.
            channels = {name: np.asarray(c.pixels) for part in exr.parts for name, c in part.channels.items()}
    except Exception as exc:  # OpenEXR raises bare RuntimeErrors for unreadable files
        raise ValueError(f"{path}: not a readable EXR file ({exc})") from exc
    result, missing = {}, []
    for key, (pass_name, components) in PASS_CHANNELS.items():
        found = []
        for component in components:
            name = next((n for n in channels if n.endswith(f"{pass_name}.{component}")
                         or n == f"{pass_name}.{component}"), None)
            found.append(None if name is None else channels[name])
        if any(c is None for c in found):
            missing.append(pass_name)
            continue
        stacked = np.stack(found, axis=-1).astype(np.float64)[::-1]
        result[key] = stacked[..., 0] if len(components) == 1 else stacked
    if missing:
        raise ValueError(f"{path}: missing render passes {', '.join(missing)}; enable them in the "
                         "view layer's Passes panel and save as OpenEXR MultiLayer")
    sizes = {key: value.shape[:2] for key, value in result.items()}
    if len(set(sizes.values())) != 1:
        raise ValueError(f"{path}: its passes differ in size ({', '.join(f'{k} {w}x{h}' for k, (h, w) in sizes.items())}); "
                         "save them from one render")
    return result


# -- pass inputs on disk: what the twin needs besides the render passes ---------------------------

def save_inputs(path, camera: Camera, sun_direction, cascades: ShadowCascades, settings: PassSettings,
                resolution=None) -> Path:
    """Camera, sun, shadow cascades and settings of a frame as one .npz (atomic write), and the
    render's (width, height) when given (``pass`` then refuses passes of another size)."""
    arrays = dict(camera_position=camera.position, camera_rotation=camera.rotation,
                  tan_half_fov=np.asarray(camera.tan_half_fov), clip_end=np.asarray(camera.clip_end),
                  sun_direction=np.asarray(sun_direction, dtype=np.float64), frame=cascades.frame,
                  centers=cascades.centers, halves=cascades.halves, far_depths=cascades.far_depths,
                  depths=cascades.depths, settings=np.asarray(json.dumps(dataclasses.asdict(settings))))
    if resolution is not None:
        arrays["resolution"] = np.asarray(resolution, dtype=np.int64)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays)
    return Path(path)


def check_passes_match(passes: dict, resolution, passes_path, inputs_path):
    """ValueError unless the render passes are finite and of the size the inputs were saved for."""
    height, width = passes["image"].shape[:2]
    if resolution is not None and (width, height) != tuple(resolution):
        raise ValueError(f"{passes_path} is {width}x{height} but {inputs_path} was exported for a "
                         f"{resolution[0]}x{resolution[1]} render; export the inputs of the same frame again")
    for key, (name, _) in PASS_CHANNELS.items():
        if not np.all(np.isfinite(passes[key])):
            raise ValueError(f"{passes_path}: its {name} pass holds NaN or infinite values; render the passes again")


def load_inputs(path):
    """(camera, sun direction, cascades, settings, the render's (width, height) or None for
    inputs saved without it) saved by ``save_inputs``; ValueError for a file that is not one."""
    try:
        with np.load(Path(path)) as data:
            camera = Camera(data["camera_position"], data["camera_rotation"], tuple(data["tan_half_fov"]),
                            float(data["clip_end"]))
            cascades = ShadowCascades(data["frame"], data["centers"], data["halves"], data["far_depths"], data["depths"])
            settings = PassSettings(**json.loads(str(data["settings"])))
            sun = data["sun_direction"]
            resolution = tuple(int(v) for v in data["resolution"]) if "resolution" in data.files else None
    except (OSError, KeyError, ValueError, TypeError, RecursionError) as exc:
        raise ValueError(f"{path}: not a pass-inputs file saved by the add-on ({exc})") from None
    for name, value in (("camera position", camera.position), ("camera rotation", camera.rotation),
                        ("field of view", camera.tan_half_fov), ("sun direction", sun),
                        ("shadow cascades", cascades.depths), ("cascades' light frame", cascades.frame),
                        ("cascades' centres", cascades.centers), ("cascades' extents", cascades.halves),
                        ("cascades' far depths", cascades.far_depths)):
        if not np.all(np.isfinite(np.asarray(value, dtype=np.float64))):
            raise ValueError(f"{path}: the {name} holds NaN or infinite values; export the inputs again")
    if not camera.clip_end > 0.0:           # +inf (no clip end) is allowed, NaN and <= 0 are not
        raise ValueError(f"{path}: the camera's clip end is {camera.clip_end}; export the inputs again")
    return camera, sun, cascades, settings, resolution
