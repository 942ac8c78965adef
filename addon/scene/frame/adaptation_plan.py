"""Light adaptation that does not depend on which frames a process rendered before.

A render farm gives each worker a chunk of frames (blender -b file.blend -s A -e B -a), each in a
fresh process: adaptation carried from frame to frame (adaptation.py) starts afresh at every
chunk, and the brightness jumps at chunk boundaries. A plan removes that dependency:

- a low-resolution pre-pass (light shafts off, at most 8 samples, about 64 pixels wide) measures
  the log-average luminance m_f of every frame of the animation, as the tone mapping measures it;
- the adapted luminance follows from those alone: A_first = m_first,
  A_f = A_prev + (m_f - A_prev)(1 - exp(-rate dt));
- frame f is tone mapped with "Previous Luminance" = A_prev from the plan and its own
  full-resolution measure, the same in one job and in any chunk.

The plan is stored in the scene (it is saved with the .blend) with its own frames and a signature
of what it depends on: the frame step and rate, the resolution, the panel's settings, and each
object's transform, visibility and animation keys (not the frame range, which a chunk changes). A plan that is missing, damaged or made for another state of the
scene is not used (one warning line); frames then adapt along what the process renders.
"""
from __future__ import annotations

import hashlib
import json
import math
from contextlib import contextmanager

import bpy

from ....lut_gen.passes import tone_mapping as twin
from . import adaptation
from .. import names

VERSION = 1
PREPASS_WIDTH_PX = 64
PREPASS_MAX_SAMPLES = 8


class PlanError(ValueError):
    pass


# -- pure -----------------------------------------------------------------------------------

def adapted_sequence(measured, weight: float) -> list:
    """Adapted luminance per frame from the measured ones, the first frame unadapted."""
    adapted = []
    for value in measured:
        adapted.append(float(value) if not adapted else twin.adapt(adapted[-1], float(value), weight))
    return adapted


def check_plan(plan) -> dict:
    """The plan if its structure and numbers are sound, else PlanError saying what is wrong."""
    if not isinstance(plan, dict) or plan.get("version") != VERSION:
        raise PlanError("it is not a version-1 plan")
    try:
        start, end, step = (int(plan[k]) for k in ("start", "end", "step"))
        weight = float(plan["weight"])
        adapted = [float(v) for v in plan["adapted"]]
        signature = str(plan["signature"])
    except (KeyError, TypeError, ValueError):
        raise PlanError("it lacks a field or holds a non-number") from None
    if step < 1 or end < start or len(adapted) != len(range(start, end + 1, step)):
        raise PlanError("its frames do not match its values")
    if not 0.0 <= weight <= 1.0 or not all(math.isfinite(v) and v > 0.0 for v in adapted):
        raise PlanError("it holds a luminance or weight out of range")
    return dict(start=start, end=end, step=step, weight=weight, adapted=adapted, signature=signature)


# -- the scene side -------------------------------------------------------------------------

def _keys(idblock):
    """The animation keys of a data-block (None: not animated)."""
    animation = getattr(idblock, "animation_data", None)
    if animation is None or animation.action is None:
        return None
    from bpy_extras import anim_utils
    bag = anim_utils.action_get_channelbag_for_slot(animation.action, animation.action_slot)
    if bag is None:
        return None
    return [(c.data_path, c.array_index, [[round(v, 6) for v in k.co] for k in c.keyframe_points]) for c in bag.fcurves]


def _setting(value):
    """A control's value for the signature: vectors (colours) as rounded lists, the rest as repr."""
    if isinstance(value, str) or not hasattr(value, "__len__"):
        return repr(value)
    return [round(v, 6) for v in value]


def signature(scene) -> str:
    """A digest of what the frames' luminance depends on, the same at every frame of the scene."""
    render, settings = scene.render, scene.ols
    names = [p.identifier for p in settings.bl_rna.properties if p.identifier not in {"rna_type", "control_set"}]
    state = {
        # Not the frame range: a farm's chunk changes it (the plan holds its own frames).
        "scene": scene.name, "frame_step": scene.frame_step,
        "fps": [render.fps, render.fps_base], "size": [render.resolution_x, render.resolution_y],
        "camera": scene.camera.name if scene.camera else None,
        "settings": {name: _setting(getattr(settings, name)) for name in names},
        "objects": [],
    }
    for obj in sorted(scene.objects, key=lambda o: o.name):
        keys = _keys(obj)
        # The animated sun is moved by the add-on per frame: its settings above describe it.
        moved = keys is not None or (settings.animate_sun and obj.type == "LIGHT" and obj.data.type == "SUN")
        entry = [obj.name, obj.type, obj.hide_render, keys,
                 None if moved else [round(v, 6) for row in obj.matrix_world for v in row]]
        if obj.type == "LIGHT":
            entry += [_keys(obj.data), round(obj.data.energy, 6)]
        elif obj.type == "MESH":
            entry += [len(obj.data.vertices)]
        state["objects"].append(entry)
    return hashlib.sha256(json.dumps(state, sort_keys=True, default=str).encode()).hexdigest()


def frame_weight(scene) -> float:
    """The adaptation weight between two frames a frame step apart."""
    render = scene.render
    return twin.adaptation_weight(max(scene.frame_step, 1) * adaptation.frame_seconds(render.fps, render.fps_base))


