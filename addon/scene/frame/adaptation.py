"""Light adaptation across frames: the tone mapping of frame f uses the luminance the eye adapted
to by then, previous + (measured - previous)(1 - exp(-rate dt)), the sample's rate 1/s.

A compositor tree has no memory across frames, so Python carries the adapted luminance. The
"OLS Tone Mapping" group outputs the luminance a frame used as a 1 x 1 image; our File Output node
writes it to a temporary EXR (Viewer nodes do not run in background renders; File Output nodes
run in every final render). The render handlers read it back after each frame and set the
group's "Previous Luminance" and "Adaptation Weight" for the next one.

When the inputs must be set (measured in bpy 5.0.1): a still render (render_init, render_pre,
then the pipeline depsgraph is built) takes what render_pre sets. An animation render evaluates
its pipeline depsgraph for frame f *before* render_pre and frame_change_pre of f, so values set
there reach the compositor one frame late; the values for f + step are set in render_post of f,
and those for the first frame in render_init.
"""
from __future__ import annotations

import os
import struct
import tempfile
from contextlib import contextmanager
from pathlib import Path

import bpy

from ....lut_gen.store import exr_min
from ....lut_gen.passes import tone_mapping as twin
from ..file_outputs import new_file_output, park
from .. import names

OUTPUT_FILE = "adapted_luminance_"

# This render job's stored plan (adaptation_plan.py), loaded once per job; and whether the
# pre-pass is measuring (every frame unadapted).
_job = {"plan": None, "measuring": False, "read_back": True}


@contextmanager
def without_read_back():
    """A still rendered from a script adapts to nothing after it: no luminance file is written
    (and Blender prints no 'Saved: ...adapted_luminance_.exr' line)."""
    _job["read_back"] = False
    try:
        yield
    finally:
        _job["read_back"] = True


@contextmanager
def unadapted():
    """Renders inside measure each frame's own luminance (the pre-pass of adaptation_plan)."""
    _job["measuring"] = True
    try:
        yield
    finally:
        _job["measuring"] = False


# -- the adaptation state (pure) ----------------------------------------------------------------

def frame_seconds(fps: int, fps_base: float) -> float:
    return fps_base / fps


def inputs_for_frame(frame: int, last_frame, last_luminance, *, enabled: bool, frame_step: int,
                     seconds_per_frame: float, rate: float = twin.ADAPTATION_RATE):
    """("Previous Luminance", "Adaptation Weight") for rendering ``frame`` after the last frame
    rendered (``last_frame``, None if none). The eye adapts only along a sequence: ``frame`` must
    follow ``last_frame`` by 1 to ``frame_step`` frames; a jump or a re-render starts afresh
    (weight 1: the frame's own measured luminance)."""
    fresh = (twin.FIXED_AVERAGE_LUMINANCE, 1.0)
    if not enabled or last_frame is None or last_luminance is None:
        return fresh
    frames = frame - last_frame
    if not 0 < frames <= max(frame_step, 1):
        return fresh
    return float(last_luminance), twin.adaptation_weight(frames * seconds_per_frame, rate)


def inputs_from_plan(plan: dict, frame: int):
    """("Previous Luminance", "Adaptation Weight") for ``frame``; None if the plan has no such
    frame (then adaptation falls back to the frames this process rendered)."""
    start, step, adapted = plan["start"], plan["step"], plan["adapted"]
    index, off_grid = divmod(frame - start, step)
    if off_grid or not 0 <= index < len(adapted):
        return None
    if index == 0:
        return twin.FIXED_AVERAGE_LUMINANCE, 1.0
    return adapted[index - 1], plan["weight"]


def read_exr_pixel(path) -> float:
    """The luminance our File Output node wrote (one uncompressed pixel). Blender's Python has no
    OpenEXR, and loading an image datablock from a render handler (the render job's thread in the
    UI) is not safe, so lut_gen's small EXR reader parses the bytes."""
    return exr_min.read_first_pixel(path)


# -- the scene side -----------------------------------------------------------------------------

_private_tempdir = {}


def _process_tempdir() -> str:
    """Blender's per-process temporary folder; where Blender has none, a private one of ours
    (never the shared system folder: a link planted there would be followed)."""
    if bpy.app.tempdir:
        return bpy.app.tempdir
    if "path" not in _private_tempdir:
        _private_tempdir["path"] = tempfile.mkdtemp(prefix="ols_adaptation_")
    return _private_tempdir["path"]


def output_directory(scene) -> str:
    """Per scene and per Blender process: Blender's temporary folder goes away when Blender exits."""
    return os.path.join(_process_tempdir(), "ols_adaptation", bpy.path.clean_name(scene.name), "")


