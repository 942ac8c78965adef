"""The draft preview while tables bake (addon/baking.py): a changed atmosphere shows the draft
tables as soon as they are baked and the full tables when their bake ends; a render never uses
the preview (the Render operator waits, a file saved in preview is re-baked on load)."""
import os
import subprocess
import sys
import time
import types

import numpy as np
import pytest
from extension import ROOT, extension_module, names

bpy = pytest.importorskip("bpy")

# Stand-ins that keep the test short: the "full" tables are the draft (16 x 64 x 32 x 8, ~3 s),
# the preview smaller still. The code path is the one a default bake takes.
FULL = "draft"
PREVIEW = (8, 32, 8, 4)


@pytest.fixture
def wired(addon_package, tmp_path, monkeypatch):
    monkeypatch.setenv("OLS_CACHE_DIR", str(tmp_path / "cache"))
    baking = extension_module("addon.baking")
    monkeypatch.setattr(baking, "PREVIEW_RESOLUTION", PREVIEW)
    batch = extension_module("addon.batch")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    args = batch.parse_args(["--sample", "--tables", FULL, "--resolution", "32x18", "--samples", "1",
                             "--output", str(tmp_path / "x.png")])
    scene = batch.prepare(args)
    batch.apply_options(scene, args)
    batch.wire(scene, args)
    return scene, baking


def wait_for(condition, timeout=120.0):
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.05)


def sky_images(scene):
    """Names of the table images the world's look-up group reads."""
    lookup = bpy.data.node_groups[names.LOOKUP_GROUP]
    return {node.image.name for node in lookup.nodes if node.type == "TEX_IMAGE" and node.image}


def changed_params(scene):
    settings = extension_module("addon.settings")
    scene.ols.aerosol_density = 1.6             # the slider change
    return settings.atmosphere_params(scene.ols).validate()


def test_a_change_shows_the_preview_then_the_new_tables(wired):
    scene, baking = wired
    old_key, old_images = scene[names.WIRED_KEY], sky_images(scene)
    params = changed_params(scene)
    started = time.perf_counter()
    bake = baking.BackgroundBake(params, FULL, preview=True)
    assert bake.preview_resolution == PREVIEW and baking.latest() is bake
    wait_for(lambda: bake.preview_ready or bake.done)
    assert bake.preview_ready and not bake.error
    # What the operator's timer does when the preview is ready.
    baking.swap_in(scene, bake.preview_directory, preview=True)
    print(f"preview on screen {time.perf_counter() - started:.2f} s after the change")
    assert baking.showing_preview(scene)
    assert scene[names.WIRED_KEY] == bake.preview_directory.name != old_key
    assert sky_images(scene).isdisjoint(old_images)
    assert "draft preview" in baking.progress_line(bake, scene) or bake.done
    assert bake.wait(300) and not bake.error and not bake.superseded
    baking.swap_in(scene, bake.directory)
    assert not baking.showing_preview(scene)
    assert scene[names.WIRED_KEY] == bake.directory.name
    assert baking.latest() is None
    # Baked: the same change again needs no preview.
    assert baking.BackgroundBake(params, FULL, preview=True).preview_resolution is None


def test_a_newer_bake_supersedes_an_older_one(wired):
    scene, baking = wired
    first = baking.BackgroundBake(changed_params(scene), FULL, preview=False)
    first.render_after = "STILL"
    scene.ols.aerosol_density = 0.7
    second = baking.BackgroundBake(extension_module("addon.settings").atmosphere_params(scene.ols), FULL)
    assert first.superseded and second.render_after == "STILL"     # F12 carries over
    assert first.wait(300) and second.wait(300)
    assert not second.superseded and not second.error
    # The older bake stopped before saving anything.
    assert not baking.is_baked(first.params, FULL)
    assert baking.is_baked(second.params, FULL)


def test_a_render_while_the_preview_shows_uses_the_new_tables(wired, tmp_path):
    scene, baking = wired
    params = changed_params(scene)
    bake = baking.BackgroundBake(params, FULL, preview=True)
    wait_for(lambda: bake.preview_ready or bake.done)
    baking.swap_in(scene, bake.preview_directory, preview=True)
    # A file saved now, rendered by a farm worker while this process's bake still runs: the
    # worker re-bakes the tables the scene asks for on load and renders with them.
    blend = tmp_path / "saved_in_preview.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    result = subprocess.run([sys.executable, str(ROOT / "scripts" / "render.py"), "--blend", str(blend),
                             "--output", str(tmp_path / "farm.png")],
                            capture_output=True, text=True, timeout=600, env={**os.environ})
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    assert "saved showing the draft preview" in result.stdout
    assert "draft preview tables" not in result.stdout        # render_init's warning: not rendered in preview
    # In this process the Render operator waits for the bake and swaps the new tables in first.
    output = tmp_path / "ui.png"
    assert bpy.ops.ols.render(filepath=str(output)) == {"FINISHED"}
    assert not baking.showing_preview(scene)
    assert scene[names.WIRED_KEY] == baking.bake_directory(params, FULL).name
    pixels = np.array(bpy.data.images.load(str(output)).pixels[:]).reshape(-1, 4)[:, :3]
    assert pixels.mean() > 0.05                                      # a real picture
    farm = np.array(bpy.data.images.load(str(tmp_path / "farm.png")).pixels[:]).reshape(-1, 4)[:, :3]
    assert np.abs(farm - pixels).max() < 2 / 255                     # the same tables, the same frame


