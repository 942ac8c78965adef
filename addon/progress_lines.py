"""Progress of headless jobs as plain lines (logs of batch renders and farms show no
self-updating terminal line): at most one line every few seconds per job, and one per finished
stage, so a long bake or render is never silent for more than about 5 s."""
from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager

import bpy

INTERVAL_S = 5.0


class ProgressLines:
    """A lut_gen Progress callback (stage, fraction) that prints ``prefix: stage 42% (12 s)``."""

    def __init__(self, prefix: str, interval: float = INTERVAL_S, stream=None):
        self.prefix, self.interval, self.stream = prefix, interval, stream or sys.stdout
        self.start = time.perf_counter()
        self.last = -float("inf")           # the first line comes at once
        self.stage = None
        self._lock = threading.Lock()

    def line(self, text: str, force: bool = False):
        with self._lock:                    # the render heartbeat calls from its own thread
            now = time.perf_counter()
            if not (force or now - self.last >= self.interval):
                return
            self.last = now
            print(f"{self.prefix}: {text} ({now - self.start:.0f} s)", file=self.stream, flush=True)

    def __call__(self, stage: str, fraction: float):
        new_stage, self.stage = stage != self.stage, stage
        self.line(f"{stage} {fraction:.0%}", force=new_stage or fraction >= 1.0)


def render_summary(stats: str) -> str:
    """The parts of a render_stats line a log reader wants: 'Sample 12/32, Remaining: 00:10.21'."""
    parts = [p.strip() for p in stats.split("|")]
    keep = [p for p in parts if p.startswith(("Sample", "Remaining", "Finished", "Rendered", "Path Tracing"))]
    return ", ".join(keep) or (parts[-1] if parts else "")


@contextmanager
def render_progress(stream=None):
    """Print render progress (Cycles and EEVEE report it through render_stats) while the block
    runs, and one line per frame finished. render_stats comes only now and then in background
    renders (every ~30 s at 960 x 540 on 2 cores), so a thread repeats the last state every
    INTERVAL_S (the render releases Python while it works)."""
    lines = ProgressLines("render", stream=stream)
    latest = {"text": "starting (shadow maps, scene sync)"}
    done = threading.Event()

    def on_stats(stats, *_args):
        frame = bpy.context.scene.frame_current if bpy.context.scene else "?"
        first = latest.get("frame") != frame          # each frame's first report comes at once
        latest["frame"], latest["text"] = frame, f"frame {frame}: {render_summary(stats)}"
        lines.line(latest["text"], force=first)

    def heartbeat():
        while not done.wait(1.0):
            lines.line(f"{latest['text']} (last report; still working)")

    def on_frame_done(scene, *_args):
        lines.line(f"frame {scene.frame_current} rendered and composited", force=True)

    handlers = ((bpy.app.handlers.render_stats, on_stats), (bpy.app.handlers.render_post, on_frame_done))
    for handler_list, function in handlers:
        handler_list.append(function)
    thread = threading.Thread(target=heartbeat, name="ols render progress", daemon=True)
    thread.start()
    try:
        yield lines
    finally:
        done.set()
        thread.join()
        for handler_list, function in handlers:
            if function in handler_list:
                handler_list.remove(function)
