"""The Basic control set: light scattering and light shafts, the technique, the shadow map, the
epipolar grid (the sample's basic GUI, in its order)."""
from .spec import Change as C, Control, Reads as R

SECTION = "BASIC"


def _epipolar(settings):
    return settings.scattering_technique == "EPIPOLAR_SAMPLING"


def _brute_force(settings):
    return settings.scattering_technique == "BRUTE_FORCE"


CONTROLS = (
    Control('enable_light_scattering', 'Enable Light Scattering', section=SECTION, kind='bool', default=True,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            description='Enable or disable the light scattering effect'),
    Control('enable_light_shafts', 'Enable Light Shafts', section=SECTION, kind='bool', default=True,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            description="Render shafts of light. When disabled, a simpler algorithm that ignores shadows "
                        "computes the scattering integral"),
    Control('scattering_technique', 'Scattering Technique', section=SECTION, kind='enum', default='EPIPOLAR_SAMPLING',
            change=C.COMPOSITOR, reads=(R.SHAFT_GRAPH,),
            items=(
                ("EPIPOLAR_SAMPLING", "Epipolar Sampling", "Calculate the scattering effect using epipolar "
                                                           "sampling"),
                ("BRUTE_FORCE", "Brute Force Ray Marching", "Calculate the scattering effect for each screen "
                                                            "pixel without 1D min/max tree optimization: the "
                                                            "reference ground-truth image"),
            ),
            description='How the scattering effect is calculated'),
    Control('shadow_map_resolution', 'Shadow Map Resolution', section=SECTION, kind='enum', default='1024',
            change=C.COMPOSITOR, reads=(R.SHAFT_GRAPH,),
            items=(
                ('512', '512 x 512', '512 x 512 shadow map'),
                ('1024', '1024 x 1024', '1024 x 1024 shadow map'),
                ('2048', '2048 x 2048', '2048 x 2048 shadow map'),
                ('4096', '4096 x 4096', '4096 x 4096 shadow map'),
            ),
            description="Resolution of the sun shadow map (the number of cascades is set in the additional "
                        "controls). A render uses at most the power of two at or above 8 texels per pixel of "
                        "its larger side (4096 from 257 pixels up): finer maps change nothing it can show"),
    Control('num_integration_steps', 'Num Integration Steps', section=SECTION, kind='int', default=30,
            change=C.COMPOSITOR, reads=(R.SHAFT_GRAPH,),
            range=(5, 100),
            description="Number of steps of the numerical single scattering integral. Used only when light "
                        "shafts are off and single scattering mode is Integration"),
    Control('jitter_steps', 'Jitter Steps', section=SECTION, kind='bool', default=False,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            enabled_by=_brute_force,
            description="Brute force: offset each pixel's march steps by a fixed per-pixel noise, so the "
                        "banding of few steps becomes fine noise"),
    Control('epipolar_slices', 'Epipolar Slices', section=SECTION, kind='int', default=512,
            change=C.COMPOSITOR, reads=(R.FRAME_PASSES,),
            range=(32, 2048),
            enabled_by=_epipolar,
            description="Number of epipolar slices. More slices give higher quality at higher cost; at least "
                        "half the largest image dimension looks good. A render uses at most its perimeter in "
                        "pixels (more are under a pixel apart)"),
    Control('samples_per_slice', 'Total Samples in Slice', section=SECTION, kind='int', default=256,
            change=C.COMPOSITOR, reads=(R.FRAME_PASSES,),
            range=(32, 2048),
            enabled_by=_epipolar,
            description="Number of samples along each epipolar slice; at least half the largest image "
                        "dimension looks good. A render uses at most twice its diagonal in pixels (more are "
                        "under a pixel apart)"),
    Control('initial_sample_step', 'Initial Sample Step', section=SECTION, kind='int', default=16,
            change=C.COMPOSITOR, reads=(R.FRAME_PASSES,),
            range=(2, 64),
            enabled_by=_epipolar,
            description="Step between the initial ray marching samples along each epipolar line. A lower step "
                        "places more samples and gives higher quality"),
    Control('epipole_sampling_density', 'Epipole Sampling Density', section=SECTION, kind='int', default=2,
            change=C.COMPOSITOR, reads=(R.FRAME_PASSES,),
            range=(1, 32),
            enabled_by=_epipolar,
            description="Additional increase of the initial ray marching sample density near the epipole, for "
                        "the strong forward Mie scattering around the sun"),
    Control('refinement_threshold', 'Refinement Threshold', section=SECTION, kind='float', default=0.03,
            change=C.COMPOSITOR, reads=(R.FRAME_PASSES,),
            range=(0.001, 0.5), precision=3, step=0.1,
            enabled_by=_epipolar,
            description="Refinement accuracy: a smaller threshold places more ray marching samples at "
                        "discontinuities of light intensity"),
    Control('scattering_scale', 'Scattering Scale', section=SECTION, kind='float', default=0.5,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            range=(0.0, 100.0), soft_max=2.0,
            description="Intensity of the scattering effect (almost no effect with automatic exposure tone "
                        "mapping)"),
    Control('show_sampling', 'Show Sampling', section=SECTION, kind='bool', default=False,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            enabled_by=_epipolar,
            description="Visualize the epipolar sampling structure: thick red dots are ray marching samples, "
                        "thin red dots interpolation samples (epipolar sampling only)"),
    Control('use_min_max_optimization', '1D Min/Max Optimization', section=SECTION, kind='bool', default=True,
            change=C.COMPOSITOR, reads=(R.FRAME_PASSES,),
            enabled_by=_epipolar,
            description="Skip the shadow-map taps of ray-march points that min/max mipmaps of the cascades "
                        "show surely lit or surely shadowed (epipolar sampling; speed only, the same picture)"),
    Control('optimize_sample_locations', 'Optimize Sample Locations', section=SECTION, kind='bool', default=True,
            change=C.NOTHING, reads=(R.NONE,),
            inert="(no effect: samples are spaced by angle from the sun, so short epipolar lines are not "
                  "oversampled)",
            description='Fix oversampling along short epipolar lines'),
    Control('correct_depth_breaks', 'Correction at Depth Breaks', section=SECTION, kind='bool', default=False,
            change=C.NOTHING, reads=(R.NONE,),
            inert="(not needed: each pixel reads the epipolar tables at its own depth, so no pixel is "
                  "interpolated across a depth break)",
            description="Extra pass that ray marches the pixels whose scattering cannot be unwarped precisely "
                        "from the epipolar image"),
    Control('show_depth_breaks', 'Show Depth Breaks', section=SECTION, kind='bool', default=False,
            change=C.NOTHING, reads=(R.NONE,),
            inert="(not needed: each pixel reads the epipolar tables at its own depth, so there are no depth "
                  "breaks to correct)",
            description="Show in green the pixels the depth-break correction pass recomputes (only with "
                        "Correction at Depth Breaks)"),
    Control('lighting_only', 'Lighting Only', section=SECTION, kind='bool', default=False,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            description='Show the light scattering effects only'),
)
