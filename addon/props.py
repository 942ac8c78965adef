"""The add-on's controls: one PropertyGroup on the Scene (``scene.ols``).

Every control of the sample's three GUI control sets (basic, additional, tone mapping), with
the sample's names in snake_case and the Intel sample's defaults and ranges. The windowing-only
controls (full screen, VSync) and the pure GPU-performance switches of the sample (cascade
processing mode, min/max texture format) have no meaning in Blender and are left out.

How the render reads them (clamped, capped, mapped to table parameters) is settings.py.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty

from ..lut_gen.clouds.layer import RANGES as CLOUD_RANGES
from ..lut_gen.clouds.presets import CLOUD_PRESETS
from ..lut_gen.model.air_presets import AIR_PRESETS, FOG_PRESETS
from ..lut_gen.model.atmosphere import DEFAULT_GROUND_ALBEDO
from . import baking
from .scene import clouds, names
from .scene.setup import compositor, wiring
from .scene.tables import wired_bake
from .settings import (DEFAULT_MIE_COLOR, DEFAULT_RAYLEIGH_COLOR, FOG_HEIGHT_MAX_M, FOG_HEIGHT_MIN_M,
                       FOG_VISIBILITY_MAX_M, WITHOUT_EFFECT, apply_air_preset, atmosphere_params)

REBAKE_DELAY_S = 0.75     # wait for a slider drag to settle before re-baking


def _rebake_soon(settings, context):
    """Changing the media re-bakes the tables in the background and swaps them into a wired
    scene (interactive sessions only; scripts call bpy.ops.ols.bake_luts themselves). Under the
    analytic model the groups are rebuilt at once instead, in scripts too: nothing to bake."""
    if context.scene is not None and wiring.wants_analytic(context.scene) and wired_bake.is_analytic(context.scene):
        wiring.use_model(context.scene)
        return
    if bpy.app.background or context.scene is None or not context.scene.get(names.WIRED_KEY):
        return
    if bpy.app.timers.is_registered(_start_rebake):
        bpy.app.timers.unregister(_start_rebake)
    bpy.app.timers.register(_start_rebake, first_interval=REBAKE_DELAY_S)


def _sync_compositor(settings, context):
    """Compositor inputs follow the settings (drivers on a compositor tree do not reach
    renders). Steps, modes and cascade settings rebuild the light-shaft groups, but not here:
    the depsgraph update that follows each change in the UI, a still's render_pre and each
    animation frame's frame_change_pre (which comes before the frame's compositor depsgraph)
    rebuild them once. Rebuilt in the callbacks, a script setting ten controls would rebuild
    them ten times, ~1 s each."""
    if context.scene is not None:
        compositor.sync_settings(context.scene)


def _sync_clouds(settings, context):
    """The cloud map follows the seed (0.36 s to make), the shadow layer and the compositor's
    cloud veil the on/off switch."""
    if context.scene is not None:
        clouds.sync(context.scene)
        compositor.sync_settings(context.scene)


def _switch_model(settings, context):
    """A wired scene follows the Atmosphere Model at once: the analytic groups, or the tables
    from the cache (switching back and forth never re-bakes). Tables not baked yet bake in the
    background in the UI; a script bakes them with bpy.ops.ols.bake_luts, and a render settles
    first (baking.settle), so no frame renders the model it was not asked for."""
    scene = context.scene
    if scene is None or not scene.get(names.WIRED_KEY):
        return
    if settings.atmosphere_model == "ANALYTIC":
        wiring.use_model(scene)
        return
    if not wired_bake.is_analytic(scene):
        return                          # on the tables already
    resolution = scene.get(names.RESOLUTION_KEY, "default")
    try:
        params = atmosphere_params(settings).validate()
    except ValueError as exc:
        print(f"Outdoor Light Scattering: no tables for these settings: {exc}")
        return
    if baking.is_baked(params, resolution):
        wiring.use_model(scene, baking.bake_directory(params, resolution))
    elif not bpy.app.background:
        baking.invoke_bake_in_window(resolution)


def _apply_air_preset(settings, context):
    key = settings.air_preset.lower().replace("_", "-")
    if key in AIR_PRESETS or key in FOG_PRESETS:
        apply_air_preset(settings, key)     # the controls' own updates re-bake the tables


def _apply_cloud_preset(settings, context):
    key = settings.cloud_preset.lower().replace("_", "-")
    for name, value in CLOUD_PRESETS.get(key, {}).items():
        setattr(settings, f"cloud_{name}", value)


def _capture_day_range(settings, context):
    """Animate Sun spreads the day over the frame range it was turned on with, not over
    whatever range a later (chunked) render sets."""
    if settings.animate_sun and context.scene is not None:
        settings.day_start_frame, settings.day_end_frame = context.scene.frame_start, context.scene.frame_end


def _start_rebake():
    baking.invoke_bake_in_window(bpy.context.scene.get(names.RESOLUTION_KEY, "default"))
    return None


def _d(name, text):
    """Tooltip for control ``name``; a control without effect here says why."""
    return f"{text} {WITHOUT_EFFECT[name]}" if name in WITHOUT_EFFECT else text


class OLSSettings(bpy.types.PropertyGroup):
    """Outdoor Light Scattering settings (the sample's GUI), stored on the scene."""

    control_set: EnumProperty(
        name="Control Set",
        description="Which of the sample's three control sets the panel shows",
        items=(
            ("BASIC", "Basic", "Light scattering, epipolar sampling and shadow map controls"),
            ("ADDITIONAL", "Additional", "Scattering modes, shadow cascades and atmosphere media"),
            ("TONE_MAPPING", "Tone Mapping", "HDR to LDR conversion controls"),
            ("CLOUDS", "Clouds", "A cloud layer in the sky, lit by the sun through the atmosphere"),
        ),
        default="BASIC",
    )

    # -- basic ------------------------------------------------------------------------------
    enable_light_scattering: BoolProperty(
        name="Enable Light Scattering",
        description=_d("enable_light_scattering", "Enable or disable the light scattering effect"),
        default=True,
        update=_sync_compositor,
    )
    enable_light_shafts: BoolProperty(
        name="Enable Light Shafts",
        description=_d("enable_light_shafts",
                       "Render shafts of light. When disabled, a simpler algorithm that ignores "
                       "shadows computes the scattering integral"),
        default=True,
        update=_sync_compositor,
    )
    scattering_technique: EnumProperty(
        name="Scattering Technique",
        description=_d("scattering_technique", "How the scattering effect is calculated"),
        items=(
            ("EPIPOLAR_SAMPLING", "Epipolar Sampling",
             "Calculate the scattering effect using epipolar sampling"),
            ("BRUTE_FORCE", "Brute Force Ray Marching",
             "Calculate the scattering effect for each screen pixel without 1D min/max tree "
             "optimization: the reference ground-truth image"),
        ),
        default="EPIPOLAR_SAMPLING",
        update=_sync_compositor,
    )
    shadow_map_resolution: EnumProperty(
        name="Shadow Map Resolution",
        description=_d("shadow_map_resolution",
                       "Resolution of the sun shadow map (the number of cascades is set in the "
                       "additional controls). A render uses at most the power of two at or above 8 "
                       "texels per pixel of its larger side (4096 from 257 pixels up): finer maps "
                       "change nothing it can show"),
        items=(
            ("512", "512 x 512", "512 x 512 shadow map"),
            ("1024", "1024 x 1024", "1024 x 1024 shadow map"),
            ("2048", "2048 x 2048", "2048 x 2048 shadow map"),
            ("4096", "4096 x 4096", "4096 x 4096 shadow map"),
        ),
        default="1024",
        update=_sync_compositor,
    )
    num_integration_steps: IntProperty(
        name="Num Integration Steps",
        description=_d("num_integration_steps",
                       "Number of steps of the numerical single scattering integral. Used only "
                       "when light shafts are off and single scattering mode is Integration"),
        default=30, min=5, max=100,
        update=_sync_compositor,
    )
    epipolar_slices: IntProperty(
        name="Epipolar Slices",
        description=_d("epipolar_slices",
                       "Number of epipolar slices. More slices give higher quality at higher "
                       "cost; at least half the largest image dimension looks good. A render uses "
                       "at most its perimeter in pixels (more are under a pixel apart)"),
        default=512, min=32, max=2048,
        update=_sync_compositor,
    )
    samples_per_slice: IntProperty(
        name="Total Samples in Slice",
        description=_d("samples_per_slice",
                       "Number of samples along each epipolar slice; at least half the largest "
                       "image dimension looks good. A render uses at most twice its diagonal in "
                       "pixels (more are under a pixel apart)"),
        default=256, min=32, max=2048,
        update=_sync_compositor,
    )
    initial_sample_step: IntProperty(
        name="Initial Sample Step",
        description=_d("initial_sample_step",
                       "Step between the initial ray marching samples along each epipolar line. "
                       "A lower step places more samples and gives higher quality"),
        default=16, min=2, max=64,
        update=_sync_compositor,
    )
    epipole_sampling_density: IntProperty(
        name="Epipole Sampling Density",
        description=_d("epipole_sampling_density",
                       "Additional increase of the initial ray marching sample density near the "
                       "epipole, for the strong forward Mie scattering around the sun"),
        default=2, min=1, max=32,
        update=_sync_compositor,
    )
    refinement_threshold: FloatProperty(
        name="Refinement Threshold",
        description=_d("refinement_threshold",
                       "Refinement accuracy: a smaller threshold places more ray marching samples "
                       "at discontinuities of light intensity"),
        default=0.03, min=0.001, max=0.5, precision=3, step=0.1,
        update=_sync_compositor,
    )
    scattering_scale: FloatProperty(
        name="Scattering Scale",
        description="Intensity of the scattering effect (almost no effect with automatic "
                    "exposure tone mapping)",
        default=0.5, min=0.0, soft_max=2.0, max=100.0,
        update=_sync_compositor,
    )
    show_sampling: BoolProperty(
        name="Show Sampling",
        description=_d("show_sampling",
                       "Visualize the epipolar sampling structure: thick red dots are ray marching "
                       "samples, thin red dots interpolation samples (epipolar sampling only)"),
        default=False,
        update=_sync_compositor,
    )
    use_min_max_optimization: BoolProperty(
        name="1D Min/Max Optimization",
        description=_d("use_min_max_optimization",
                       "Skip the shadow-map taps of ray-march points that min/max mipmaps of the cascades show "
                       "surely lit or surely shadowed (epipolar sampling; speed only, the same picture)"),
        default=True,
        update=_sync_compositor,
    )
    optimize_sample_locations: BoolProperty(
        name="Optimize Sample Locations",
        description=_d("optimize_sample_locations", "Fix oversampling along short epipolar lines"),
        default=True,
    )
    correct_depth_breaks: BoolProperty(
        name="Correction at Depth Breaks",
        description=_d("correct_depth_breaks",
                       "Extra pass that ray marches the pixels whose scattering cannot be "
                       "unwarped precisely from the epipolar image"),
        default=False,
    )
    show_depth_breaks: BoolProperty(
        name="Show Depth Breaks",
        description=_d("show_depth_breaks",
                       "Show in green the pixels the depth-break correction pass recomputes "
                       "(only with Correction at Depth Breaks)"),
        default=False,
    )
    lighting_only: BoolProperty(
        name="Lighting Only",
        description=_d("lighting_only", "Show the light scattering effects only"),
        default=False,
        update=_sync_compositor,
    )

    # -- additional -------------------------------------------------------------------------
    single_scattering_mode: EnumProperty(
        name="Single Scattering",
        description=_d("single_scattering_mode", "How single scattering is computed"),
        items=(
            ("NONE", "None", "Do not compute single scattering"),
            ("INTEGRATION", "Integration",
             "Compute single scattering with numerical integration during ray marching"),
            ("LUT", "LUT",
             "Compute single scattering with look-ups into the precomputed table: ray marching "
             "only measures the lit length of the ray"),
        ),
        default="LUT",
        update=_sync_compositor,
    )
    multiple_scattering_mode: EnumProperty(
        name="Multiple Scattering",
        description=_d("multiple_scattering_mode", "How higher order scattering is added"),
        items=(
            ("NONE", "None", "Do not compute multiple scattering"),
            ("OCCLUDED", "Occluded",
             "Multiple scattering from the illuminated part of the view ray only"),
            ("UNOCCLUDED", "Unoccluded",
             "Higher order scattering from the whole view ray"),
        ),
        default="UNOCCLUDED",
        update=_sync_compositor,
    )
    num_cascades: IntProperty(
        name="Num Cascades",
        description=_d("num_cascades", "Number of shadow map cascades"),
        default=6, min=1, max=8,
        update=_sync_compositor,
    )
    show_cascades: BoolProperty(
        name="Show Cascades",
        description=_d("show_cascades", "Visualize the shadow map cascades"),
        default=False,
        update=_sync_compositor,
    )
    jitter_steps: BoolProperty(
        name="Jitter Steps",
        description=_d("jitter_steps",
                       "Brute force: offset each pixel's march steps by a fixed per-pixel noise, so the banding "
                       "of few steps becomes fine noise"),
        default=False,
        update=_sync_compositor,
    )
    smooth_shadows: BoolProperty(
        name="Smooth Shadows",
        description=_d("smooth_shadows", "Soften shadow edges by bilinear filtering of 4 shadow-map samples"),
        default=True,
        update=_sync_compositor,
    )
    best_cascade_search: BoolProperty(
        name="Best Cascade Search",
        description=_d("best_cascade_search",
                       "Use the smallest cascade a point projects into instead of the cascade "
                       "depth ranges, for better shadow quality"),
        default=True,
        update=_sync_compositor,
    )
    cascade_partitioning_factor: FloatProperty(
        name="Partitioning Factor",
        description=_d("cascade_partitioning_factor",
                       "Blend between linear (0) and logarithmic (1) cascade distribution"),
        default=0.95, min=0.0, max=1.0, subtype='FACTOR',
        update=_sync_compositor,
    )
    first_cascade_to_ray_march: IntProperty(
        name="First Cascade to Ray March",
        description=_d("first_cascade_to_ray_march",
                       "Smallest cascade considered during ray marching; the one or two smallest "
                       "can usually be skipped without visible loss"),
        default=2, min=0, max=7,
        update=_sync_compositor,
    )
    extinction_evaluation_mode: EnumProperty(
        name="Extinction Evaluation",
        description=_d("extinction_evaluation_mode",
                       "How extinction is evaluated per pixel (no effect on quality)"),
        items=(
            ("EPIPOLAR", "Epipolar",
             "Extinction from the epipolar extinction image, unwarped per pixel (faster)"),
            ("PER_PIXEL", "Per Pixel", "Analytical extinction evaluated for each pixel"),
        ),
        default="EPIPOLAR",
    )
    refinement_criterion: EnumProperty(
        name="Refinement Criterion",
        description=_d("refinement_criterion", "What decides where ray marching samples are refined"),
        items=(
            ("DEPTH", "Depth", "Refine where depth differs"),
            ("INSCATTERING", "Inscattering",
             "Refine where the coarse unshadowed inscattering differs (no banding near the "
             "epipole in outer space views)"),
        ),
        default="INSCATTERING",
    )
    use_custom_scattering_coeffs: BoolProperty(
        name="Use Custom Scattering Coeffs",
        description="Set custom Rayleigh and Mie scattering coefficients with the colours below "
                    "(the tables are re-baked)",
        default=False,
        update=_rebake_soon,
    )
    rayleigh_color: FloatVectorProperty(
        name="Rayleigh Color",
        description="Rayleigh scattering coefficients relative to the default blue coefficient "
                    "(the default colour gives the default air)",
        subtype='COLOR', size=3, default=DEFAULT_RAYLEIGH_COLOR, min=0.0, soft_max=1.0, max=10.0,
        update=_rebake_soon,
    )
    mie_color: FloatVectorProperty(
        name="Mie Color",
        description="Mie scattering coefficients relative to the Atmosphere preset's aerosol (white: "
                    "the preset's own)",
        subtype='COLOR', size=3, default=DEFAULT_MIE_COLOR, min=0.0, soft_max=1.0, max=10.0,
        update=_rebake_soon,
    )
    aerosol_density: FloatProperty(
        name="Aerosol Density",
        description="Aerosol (Mie) particle density relative to the default (the tables are re-baked)",
        default=1.0, min=0.1, max=5.0,
        update=_rebake_soon,
    )
    aerosol_absorption: FloatProperty(
        name="Aerosol Absorption",
        description="Aerosol absorption relative to aerosol scattering: Mie extinction = "
                    "scattering x (1 + absorption) (the tables are re-baked)",
        default=0.1, min=0.0, max=5.0,
        update=_rebake_soon,
    )
    air_preset: EnumProperty(
        name="Air Preset",
        description="Set the air of a common day: a haze by its aerosol optical depth at 550 nm (the clear "
                    "sky's is 0.11), or a fog by its visibility and depth (the controls stay editable; the "
                    "tables are re-baked)",
        items=(("CUSTOM", "Custom", "The aerosol density and fog as set"),
               *((key.upper().replace("-", "_"), key.replace("-", " ").capitalize(),
                  f"Aerosol optical depth {depth:g} at 550 nm, no fog") for key, depth in AIR_PRESETS.items()),
               *((key.upper().replace("-", "_"), key.replace("-", " ").capitalize(),
                  f"Fog of {visibility:g} m visibility, {height:g} m deep (the haze as set)")
                 for key, (visibility, height) in FOG_PRESETS.items())),
        default="CUSTOM",
        update=_apply_air_preset,
    )
    atmosphere_model: EnumProperty(
        name="Atmosphere Model",
        description="What computes the sky, the terrain's light and the aerial perspective",
        items=[
            ("PRECOMPUTED", "Precomputed",
             "The baked tables: multiple scattering, the Earth's curvature, twilight and light shafts"),
            ("ANALYTIC", "Analytic (Hoffman-Preetham)",
             "Hoffman & Preetham's constant-density model: single scattering in closed form, no bake, no "
             "table file, updates at once; light shafts in closed form; a preview, with no twilight"),
        ],
        default="PRECOMPUTED",
        update=_switch_model,
    )
    atmosphere_preset: EnumProperty(
        name="Atmosphere",
        description="The media the tables are baked for (the tables are re-baked)",
        items=[
            ("CLEAR_SKY", "Clear Sky (spectral)",
             "Spectral bake converted with the CIE observer, ozone layer and a lit ground: the colours of a "
             "real clear sky, blue twilight zenith included"),
            ("SAMPLE_2013", "Sample 2013",
             "The sample's own media: three wavelengths used directly as RGB, no ozone, black ground "
             "(the media of the seed's figures, with this version's numerics)"),
        ],
        default="CLEAR_SKY",
        update=_rebake_soon,
    )
    ground_albedo: FloatProperty(
        name="Ground Albedo",
        description="Reflectance of the ground under the atmosphere: lights the sky from below and is the "
                    "ground seen below the horizon (0.2: vegetation and soil; Clear Sky preset only; "
                    "the tables are re-baked)",
        default=DEFAULT_GROUND_ALBEDO, min=0.0, max=1.0,
        update=_rebake_soon,
    )
    ozone_column: FloatProperty(
        name="Ozone (DU)",
        description="Ozone column in Dobson units (300: the global mean; 0: no ozone). Its Chappuis band "
                    "keeps the twilight zenith blue (Clear Sky preset only; the tables are re-baked)",
        default=300.0, min=0.0, max=600.0,
        update=_rebake_soon,
    )
    fog_visibility: FloatProperty(
        name="Fog Visibility",
        description="Meteorological visibility in the fog at the ground, in metres (0: no fog; 100 m "
                    "to 50 km). A grey, forward-scattering layer of droplets beside the haze: distant "
                    "hills fade into white and the sun's disc pales (the tables are re-baked)",
        default=0.0, min=0.0, max=FOG_VISIBILITY_MAX_M, soft_max=5000.0, unit="LENGTH",
        update=_rebake_soon,
    )
    fog_height: FloatProperty(
        name="Fog Height",
        description="The fog layer's scale height in metres: its density falls by e over this height "
                    "(10-500 m; the tables are re-baked)",
        default=50.0, min=FOG_HEIGHT_MIN_M, max=FOG_HEIGHT_MAX_M, unit="LENGTH",
        update=_rebake_soon,
    )
    animate_sun: BoolProperty(
        name="Animate Sun",
        description="Animate the sun across the sky: a day at 45 deg N from an hour before sunrise "
                    "(Day Start Frame) to an hour after sunset (Day End Frame). Turning it on takes "
                    "the scene's frame range",
        default=False,
        update=_capture_day_range,
    )
    day_start_frame: IntProperty(
        name="Day Start Frame",
        description="Frame of an hour before sunrise for Animate Sun. Kept with the scene, so a render "
                    "farm's chunks (blender -s A -e B) and render.py --frames give each frame the sun "
                    "of the whole animation",
        default=1,
    )
    day_end_frame: IntProperty(
        name="Day End Frame",
        description="Frame of an hour after sunset for Animate Sun (see Day Start Frame)",
        default=250,
    )

    # -- tone mapping -----------------------------------------------------------------------
    middle_gray: FloatProperty(
        name="Middle Gray (Key)",
        description=_d("middle_gray",
                       "Tone of the scene: larger values look brighter, smaller values dimmer"),
        default=0.18, min=0.01, max=1.0,
        update=_sync_compositor,
    )
    white_point: FloatProperty(
        name="White Point",
        description=_d("white_point",
                       "White point of the Reinhard Mod, Uncharted 2, Logarithmic and Adaptive "
                       "Log operators"),
        default=3.0, min=0.01, max=10.0,
        update=_sync_compositor,
    )
    luminance_saturation: FloatProperty(
        name="Luminance Saturation",
        description=_d("luminance_saturation",
                       "Additional colour saturation of the Exp, Reinhard, Reinhard Mod, "
                       "Logarithmic and Adaptive Log operators"),
        default=1.0, min=0.1, max=2.0,
        update=_sync_compositor,
    )
    auto_exposure: BoolProperty(
        name="Auto Exposure",
        description=_d("auto_exposure",
                       "Adjust exposure automatically from the log-average luminance of the scene"),
        default=True,
        update=_sync_compositor,
    )
    tone_mapping_operator: EnumProperty(
        name="Tone Mapping Operator",
        description=_d("tone_mapping_operator", "HDR to LDR conversion operator"),
        items=(
            ("EXP", "Exp", "Exponential tone mapping operator"),
            ("REINHARD", "Reinhard", "Basic Reinhard tone mapping operator"),
            ("REINHARD_MOD", "Reinhard Mod", "Modified Reinhard tone mapping operator"),
            ("UNCHARTED2", "Uncharted 2", "Tone mapping operator from Uncharted 2 (Hable)"),
            ("FILMIC_ALU", "Filmic ALU", "Filmic tone mapping operator (Hable)"),
            ("LOGARITHMIC", "Logarithmic", "Logarithmic tone mapping operator (Drago)"),
            ("ADAPTIVE_LOG", "Adaptive Log", "Adaptive logarithmic tone mapping operator (Drago)"),
            ("BLENDER_VIEW", "Blender View Transform",
             "No tone-mapping curve: the scene's own view transform (Color Management, AgX by "
             "default) maps the image; Auto Exposure still sets its exposure"),
        ),
        default="UNCHARTED2",
        update=_sync_compositor,
    )
    light_adaptation: BoolProperty(
        name="Light Adaptation",
        description=_d("light_adaptation", "Simulate temporal light adaptation across frames"),
        default=True,
    )
    tone_map_exr: BoolProperty(
        name="Tone Map EXR",
        description="Apply the tone mapping to renders saved as OpenEXR too. Off: EXR files hold "
                    "scene-linear radiance with the atmosphere applied, as any Blender render",
        default=False,
        update=_sync_compositor,
    )


    # -- clouds -----------------------------------------------------------------------------
    clouds_enabled: BoolProperty(
        name="Clouds",
        description="A cloud layer in the sky: lit by the sun through the atmosphere and by the sky, "
                    "hazed by the air in front of it (world shader; Set Up Scene makes the images)",
        default=False,
        update=_sync_clouds,
    )
    cloud_preset: EnumProperty(
        name="Preset", description="Set the cloud controls for a common sky (they stay editable)",
        items=(("CUSTOM", "Custom", "The controls as set"),
               *((key.upper().replace("-", "_"), key.replace("-", " ").capitalize(),
                  ", ".join(f"{k} {v:g}" for k, v in values.items())) for key, values in CLOUD_PRESETS.items())),
        default="CUSTOM",
        update=_apply_cloud_preset,
    )
    cloud_coverage: FloatProperty(
        name="Coverage", description="Fraction of the sky the clouds cover (0: clear, 1: overcast)",
        default=CLOUD_RANGES["coverage"][0], min=0.0, max=1.0, subtype="FACTOR",
    )
    cloud_base: FloatProperty(
        name="Base", description="Height of the cloud base above the ground",
        default=CLOUD_RANGES["base"][0], min=CLOUD_RANGES["base"][1], max=CLOUD_RANGES["base"][2], unit="LENGTH",
    )
    cloud_thickness: FloatProperty(
        name="Thickness", description="Thickness of a full cloud (thinner at its edges)",
        default=CLOUD_RANGES["thickness"][0], min=CLOUD_RANGES["thickness"][1], max=CLOUD_RANGES["thickness"][2],
        unit="LENGTH",
    )
    cloud_density: FloatProperty(
        name="Density",
        description="Extinction inside a cloud, per metre (0.033: optical depth 20 through 600 m, "
                    "a stratocumulus or fair-weather cumulus)",
        default=CLOUD_RANGES["density"][0], min=CLOUD_RANGES["density"][1], max=CLOUD_RANGES["density"][2],
        precision=4, step=0.1,
    )
    cloud_scale: FloatProperty(
        name="Scale", description="Size of the cloud features",
        default=CLOUD_RANGES["scale"][0], min=CLOUD_RANGES["scale"][1], max=CLOUD_RANGES["scale"][2], unit="LENGTH",
    )
    cloud_seed: IntProperty(
        name="Seed", description="Which cloud field: every seed is another sky of the same coverage",
        default=0, min=0, max=1_000_000,
        update=_sync_clouds,
    )
    cloud_offset: FloatVectorProperty(
        name="Offset", description="Shift of the cloud field (x, y): keyframe it for wind",
        size=2, default=(0.0, 0.0), unit="LENGTH",
    )


CLASSES = (OLSSettings,)