class FakeWindowManager:
    """What the modal operator calls on the window manager and workspace (no window here)."""

    def __init__(self):
        self.status = []

    def progress_update(self, value):
        pass

    def progress_end(self):
        pass

    def event_timer_remove(self, timer):
        pass

    def status_text_set(self, text):
        self.status.append(text)


def test_the_bake_operator_shows_the_preview_and_renders_after_f12(wired, monkeypatch):
    """The Bake Tables operator's modal steps as the UI's timer drives them: the analytic model
    stands in at once, F12 pressed while baking is held back, the draft preview is shown when
    ready, then the full tables, then the render."""
    scene, baking = wired
    ops = extension_module("addon.ops")
    renders = []
    monkeypatch.setattr(ops, "start_render", lambda **kwargs: renders.append(kwargs))
    wm = FakeWindowManager()
    context = types.SimpleNamespace(scene=scene, window_manager=wm, workspace=wm, screen=None, selected_objects=[])
    operator = types.SimpleNamespace(resolution=FULL, setup_after=False, preview=True, reports=[])
    operator.report = lambda kind, message: operator.reports.append((kind, message))
    for method in ("_show", "_finish", "_show_stand_in"):
        setattr(operator, method, getattr(ops.OLS_OT_bake_luts, method).__get__(operator))
    operator._params = changed_params(scene)
    started = time.perf_counter()
    assert baking.wants_preview(operator._params, FULL)
    operator._show_stand_in(context)                                   # what invoke does, then the bake
    print(f"analytic stand-in on screen {time.perf_counter() - started:.2f} s after the change")
    operator._bake = baking.BackgroundBake(operator._params, FULL, preview=True)
    operator._preview_shown, operator._timer = False, None
    assert baking.showing_preview(scene) and baking.preview_name(scene) == "analytic"
    assert not operator.reports
    modal = ops.OLS_OT_bake_luts.modal
    f12 = types.SimpleNamespace(type="F12", value="PRESS", ctrl=False)
    assert modal(operator, context, f12) == {"RUNNING_MODAL"}          # held back, not passed on
    timer = types.SimpleNamespace(type="TIMER", value="NOTHING", ctrl=False)
    seen = set()
    end = time.monotonic() + 300
    while (result := modal(operator, context, timer)) == {"RUNNING_MODAL"}:
        if baking.showing_preview(scene):
            seen.add(baking.preview_name(scene))
        assert time.monotonic() < end, "timed out"
        time.sleep(0.05)
    assert result == {"FINISHED"}, operator.reports
    assert seen == {"analytic", "draft"} and not baking.showing_preview(scene)
    assert scene[names.WIRED_KEY] == baking.bake_directory(operator._params, FULL).name
    assert any("analytic preview" in (line or "") for line in wm.status)
    assert any("draft preview" in (line or "") for line in wm.status) and wm.status[-1] is None
    assert renders == [{"animation": False}]                            # F12's render, after the swap


def test_unwiring_drops_the_preview_mark(wired):
    """An unwired scene never counts as showing a preview (a file load would re-bake into it)."""
    scene, baking = wired
    baking.mark_preview(scene, True)
    assert baking.showing_preview(scene)
    extension_module("addon.scene.setup.wiring").unwire_scene(scene)
    assert names.PREVIEW_KEY not in scene and not baking.showing_preview(scene)
    scene[names.PREVIEW_KEY] = True                 # a stale mark on an unwired scene
    assert not baking.showing_preview(scene)


def test_the_analytic_model_stands_in_only_where_it_shows_what_the_scene_asks_for(wired):
    """No analytic stand-in with fog, clouds or the sun below 2 deg (it has none of those: its
    sky is black without the sun); the draft alone then. A render in the stand-in settles to
    the tables asked for."""
    scene, baking = wired
    assert baking.analytic_can_stand_in(scene)
    scene.ols.fog_visibility = 2000.0
    assert not baking.analytic_can_stand_in(scene)
    scene.ols.fog_visibility = 0.0
    scene.ols.clouds_enabled = True
    assert not baking.analytic_can_stand_in(scene)
    scene.ols.clouds_enabled = False
    sun = extension_module("addon.scene.sun").find_sun(scene)
    rotation = tuple(sun.rotation_euler)
    sun.rotation_euler = (0.0, -1.55, 0.0)           # the sun 1.2 deg up
    bpy.context.view_layer.update()
    assert not baking.analytic_can_stand_in(scene)
    sun.rotation_euler = rotation
    bpy.context.view_layer.update()
    key = scene[names.WIRED_KEY]
    shafts = scene.compositing_node_group.nodes[names.SHAFTS_NODE]
    layout = shafts.node_tree[names.LAYOUT_KEY]
    baking.show_analytic_stand_in(scene)
    assert baking.preview_name(scene) == "analytic" and baking.showing_preview(scene)
    # The stand-in lasts until the draft: the tables' shafts are kept, muted (their air is not the
    # analytic aerial group's), and not rebuilt as the analytic ones, not even by a scene update.
    extension_module("addon.scene.setup.wiring").match_light_shaft_layout(scene)
    assert shafts.mute and shafts.node_tree[names.LAYOUT_KEY] == layout
    params = extension_module("addon.settings").validated_params(scene.ols)     # what a render hands down
    assert baking.settle(scene, params) and scene[names.WIRED_KEY] == key and not baking.showing_preview(scene)
    assert not shafts.mute and shafts.node_tree[names.LAYOUT_KEY] == layout
