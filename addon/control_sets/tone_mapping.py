"""The Tone Mapping control set: the sample's seven operators and their parameters, light
adaptation, and what OpenEXR renders hold."""
from .spec import Change as C, Control, Reads as R

SECTION = "TONE_MAPPING"

CONTROLS = (
    Control('middle_gray', 'Middle Gray (Key)', section=SECTION, kind='float', default=0.18,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            range=(0.01, 1.0),
            description='Tone of the scene: larger values look brighter, smaller values dimmer'),
    Control('white_point', 'White Point', section=SECTION, kind='float', default=3.0,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            range=(0.01, 10.0),
            description='White point of the Reinhard Mod, Uncharted 2, Logarithmic and Adaptive Log operators'),
    Control('luminance_saturation', 'Luminance Saturation', section=SECTION, kind='float', default=1.0,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            range=(0.1, 2.0),
            description="Additional colour saturation of the Exp, Reinhard, Reinhard Mod, Logarithmic and "
                        "Adaptive Log operators"),
    Control('auto_exposure', 'Auto Exposure', section=SECTION, kind='bool', default=True,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            description='Adjust exposure automatically from the log-average luminance of the scene'),
    Control('tone_mapping_operator', 'Tone Mapping Operator', section=SECTION, kind='enum', default='UNCHARTED2',
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            items=(
                ('EXP', 'Exp', 'Exponential tone mapping operator'),
                ('REINHARD', 'Reinhard', 'Basic Reinhard tone mapping operator'),
                ('REINHARD_MOD', 'Reinhard Mod', 'Modified Reinhard tone mapping operator'),
                ('UNCHARTED2', 'Uncharted 2', 'Tone mapping operator from Uncharted 2 (Hable)'),
                ('FILMIC_ALU', 'Filmic ALU', 'Filmic tone mapping operator (Hable)'),
                ('LOGARITHMIC', 'Logarithmic', 'Logarithmic tone mapping operator (Drago)'),
                ('ADAPTIVE_LOG', 'Adaptive Log', 'Adaptive logarithmic tone mapping operator (Drago)'),
                ("BLENDER_VIEW", "Blender View Transform", "No tone-mapping curve: the scene's own view transform"
                                                           " (Color Management, AgX by default) maps the image; "
                                                           "Auto Exposure still sets its exposure"),
            ),
            description='HDR to LDR conversion operator'),
    Control('light_adaptation', 'Light Adaptation', section=SECTION, kind='bool', default=True,
            change=C.NOTHING, reads=(R.ADAPTATION,),
            description='Simulate temporal light adaptation across frames'),
    Control('tone_map_exr', 'Tone Map EXR', section=SECTION, kind='bool', default=False,
            change=C.COMPOSITOR, reads=(R.COMPOSITOR,),
            description="Apply the tone mapping to renders saved as OpenEXR too. Off: EXR files hold scene-"
                        "linear radiance with the atmosphere applied, as any Blender render"),
)