def ensure_output_node(tree, tone_node):
    """Our File Output node, fed by the tone-mapping group's "Adapted Luminance" (idempotent)."""
    node = tree.nodes.get(names.ADAPTED_LUMINANCE_NODE)
    if node is None:
        node = new_file_output(tree, names.ADAPTED_LUMINANCE_NODE, (tone_node.location.x, tone_node.location.y - 200),
                               media_type="IMAGE", file_format="OPEN_EXR", exr_codec="NONE",
                               items=[("FLOAT", "")], color_mode="BW")
        node.file_name = OUTPUT_FILE
    if not node.inputs[0].is_linked:
        tree.links.new(tone_node.outputs["Adapted Luminance"], node.inputs[0])
    return node


def remove_output_node(tree):
    node = tree.nodes.get(names.ADAPTED_LUMINANCE_NODE)
    if node is not None:
        tree.nodes.remove(node)


def _nodes(scene):
    tree = scene.compositing_node_group
    if tree is None:
        return None, None
    tone, output = tree.nodes.get(names.TONE_NODE), tree.nodes.get(names.ADAPTED_LUMINANCE_NODE)
    if tone is None or tone.node_tree is None or "Adaptation Weight" not in tone.inputs:
        return None, output
    return tone, output


def _set(tone, previous: float, weight: float):
    """Only what changed (every assignment tags the depsgraph)."""
    for name, value in (("Previous Luminance", previous), ("Adaptation Weight", weight)):
        if abs(tone.inputs[name].default_value - value) > 1e-7 * max(1.0, abs(value)):
            tone.inputs[name].default_value = value


def push_inputs(scene, frame: int):
    """Set the group's adaptation inputs for rendering ``frame`` from the stored state."""
    tone, _ = _nodes(scene)
    if tone is None:
        return
    render = scene.render
    planned = None
    if _job["plan"] is not None and scene.ols.light_adaptation and not _job["measuring"]:
        planned = inputs_from_plan(_job["plan"], frame)
    previous, weight = planned or inputs_for_frame(
        frame, scene.get(names.ADAPTED_FRAME_KEY), scene.get(names.ADAPTED_LUMINANCE_KEY),
        enabled=scene.ols.light_adaptation and not _job["measuring"],
        frame_step=scene.frame_step, seconds_per_frame=frame_seconds(render.fps, render.fps_base))
    _set(tone, previous, weight)


def _clear_files(directory: str):
    for entry in Path(directory).glob("*.exr"):
        entry.unlink(missing_ok=True)


def forget(scene):
    for key in (names.ADAPTED_LUMINANCE_KEY, names.ADAPTED_FRAME_KEY):
        if key in scene:
            del scene[key]


def record_frame(scene, frame: int):
    """After a frame: store the luminance it used (from our File Output's file) as the state.
    No file (compositing off, pass not wired): the sequence is broken, forget the state."""
    _, output = _nodes(scene)
    files = sorted(Path(output.directory).glob("*.exr"), key=lambda p: p.stat().st_mtime) if output else []
    luminance = None
    if files:
        try:
            luminance = read_exr_pixel(files[-1])
        except (OSError, ValueError, struct.error) as exc:
            print(f"Outdoor Light Scattering: cannot read the adapted luminance: {exc}")
        _clear_files(output.directory)
    if luminance is None or not luminance > 0.0:
        forget(scene)
        return
    scene[names.ADAPTED_LUMINANCE_KEY] = luminance
    scene[names.ADAPTED_FRAME_KEY] = frame


def reads_back(scene) -> bool:
    """Whether a render job of the scene reads back the luminance it adapted to (the scene is
    wired, no still without read-back, not measuring the adaptation plan)."""
    _, output = _nodes(scene)
    return output is not None and _job["read_back"] and not _job["measuring"]


def begin_render(scene, plan=None):
    """A render job starts: point our File Output at this process's folder, drop stale files and
    set the inputs for the first frame an animation renders (a still's render_pre corrects them).
    ``plan``: the job's stored adaptation plan (adaptation_plan.for_render), or None."""
    _, output = _nodes(scene)
    if output is None:
        return
    if not _job["read_back"]:
        park(output)
        return
    directory = output_directory(scene)
    os.makedirs(directory, exist_ok=True)
    _clear_files(directory)
    if output.directory != directory:
        output.directory = directory
    output.mute = False
    _job["plan"] = plan if scene.ols.light_adaptation and not _job["measuring"] else None
    push_inputs(scene, scene.frame_start)


def end_render(scene):
    """Back to no adaptation, so the viewport compositor and a saved file show the plain frame."""
    _job["plan"] = None
    tone, output = _nodes(scene)
    if tone is not None:
        _set(tone, twin.FIXED_AVERAGE_LUMINANCE, 1.0)
    if output is not None:
        park(output)
