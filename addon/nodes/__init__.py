"""Node-group builders: one module per group (or family of groups), all on top of builder.Graph.

``GROUPS`` pairs every node group the add-on builds with its builder, its numpy twin (the same
maths in lut_gen, which the tests and the per-frame code run) and the test that renders the
group with Cycles and compares its pixels with the twin. tests/addon/test_node_groups.py fails
when a group is built that has no entry here, when a twin does not import or when a test is
missing; a new group lands with all three.
"""
from dataclasses import dataclass
from typing import Callable

from ..scene import names
from . import analytic, builder, epipolar, frame_values, lookup  # noqa: F401 (their helpers are used as nodes.<module>.<name>)
from .aerial import build_aerial_group
from .analytic import (build_analytic_aerial_group, build_analytic_sky_group, build_analytic_terrain_group,
                       build_media_group)
from .analytic_shafts import build_analytic_integration_group, build_analytic_light_shaft_groups
from .cloud_shadow import build_cloud_shadow_group
from .cloud_veil import build_cloud_veil_group, build_cloud_veil_step_group
from .clouds import build_cloud_group
from .frame_values import build_frame_values_group
from .inscattering import build_section_group, lookup_group_name, section_group_name
from .light_shafts import (ShaftLayout,  # noqa: F401 (nodes.ShaftLayout)
                           build_integration_group, build_light_shaft_groups, build_march_chunk_group,
                           build_shadow_test_group, build_shaft_edge_group)
from .lookup import build_lookup_group
from .optical import build_segment_transmittance_group
from .sky import build_sky_group
from .terrain import build_terrain_group
from .tone_mapping import build_tone_mapping_group

COMPOSITOR_TABLES = ("single", "higher", "multiple")


@dataclass(frozen=True)
class Group:
    name: str           # the node group's name in bpy.data.node_groups
    builder: Callable   # the function that (re)builds it
    twin: str           # its numpy twin: a dotted path from the repository root (module, then attribute)
    test: str           # the test comparing a render of it with the twin: "tests/<layer>/<file>.py::<function>"


_AERIAL_TEST = "tests/twins/test_aerial_pass.py::test_aerial_perspective_pass_matches_twin"
_SHAFTS_TEST = "tests/twins/test_light_shafts_pass.py::test_every_scattering_mode_matches_the_twin_and_shafts_show"
_SKY_TEST = "tests/twins/test_sky_group.py::test_sky_render_matches_numpy_twin"
_VEIL_TEST = "tests/twins/test_cloud_veil.py::test_peaks_in_the_cloud_are_veiled_as_the_twin_says"
_ANALYTIC_TESTS = "tests/twins/test_analytic_groups.py::"
_CLOUDS_TEST = "tests/twins/test_cloud_sky.py::test_cloudy_sky_render_matches_numpy_twin"
_ANALYTIC_SHAFTS_TEST = "tests/twins/test_analytic_shafts.py::test_analytic_shafts_match_the_twin_in_every_mode"

