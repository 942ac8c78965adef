"""The Additional control set: scattering modes, shadow cascades, the atmosphere's media and
Animate Sun (the sample's additional GUI, with the media this version bakes)."""
from ...lut_gen.model.air_presets import AIR_PRESETS, FOG_PRESETS
from ...lut_gen.model.atmosphere import (DEFAULT_GROUND_ALBEDO, DEFAULT_RAYLEIGH_SCATTERING, FOG_HEIGHT_RANGE,
                                         FOG_VISIBILITY_RANGE, PARAMETER_RANGES)
from .spec import MAX_FRAME, Change as C, Control, Reads as R

SECTION = "ADDITIONAL"

# The Rayleigh colour is relative to the largest default Rayleigh coefficient (blue), so the
# default colour gives the default air; the Mie colour is relative to the preset's aerosol.
RAYLEIGH_SCATTERING_SCALE = max(DEFAULT_RAYLEIGH_SCATTERING)
DEFAULT_RAYLEIGH_COLOR = tuple(c / RAYLEIGH_SCATTERING_SCALE for c in DEFAULT_RAYLEIGH_SCATTERING)
DEFAULT_MIE_COLOR = (1.0, 1.0, 1.0)
# The media's ranges where the model's own (PARAMETER_RANGES, which keep the bake's arithmetic
# finite) are far wider than any air the tables are meant for; tests/addon/test_controls.py holds
# them inside the model's.
AEROSOL_RANGE = (0.1, 5.0)
OZONE_RANGE = (0.0, 600.0)
ABSORPTION_RANGE = (0.0, 5.0)


def _custom_coefficients(settings):
    return settings.use_custom_scattering_coeffs


def _clear_sky(settings):
    return settings.atmosphere_preset == "CLEAR_SKY"


def _animated_sun(settings):
    return settings.animate_sun


def _preset_items():
    yield "CUSTOM", "Custom", "The aerosol density and fog as set"
    for key, depth in AIR_PRESETS.items():
        yield key.upper().replace("-", "_"), key.replace("-", " ").capitalize(), \
            f"Aerosol optical depth {depth:g} at 550 nm, no fog"
    for key, (visibility, height) in FOG_PRESETS.items():
        yield key.upper().replace("-", "_"), key.replace("-", " ").capitalize(), \
            f"Fog of {visibility:g} m visibility, {height:g} m deep (the haze as set)"


