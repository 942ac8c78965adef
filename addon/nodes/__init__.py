"""Node-group builders: one module per group, all on top of builder.Graph."""
from . import epipolar, frame_values, lookup
from .aerial import GROUP_NAME as AERIAL_GROUP, build_aerial_group
from .frame_values import GROUP_NAME as FRAME_VALUES_GROUP, build_frame_values_group
from .inscattering import build_section_group, lookup_group_name, section_group_name
from .light_shafts import (GROUP_NAME as LIGHT_SHAFTS_GROUP, INTEGRATION_GROUP, MARCH_CHUNK_GROUP, MARCH_REST_GROUP,
                           READS_SHADOW_MAPS_KEY, SHADOW_TEST_GROUP, ShaftLayout, build_light_shaft_groups)
from .lookup import GROUP_NAME as LOOKUP_GROUP, build_lookup_group
from .optical import SEGMENT_GROUP, build_segment_transmittance_group
from .sky import GROUP_NAME as SKY_GROUP, build_sky_group
from .terrain import GROUP_NAME as TERRAIN_GROUP, build_terrain_group
from .tone_mapping import GROUP_NAME as TONE_MAPPING_GROUP, build_tone_mapping_group

COMPOSITOR_TABLES = ("single", "higher", "multiple")
GROUP_NAMES = ((LOOKUP_GROUP, SKY_GROUP, TERRAIN_GROUP, TONE_MAPPING_GROUP, AERIAL_GROUP, LIGHT_SHAFTS_GROUP,
                SHADOW_TEST_GROUP, INTEGRATION_GROUP, MARCH_CHUNK_GROUP, MARCH_REST_GROUP, FRAME_VALUES_GROUP, SEGMENT_GROUP)
               + tuple(lookup_group_name(t) for t in COMPOSITOR_TABLES) + tuple(section_group_name(t) for t in COMPOSITOR_TABLES))