@contextmanager
def _prepass_settings(scene):
    render, settings = scene.render, scene.ols
    saved = (render.resolution_percentage, render.use_compositing, scene.cycles.samples,
             scene.eevee.taa_render_samples, settings.enable_light_shafts, scene.frame_current)
    try:
        render.resolution_percentage = max(1, min(100, round(100 * PREPASS_WIDTH_PX / max(render.resolution_x, 1))))
        render.use_compositing = True
        scene.cycles.samples = min(scene.cycles.samples, PREPASS_MAX_SAMPLES)
        scene.eevee.taa_render_samples = min(scene.eevee.taa_render_samples, PREPASS_MAX_SAMPLES)
        settings.enable_light_shafts = False
        yield
    finally:
        (render.resolution_percentage, render.use_compositing, scene.cycles.samples,
         scene.eevee.taa_render_samples, settings.enable_light_shafts, frame) = saved
        scene.frame_set(frame)
        adaptation.forget(scene)


def measure(scene, frames, progress=print) -> list:
    """The log-average luminance of ``frames`` from the low-resolution pre-pass."""
    measured = []
    with _prepass_settings(scene), adaptation.unadapted():
        for number, frame in enumerate(frames, 1):
            scene.frame_set(frame)
            bpy.ops.render.render()
            value = scene.get(names.ADAPTED_LUMINANCE_KEY)
            if value is None or not value > 0.0:
                raise PlanError(f"the pre-pass of frame {frame} measured no luminance (is compositing "
                                "off, or the tone mapping unwired?)")
            measured.append(float(value))
            if progress:
                progress(f"light adaptation: measured frame {frame} ({number}/{len(frames)})")
    return measured


def build(scene, start=None, end=None, progress=print) -> dict:
    """Measure frames ``start``-``end`` (default: the scene's frame range) and store their plan
    in the scene; returns the plan."""
    start = scene.frame_start if start is None else start
    end = scene.frame_end if end is None else end
    if end < start:
        raise PlanError(f"the frames run backward ({start}-{end})")
    step, weight = max(scene.frame_step, 1), frame_weight(scene)
    frames = range(start, end + 1, step)
    measured = measure(scene, frames, progress)
    plan = dict(version=VERSION, start=start, end=frames[-1], step=step, weight=weight,
                adapted=adapted_sequence(measured, weight), signature=signature(scene))
    scene[names.ADAPTATION_PLAN_KEY] = json.dumps(plan)
    return plan


def stored(scene):
    """(plan, problem): the scene's plan if it is sound and made for the scene as it is now, else
    None and why not (None, None: there is no plan)."""
    text = scene.get(names.ADAPTATION_PLAN_KEY)
    if text is None:
        return None, None
    try:
        plan = check_plan(json.loads(text))
    except (PlanError, ValueError, TypeError, RecursionError) as exc:
        return None, f"the stored light-adaptation plan is damaged ({exc})"
    if plan["signature"] != signature(scene):
        return None, ("the stored light-adaptation plan was made for another state of the scene (frame "
                      "rate or step, resolution, settings, objects or animation changed)")
    return plan, None


# Frames before a chunk that still matter: the adapted luminance forgets a frame by (1 - w) per
# frame, so after this many the difference from one job over the whole range is below 1e-6.
FORGETTING = 1e-6


def history_frames(weight: float) -> int:
    if weight >= 1.0:
        return 1
    return max(1, math.ceil(math.log(FORGETTING) / math.log(1.0 - weight)))


def first_frame_needed(scene, first: int) -> int:
    """The earliest frame whose luminance still reaches frame ``first`` of a chunk (the
    animation's first frame for chunks less than history_frames into it)."""
    step = max(scene.frame_step, 1)
    start = min(scene.frame_start, first)
    earliest = first - history_frames(frame_weight(scene)) * step
    return max(start, start + -(-(earliest - start) // step) * step)


def wanted(scene) -> bool:
    """Whether renders of this scene adapt (and so need a plan for their frames)."""
    return bool(scene.get(names.WIRED_KEY)) and scene.ols.light_adaptation and scene.render.use_compositing


def ensure(scene, start: int, end: int, progress=print) -> dict:
    """A plan that covers frames ``start``-``end``: the stored one if it is current and does,
    else a new one measured from ``start``."""
    plan, problem = stored(scene)
    if problem and progress:
        progress(f"light adaptation: {problem}; measuring again")
    if plan is not None and plan["start"] <= start and plan["end"] >= end \
            and (start - plan["start"]) % plan["step"] == 0:
        return plan
    return build(scene, start, end, progress)


def for_render(scene):
    """The plan a render job of the scene follows: None where the job does not adapt, or where
    the scene has no current plan, and then one line saying why frames adapt along this
    process's renders instead (a farm's chunks then differ at their boundaries)."""
    if not (scene.ols.light_adaptation and adaptation.reads_back(scene)):
        return None
    plan, problem = stored(scene)
    if problem is not None:
        print(f"Outdoor Light Scattering: {problem}: frames adapt along the frames this process renders, "
              "so chunks rendered apart differ at their boundaries; press Measure Light Adaptation "
              "(Tone mapping panel) and save, or render with scripts/render.py, which measures itself")
    return plan


def forget(scene):
    if names.ADAPTATION_PLAN_KEY in scene:
        del scene[names.ADAPTATION_PLAN_KEY]
