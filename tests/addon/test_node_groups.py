"""The node-group registry (addon/nodes/__init__.py: GROUPS): every group the add-on builds has an
entry, each entry's numpy twin imports and its test exists; and each group's interface (socket
names, types and defaults) matches the snapshot in node_group_interfaces.json.

A deliberate interface change: run with OLS_UPDATE_SNAPSHOTS=1 once and commit the new file.
"""
import ast
import json
import math
import os
from pathlib import Path

import pytest

from extension import ROOT, extension_module, import_extension, names

bpy = pytest.importorskip("bpy")
SNAPSHOTS = Path(__file__).with_name("node_group_interfaces.json")
# Layouts that between them build every group: brute force in both single-scattering modes (the
# march chunks, the shadow test, the integration step) and epipolar sampling.
LAYOUTS = ({"scattering_technique": "BRUTE_FORCE", "single_scattering_mode": "LUT", "num_integration_steps": 16},
           {"scattering_technique": "BRUTE_FORCE", "single_scattering_mode": "INTEGRATION", "num_integration_steps": 12},
           {"scattering_technique": "EPIPOLAR_SAMPLING", "single_scattering_mode": "LUT"})


@pytest.fixture(scope="module")
def built_groups(tmp_path_factory):
    """{group name: interface} of every group a wired scene gets across LAYOUTS."""
    os.environ.setdefault("OLS_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
    package = import_extension()
    package.register()
    try:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        camera = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
        camera.location, camera.rotation_euler = (0.0, 0.0, 2.0), (math.pi / 2, 0.0, 0.0)
        scene.collection.objects.link(camera)
        scene.camera = camera
        sun = extension_module("addon.scene.sun").create_sun(scene, elevation_deg=20.0)
        directory = extension_module("addon.baking").bake_if_needed(package.lut_gen.AtmosphereParams(), "draft")
        wiring = extension_module("addon.scene.setup.wiring")
        wiring.wire_scene(scene, directory, [], sun)
        interfaces, per_layout = {}, []

        def built():
            return {group.name: interface(group) for group in bpy.data.node_groups
                    if group.name.startswith("OLS ") and group.name != names.COMPOSITOR_TREE}
        for layout in LAYOUTS:
            for name, value in layout.items():
                setattr(scene.ols, name, value)
            scene.ols.enable_light_shafts = True
            wiring.match_light_shaft_layout(scene)
            per_layout.append(built())
            interfaces.update(per_layout[-1])
        # The analytic model builds its groups under the same names: they must keep the interfaces.
        # Its light shafts too, across the same layouts (their march has groups of its own).
        scene.ols.atmosphere_model = "ANALYTIC"
        for layout, tables in zip(LAYOUTS, per_layout):
            for name, value in layout.items():
                setattr(scene.ols, name, value)
            wiring.match_light_shaft_layout(scene)
            for name, sockets in built().items():
                assert tables.get(name, sockets) == sockets, f"{name}: the analytic group's interface differs"
                assert interfaces.setdefault(name, sockets) == sockets or name in tables, name
        return interfaces
    finally:
        package.unregister()


def _value(value):
    if hasattr(value, "__len__") and not isinstance(value, str):
        return [round(float(v), 6) for v in value]
    return round(float(value), 6) if isinstance(value, float) else value


def interface(group) -> list:
    """The group's sockets in order: [in/out, name, socket type, default]."""
    items = []
    for item in group.interface.items_tree:
        if item.item_type != "SOCKET":
            continue
        default = getattr(item, "default_value", None)
        items.append([item.in_out, item.name, item.socket_type, None if default is None else _value(default)])
    return items


def registry():
    return extension_module("addon.nodes").GROUPS


def test_every_built_group_has_an_entry(built_groups):
    registered = {group.name for group in registry()}
    assert set(built_groups) <= registered, sorted(set(built_groups) - registered)
    assert registered <= set(built_groups), ("registered but never built", sorted(registered - set(built_groups)))
    # one entry per group and builder (the analytic model rebuilds some names with its own)
    assert len({(group.name, group.builder) for group in registry()}) == len(registry())


def _resolve(dotted: str):
    """Import the longest module prefix of ``dotted`` and get the rest as attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            target = extension_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attribute in parts[cut:]:
            target = getattr(target, attribute)
        return target
    raise ImportError(dotted)


@pytest.mark.parametrize("index", range(32))
def test_each_entry_has_a_builder_an_importable_twin_and_a_test(index):
    groups = registry()
    assert len(groups) == 32, "a group was added or removed: update this test's range"
    group = groups[index]
    assert callable(group.builder) and group.builder.__module__.split(".addon.nodes.")[-1], group
    assert group.twin.startswith("lut_gen."), f"{group.name}: the twin lives in lut_gen (numpy), not {group.twin}"
    assert callable(_resolve(group.twin)), group.twin
    path, _, function = group.test.partition("::")
    test_file = ROOT / path
    assert test_file.is_file(), f"{group.name}: test file {path} is missing"
    defined = {node.name for node in ast.walk(ast.parse(test_file.read_text())) if isinstance(node, ast.FunctionDef)}
    assert function in defined, f"{group.name}: {path} has no {function}"


def test_interfaces_match_their_snapshots(built_groups):
    if os.environ.get("OLS_UPDATE_SNAPSHOTS"):
        groups = (f"  {json.dumps(name)}: [\n" + ",\n".join(f"    {json.dumps(socket)}" for socket in sockets) + "\n  ]"
                  for name, sockets in sorted(built_groups.items()))
        SNAPSHOTS.write_text("{\n" + ",\n".join(groups) + "\n}\n")
    snapshots = json.loads(SNAPSHOTS.read_text())
    assert sorted(built_groups) == sorted(snapshots)
    for name, sockets in built_groups.items():
        assert sockets == snapshots[name], name


def test_group_names_come_from_the_names_module():
    assert {group.name for group in registry()} >= {names.SKY_GROUP, names.TERRAIN_GROUP, names.AERIAL_GROUP,
                                                    names.LIGHT_SHAFTS_GROUP, names.TONE_MAPPING_GROUP}