CONTROLS = (
    Control('single_scattering_mode', 'Single Scattering', section=SECTION, kind='enum', default='LUT',
            change=C.COMPOSITOR, reads=(R.SHAFT_GRAPH,),
            items=(
                ('NONE', 'None', 'Do not compute single scattering'),
                ("INTEGRATION", "Integration", "Compute single scattering with numerical integration during ray "
                                               "marching"),
                ("LUT", "LUT", "Compute single scattering with look-ups into the precomputed table: ray marching "
                               "only measures the lit length of the ray"),
            ),
            description='How single scattering is computed'),
    Control('multiple_scattering_mode', 'Multiple Scattering', section=SECTION, kind='enum', default='UNOCCLUDED',
            change=C.COMPOSITOR, reads=(R.SHAFT_GRAPH,),
            items=(
                ('NONE', 'None', 'Do not compute multiple scattering'),
                ('OCCLUDED', 'Occluded', 'Multiple scattering from the illuminated part of the view ray only'),
                ('UNOCCLUDED', 'Unoccluded', 'Higher order scattering from the whole view ray'),
            ),
            description='How higher order scattering is added'),
    Control('num_cascades', 'Num Cascades', section=SECTION, kind='int', default=6,
            change=C.COMPOSITOR, reads=(R.SHAFT_GRAPH,),
            range=(1, 8),
            description='Number of shadow map cascades'),
    Control('show_cascades', 'Show Cascades', section=SECTION, kind='bool', default=False,
            change=C.COMPOSITOR, reads=(R.SHAFT_GRAPH,),
            description='Visualize the shadow map cascades'),
    Control('smooth_shadows', 'Smooth Shadows', section=SECTION, kind='bool', default=True,
            change=C.COMPOSITOR, reads=(R.SHAFT_GRAPH,),
            description='Soften shadow edges by bilinear filtering of 4 shadow-map samples'),
    Control('best_cascade_search', 'Best Cascade Search', section=SECTION, kind='bool', default=True,
            change=C.COMPOSITOR, reads=(R.SHAFT_GRAPH,),
            description="Use the smallest cascade a point projects into instead of the cascade depth ranges, "
                        "for better shadow quality"),
    Control('cascade_partitioning_factor', 'Partitioning Factor', section=SECTION, kind='float', default=0.95,
            change=C.COMPOSITOR, reads=(R.FRAME_PASSES,),
            range=(0.0, 1.0), subtype='FACTOR',
            description='Blend between linear (0) and logarithmic (1) cascade distribution'),
    Control('first_cascade_to_ray_march', 'First Cascade to Ray March', section=SECTION, kind='int', default=2,
            change=C.COMPOSITOR, reads=(R.FRAME_PASSES,),
            range=(0, 7),
            description="Smallest cascade considered during ray marching; the one or two smallest can usually "
                        "be skipped without visible loss"),
    Control('extinction_evaluation_mode', 'Extinction Evaluation', section=SECTION, kind='enum', default='EPIPOLAR',
            change=C.NOTHING, reads=(R.NONE,),
            items=(
                ("EPIPOLAR", "Epipolar", "Extinction from the epipolar extinction image, unwarped per pixel "
                                         "(faster)"),
                ('PER_PIXEL', 'Per Pixel', 'Analytical extinction evaluated for each pixel'),
            ),
            inert='(extinction is always evaluated per pixel)',
            description='How extinction is evaluated per pixel (no effect on quality)'),
    Control('refinement_criterion', 'Refinement Criterion', section=SECTION, kind='enum', default='INSCATTERING',
            change=C.NOTHING, reads=(R.NONE,),
            items=(
                ('DEPTH', 'Depth', 'Refine where depth differs'),
                ("INSCATTERING", "Inscattering", "Refine where the coarse unshadowed inscattering differs (no "
                                                 "banding near the epipole in outer space views)"),
            ),
            inert="(refinement always compares the lit length of neighbouring samples; depth plays no part "
                  "since each pixel uses its own)",
            description='What decides where ray marching samples are refined'),
    Control('use_custom_scattering_coeffs', 'Use Custom Scattering Coeffs', section=SECTION, kind='bool', default=False,
            change=C.REBAKE, reads=(R.TABLES,),
            description="Set custom Rayleigh and Mie scattering coefficients with the colours below (the "
                        "tables are re-baked)"),
    Control('rayleigh_color', 'Rayleigh Color', section=SECTION, kind='color', default=DEFAULT_RAYLEIGH_COLOR,
            change=C.REBAKE, reads=(R.TABLES,),
            range=(0.0, 10.0), soft_max=1.0, param='rayleigh_scattering', enabled_by=_custom_coefficients,
            description="Rayleigh scattering coefficients relative to the default blue coefficient (the "
                        "default colour gives the default air)"),
    Control('mie_color', 'Mie Color', section=SECTION, kind='color', default=DEFAULT_MIE_COLOR,
            change=C.REBAKE, reads=(R.TABLES,),
            range=(0.0, 10.0), soft_max=1.0, param='mie_scattering', enabled_by=_custom_coefficients,
            description="Mie scattering coefficients relative to the Atmosphere preset's aerosol (white: the "
                        "preset's own)"),
    Control('air_preset', 'Air Preset', section=SECTION, kind='enum', default='CUSTOM',
            change=C.PRESET, reads=(R.PANEL,),
            items=tuple(_preset_items()),
            description="Set the air of a common day: a haze by its aerosol optical depth at 550 nm (the clear"
                        " sky's is 0.11), or a fog by its visibility and depth (the controls stay editable; "
                        "the tables are re-baked)"),
    Control('aerosol_density', 'Aerosol Density', section=SECTION, kind='float', default=1.0,
            change=C.REBAKE, reads=(R.TABLES,),
            range=AEROSOL_RANGE, param='aerosol_density',
            description='Aerosol (Mie) particle density relative to the default (the tables are re-baked)'),
    Control('aerosol_absorption', 'Aerosol Absorption', section=SECTION, kind='float', default=0.1,
            change=C.REBAKE, reads=(R.TABLES,),
            range=ABSORPTION_RANGE, param='aerosol_absorption',
            description="Aerosol absorption relative to aerosol scattering: Mie extinction = scattering x (1 +"
                        " absorption) (the tables are re-baked)"),
    Control('atmosphere_model', 'Atmosphere Model', section=SECTION, kind='enum', default='PRECOMPUTED',
            change=C.MODEL, reads=(R.MODEL,),
            items=(
                ("PRECOMPUTED", "Precomputed", "The baked tables: multiple scattering, the Earth's curvature, "
                                               "twilight and light shafts"),
                ("ANALYTIC", "Analytic (Hoffman-Preetham)", "Hoffman & Preetham's constant-density model: single "
                                                            "scattering in closed form, no bake, no table file, "
                                                            "updates at once; light shafts in closed form; a "
                                                            "preview, with no twilight"),
            ),
            description="What computes the sky, the terrain's light and the aerial perspective"),
    Control('atmosphere_preset', 'Atmosphere', section=SECTION, kind='enum', default='CLEAR_SKY',
            change=C.REBAKE, reads=(R.TABLES,),
            items=(
                ("CLEAR_SKY", "Clear Sky (spectral)", "Spectral bake converted with the CIE observer, ozone layer"
                                                      " and a lit ground: the colours of a real clear sky, blue "
                                                      "twilight zenith included"),
                ("SAMPLE_2013", "Sample 2013", "The sample's own media: three wavelengths used directly as RGB, "
                                               "no ozone, black ground (the media of the seed's figures, with "
                                               "this version's numerics)"),
            ),
            description='The media the tables are baked for (the tables are re-baked)'),
    Control('ground_albedo', 'Ground Albedo', section=SECTION, kind='float', default=DEFAULT_GROUND_ALBEDO,
            change=C.REBAKE, reads=(R.TABLES,),
            range=PARAMETER_RANGES['ground_albedo'], param='ground_albedo', enabled_by=_clear_sky,
            description="Reflectance of the ground under the atmosphere: lights the sky from below and is the "
                        "ground seen below the horizon (0.2: vegetation and soil; Clear Sky preset only; the "
                        "tables are re-baked)"),
    Control('ozone_column', 'Ozone (DU)', section=SECTION, kind='float', default=300.0,
            change=C.REBAKE, reads=(R.TABLES,),
            range=OZONE_RANGE, unit='DU', param='ozone_column', enabled_by=_clear_sky,
            description="Ozone column in Dobson units (300: the global mean; 0: no ozone). Its Chappuis band "
                        "keeps the twilight zenith blue (Clear Sky preset only; the tables are re-baked)"),
    Control('fog_visibility', 'Fog Visibility', section=SECTION, kind='float', default=0.0,
            change=C.REBAKE, reads=(R.TABLES,),
            range=(0.0, FOG_VISIBILITY_RANGE[1]), soft_max=5000.0, unit='m', param='fog_visibility',
            description=f"Meteorological visibility in the fog at the ground, in metres (0: no fog; "
                        f"{FOG_VISIBILITY_RANGE[0]:g} m to {FOG_VISIBILITY_RANGE[1] / 1000:g} km). A grey, "
                        f"forward-scattering layer of droplets beside the haze: distant hills fade into white "
                        f"and the sun's disc pales (the tables are re-baked)"),
    Control('fog_height', 'Fog Height', section=SECTION, kind='float', default=50.0,
            change=C.REBAKE, reads=(R.TABLES,),
            range=FOG_HEIGHT_RANGE, unit='m', param='fog_height',
            enabled_by=lambda settings: settings.fog_visibility > 0.0,
            description=f"The fog layer's scale height in metres: its density falls by e over this height "
                        f"({FOG_HEIGHT_RANGE[0]:g}-{FOG_HEIGHT_RANGE[1]:g} m; the tables are re-baked)"),
    Control('animate_sun', 'Animate Sun', section=SECTION, kind='bool', default=False,
            change=C.DAY_RANGE, reads=(R.SUN,),
            description="Animate the sun across the sky: a day at 45 deg N from an hour before sunrise (Day "
                        "Start Frame) to an hour after sunset (Day End Frame). Turning it on takes the scene's"
                        " frame range"),
    Control('day_start_frame', 'Day Start Frame', section=SECTION, kind='int', default=1,
            change=C.NOTHING, reads=(R.SUN,),
            range=(-MAX_FRAME, MAX_FRAME), enabled_by=_animated_sun,
            description="Frame of an hour before sunrise for Animate Sun. Kept with the scene, so a render "
                        "farm's chunks (blender -s A -e B) and render.py --frames give each frame the sun of "
                        "the whole animation"),
    Control('day_end_frame', 'Day End Frame', section=SECTION, kind='int', default=250,
            change=C.NOTHING, reads=(R.SUN,),
            range=(-MAX_FRAME, MAX_FRAME), enabled_by=_animated_sun,
            description='Frame of an hour after sunset for Animate Sun (see Day Start Frame)'),
)