GROUPS = (
    Group(names.LOOKUP_GROUP, build_lookup_group, "lut_gen.tables.lookup.Luts.sky_radiance", _SKY_TEST),
    *(Group(lookup_group_name(table), build_lookup_group, "lut_gen.tables.lookup.Luts.sky_radiance",
            _AERIAL_TEST if table == "multiple" else _SHAFTS_TEST) for table in COMPOSITOR_TABLES),
    *(Group(section_group_name(table), build_section_group, "lut_gen.passes.aerial.section_inscattering",
            _AERIAL_TEST if table == "multiple" else _SHAFTS_TEST) for table in COMPOSITOR_TABLES),
    Group(names.SEGMENT_GROUP, build_segment_transmittance_group, "lut_gen.passes.aerial.segment_transmittance",
          "tests/twins/test_aerial_pass.py::test_segment_transmittance_just_below_the_horizon_matches_twin"),
    Group(names.SKY_GROUP, build_sky_group, "lut_gen.passes.sky_view.camera_sky", _SKY_TEST),
    Group(names.CLOUDS_GROUP, build_cloud_group, "lut_gen.clouds.sky.view", _CLOUDS_TEST),
    Group(names.CLOUD_VEIL_GROUP, build_cloud_veil_group, "lut_gen.clouds.veil.veiled", _VEIL_TEST),
    Group(names.CLOUD_VEIL_STEP_GROUP, build_cloud_veil_step_group, "lut_gen.clouds.veil.veil", _VEIL_TEST),
    Group(names.CLOUD_SHADOW_GROUP, build_cloud_shadow_group, "lut_gen.clouds.shadow.sun_transmittance",
          "tests/twins/test_cloud_shadow.py::test_cloud_shadows_on_a_plain_match_the_twin"),
    Group(names.TERRAIN_GROUP, build_terrain_group, "lut_gen.passes.terrain.terrain_radiance",
          "tests/twins/test_terrain_group.py::test_terrain_group_matches_numpy_twin"),
    Group(names.AERIAL_GROUP, build_aerial_group, "lut_gen.passes.aerial.aerial_perspective", _AERIAL_TEST),
    Group(names.FRAME_VALUES_GROUP, build_frame_values_group, "lut_gen.passes.frame_values.unpack",
          "tests/twins/test_frame_values_group.py::test_frame_values_group_outputs_what_unpack_reads"),
    Group(names.LIGHT_SHAFTS_GROUP, build_light_shaft_groups, "lut_gen.passes.scattering_pass.light_shafts", _SHAFTS_TEST),
    Group(names.SHADOW_TEST_GROUP, build_shadow_test_group, "lut_gen.passes.shadow_map.visibility", _SHAFTS_TEST),
    Group(names.INTEGRATION_GROUP, build_integration_group, "lut_gen.passes.aerial.integration_terms", _SHAFTS_TEST),
    Group(names.MARCH_CHUNK_GROUP, build_march_chunk_group, "lut_gen.passes.aerial.light_shafts", _SHAFTS_TEST),
    Group(names.MARCH_REST_GROUP, build_march_chunk_group, "lut_gen.passes.aerial.light_shafts", _SHAFTS_TEST),
    Group(names.SHAFT_EDGE_GROUP, build_shaft_edge_group, "lut_gen.passes.shaft_boundary.refine", _SHAFTS_TEST),
    # The analytic model's groups: the same names and interfaces, other builders and twins.
    Group(names.SKY_GROUP, build_analytic_sky_group, "lut_gen.model.analytic.sky_parts",
          _ANALYTIC_TESTS + "test_analytic_sky_matches_its_twin"),
    Group(names.TERRAIN_GROUP, build_analytic_terrain_group, "lut_gen.model.analytic.terrain_radiance",
          _ANALYTIC_TESTS + "test_analytic_terrain_matches_its_twin_with_no_tables"),
    Group(names.AERIAL_GROUP, build_analytic_aerial_group, "lut_gen.model.analytic.aerial_perspective",
          _ANALYTIC_TESTS + "test_analytic_aerial_perspective_matches_its_twin"),
    Group(names.ANALYTIC_MEDIA_GROUP, build_media_group, "lut_gen.model.analytic.media",
          _ANALYTIC_TESTS + "test_analytic_sky_matches_its_twin"),
    Group(names.ANALYTIC_MEDIA_COMPOSITOR_GROUP, build_media_group, "lut_gen.model.analytic.media",
          _ANALYTIC_TESTS + "test_analytic_aerial_perspective_matches_its_twin"),
    Group(names.LIGHT_SHAFTS_GROUP, build_analytic_light_shaft_groups, "lut_gen.passes.analytic_shafts.scattering_pass",
          _ANALYTIC_SHAFTS_TEST),
    Group(names.ANALYTIC_INTEGRATION_GROUP, build_analytic_integration_group,
          "lut_gen.passes.analytic_shafts.step_integral", _ANALYTIC_SHAFTS_TEST),
    *(Group(name, build_march_chunk_group, "lut_gen.passes.analytic_shafts.light_shafts", _ANALYTIC_SHAFTS_TEST)
      for name in (names.ANALYTIC_MARCH_CHUNK_GROUP, names.ANALYTIC_MARCH_REST_GROUP)),
    Group(names.TONE_MAPPING_GROUP, build_tone_mapping_group, "lut_gen.passes.tone_mapping.tone_map",
          "tests/twins/test_tone_mapping.py::test_every_operator_matches_the_sample_formula"),
)
