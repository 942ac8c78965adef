"""Every name the add-on gives to something in a .blend: custom properties, nodes, node trees
and groups, images, objects and materials. Each is written here once, so that a saved file, the
code that wires it and the code that finds it again can never disagree. Imports nothing.

A rename here changes what existing .blend files are recognised by: keep old names working or
say so in CHANGELOG.md.
"""

# -- custom properties on the scene --------------------------------------------------------
WIRED_KEY = "ols_bake_key"                        # the bake key of the tables the scene is wired to
RESOLUTION_KEY = "ols_table_resolution"           # "default" or "draft", what Set Up Scene baked
PREVIEW_KEY = "ols_showing_preview"               # wired to the draft preview of tables still baking
PREVIOUS_WORLD = "ols_previous_world"             # the world Set Up Scene replaced (restored on unwire)
PREVIOUS_PASSES = "ols_previous_passes"           # the render passes before we turned ours on
CREATED_TREE = "ols_created_compositor"           # the compositor tree is ours (removed on unwire)
PREVIOUS_VIEW = "ols_previous_view_transform"
VIEW_MODE = "ols_view_mode"                       # "SAMPLE": ours set Standard; absent: the user's view
ADAPTED_LUMINANCE_KEY = "ols_adapted_luminance"   # the adapted luminance of ...
ADAPTED_FRAME_KEY = "ols_adapted_frame"           # ... the last frame rendered through the tone mapping
ADAPTATION_PLAN_KEY = "ols_adaptation_plan"       # Measure Light Adaptation's per-frame plan (JSON)

# -- custom properties on objects, materials, nodes, node groups and images ---------------
PREVIOUS_MATERIAL = "ols_previous_material"       # on an object: its material before wiring
GENERATED = "ols_generated"                       # on a material: made by the add-on
SOURCE = "ols_source"                             # on our compositor node: the node it follows ...
SOURCE_OUTPUT = "ols_source_output"               # ... and that node's output index
ATMOSPHERE_TARGETS_KEY = "ols_atmosphere_targets"  # on our aerial node: the inputs the render's image fed
LAYOUT_KEY = "ols_layout"                         # on the light-shaft group: the layout it was built for
SHAFT_MODEL_KEY = "ols_shaft_model"               # ... and the atmosphere model ("tables" or "analytic")
READS_SHADOW_MAPS_KEY = "ols_reads_shadow_maps"   # on the light-shaft group: whether it samples the atlas
ROWS_KEY = "ols_rows"                             # on the frame-values group: the rows it unpacks
FILTERING_KEY = "ols_filtering"                   # on the look-up group: the engine's filtering
FILE_STAMP_KEY = "ols_file_stamp"                 # on a table image: the file it was loaded from
# On the optical-depth image: the name of its bake's fog optical-depth image ("" without fog).
# The node builders that read net densities take the optical-depth image alone; the fog
# column of a bake with fog travels with it this way (addon.nodes.optical.fog_depth_image).
FOG_DEPTH_IMAGE_KEY = "ols_fog_depth_image"
PACKED_MANIFEST_KEY = "ols_bake_manifest"         # on a packed table image: its bake's manifest

# -- objects, worlds, materials ------------------------------------------------------------
SUN_OBJECT = "OLS Sun"
WORLD = "OLS World"
TERRAIN_MATERIAL = "OLS Terrain"

# -- node groups (each built by a builder in addon/nodes, see GROUPS there) ----------------
LOOKUP_GROUP = "OLS Scattering Lookup"
COMPOSITOR_LOOKUP_GROUP = "OLS Scattering Lookup (Compositor)"
SEGMENT_GROUP = "OLS Segment Transmittance"
SECTION_GROUP = "OLS Section Scattering ({table})"      # one per table: single, higher, multiple
SKY_GROUP = "OLS Sky"
CLOUDS_GROUP = "OLS Clouds"
CLOUD_SHADOW_GROUP = "OLS Cloud Shadow"
CLOUD_VEIL_GROUP = "OLS Cloud Veil"
CLOUD_VEIL_STEP_GROUP = "OLS Cloud Veil Step"
CLOUD_SHADOW_OBJECT = "OLS Cloud Shadows"            # the shadow-only layer
CLOUD_SHADOW_MATERIAL = "OLS Cloud Shadows"
TERRAIN_GROUP = "OLS Terrain"
AERIAL_GROUP = "OLS Aerial Perspective"
FRAME_VALUES_GROUP = "OLS Frame Values"
LIGHT_SHAFTS_GROUP = "OLS Light Shafts"
SHADOW_TEST_GROUP = "OLS Shadow Test"
INTEGRATION_GROUP = "OLS Integration Step"
MARCH_CHUNK_GROUP = "OLS March Chunk"
MARCH_REST_GROUP = "OLS March Rest"
SHAFT_EDGE_GROUP = "OLS Shaft Edge"
TONE_MAPPING_GROUP = "OLS Tone Mapping"

# -- the compositor tree and our nodes in it -----------------------------------------------
COMPOSITOR_TREE = "OLS Compositing"
LAYERS_NODE = "OLS Render Layers"
AERIAL_NODE = "OLS Aerial Perspective"
SHAFTS_NODE = "OLS Light Shafts"
VEIL_NODE = "OLS Cloud Veil"                  # between the render's image and the atmosphere groups
FRAME_NODE = "OLS Frame Values"
TONE_NODE = "OLS Tone Mapping"
ATMOSPHERE_NODE = "OLS Atmosphere Layers"         # File Output: the layers of a multilayer EXR render
SHAFTS_LAYER_NODE = "OLS Shafts Layer"
ADAPTED_LUMINANCE_NODE = "OLS Adapted Luminance"  # File Output: the luminance a frame adapted to

# -- images ----------------------------------------------------------------------------------
TABLE_IMAGE_PREFIX = "OLS"                        # + table name + bake key: the baked tables
FRAME_IMAGE = "OLS Frame Values"                  # camera, sun and cascades of the frame
SHADOW_MAP_IMAGE = "OLS Shadow Map"               # the cascades' depth atlas
SHADOW_CASCADES_IMAGE = "OLS Shadow Cascades"     # the cascades' rectangles and biases
CLOUD_MAP_IMAGE = "OLS Cloud Map"                 # lut_gen.clouds.field.cloud_map of the seed
CLOUD_TABLE_IMAGE = "OLS Cloud Table"             # lut_gen.clouds.slab.table_pixels
CLOUD_SEED_KEY = "ols_cloud_seed"                 # custom property of the map image: the seed it holds
SKY_LIGHT_IMAGE = "OLS Sky Light"                 # the world-lighting panoramas
GROUND_LIGHT_IMAGE = "OLS Ground Light"
SKY_VIEW_IMAGE = "OLS Sky View"                    # lut_gen.passes.sky_view: the camera's twilight correction
CLOUD_AIR_IMAGE = "OLS Cloud Air"                 # lut_gen.clouds.air_map of the frame's sun and camera height
EPIPOLAR_LIT_IMAGE = "OLS Epipolar Lit"
EPIPOLAR_INTEGRAL_IMAGE = "OLS Epipolar Integral"
EPIPOLAR_SAMPLING_IMAGE = "OLS Epipolar Sampling"
EPIPOLAR_AIR_IMAGES = {"single": "OLS Epipolar Air Rayleigh", "single_mie": "OLS Epipolar Air Mie",
                       "higher": "OLS Epipolar Air Higher", "single_fog": "OLS Epipolar Air Fog"}

# -- the analytic model (Hoffman & Preetham) --------------------------------------------------
ANALYTIC_WIRED = "analytic"                       # WIRED_KEY of a scene wired to the analytic model: no tables
ANALYTIC_MEDIA_GROUP = "OLS Analytic Media"                    # its coefficients, for the shader groups
ANALYTIC_MEDIA_COMPOSITOR_GROUP = "OLS Analytic Media (Compositor)"
# The analytic shafts' march: its own chunk groups (they take the ray's extinction) and step.
ANALYTIC_INTEGRATION_GROUP = "OLS Analytic Integration Step"
ANALYTIC_MARCH_CHUNK_GROUP = "OLS Analytic March Chunk"
ANALYTIC_MARCH_REST_GROUP = "OLS Analytic March Rest"
