"""The epipolar grid of the light shafts (Yusov 2012, "IVB Atmospheric Light Scattering"): the
sample's epipolar controls, the parametrisation of one frame's view rays by slice and sample, and
the grid nodes a render's pixels read. The tables on this grid: lut_gen.passes.epipolar.

Every view ray of the frame lies in a plane through the camera that holds the sun direction
(an epipolar slice, Yusov 2012 section 4). A ray is named by two angles: ``phi``, the slice's turn
about the sun axis, and ``theta``, the ray's angle from the sun within its slice. The epipole is
theta = 0, the anti-solar point theta = pi, so the epipole on screen, off screen or behind the
camera needs no special case, and no slice has a seam (a full turn of phi repeats its first
slice as its last).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from . import render_detail
from ..clouds import shafts as cloud_shafts
from .shadow_map import MIN_FORWARD_COSINE, Camera

MIN_NEAR = 10.0                 # m: the distance grid is geometric from here (1 m: 4 dB worse on the sample)
BORDER_POINTS = 256             # points per screen edge when finding the angle ranges


@dataclass(frozen=True)
class EpipolarSettings:
    """The sample's epipolar controls (scene.ols names)."""
    slices: int = 512
    samples: int = 256
    steps: int = 32                     # distances per ray (Num integration steps)
    initial_sample_step: int = 16
    epipole_sampling_density: int = 2
    refinement_threshold: float = 0.03
    use_min_max: bool = True

    def checked(self) -> "EpipolarSettings":
        for name in ("slices", "samples", "steps", "initial_sample_step", "epipole_sampling_density"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"epipolar {name.replace('_', ' ')} must be a positive integer, got {value!r}")
        if self.slices < 2 or self.samples < 2 or self.steps < 2:
            raise ValueError("epipolar sampling needs at least 2 slices, 2 samples and 2 steps")
        if not np.isfinite(self.refinement_threshold) or self.refinement_threshold < 0:
            raise ValueError(f"the refinement threshold must be >= 0, got {self.refinement_threshold!r}")
        return self


def settings_from(controls) -> EpipolarSettings:
    """EpipolarSettings from anything holding the panel's names (scene.ols, scattering_pass's
    PassSettings)."""
    return EpipolarSettings(
        slices=controls.epipolar_slices, samples=controls.samples_per_slice, steps=controls.num_integration_steps,
        initial_sample_step=controls.initial_sample_step, epipole_sampling_density=controls.epipole_sampling_density,
        refinement_threshold=controls.refinement_threshold, use_min_max=controls.use_min_max_optimization)


def for_render(wanted: EpipolarSettings, width: int, height: int) -> EpipolarSettings:
    """``wanted`` with its slices and samples capped at what a width x height render resolves
    (lut_gen.passes.render_detail; the add-on's settings arrive capped already)."""
    return replace(wanted, slices=render_detail.epipolar_slices(wanted.slices, width, height),
                   samples=render_detail.epipolar_samples(wanted.samples, width, height))


@dataclass(frozen=True)
class EpipolarFrame:
    """The parametrisation of one frame: the sun, two axes across it, the angle ranges the
    screen covers (``phi0`` + [0, phi_span], ``theta0`` + [0, theta_span]), and the distance
    grid t_k = t_max ((1 + a)^(k / (K - 1)) - 1) / a."""
    sun: np.ndarray
    axis1: np.ndarray
    axis2: np.ndarray
    phi0: float
    phi_span: float
    theta0: float
    theta_span: float
    t_max: float
    growth: float
    slices: int
    samples: int
    steps: int

    @property
    def full_turn(self) -> bool:
        return self.phi_span >= 2.0 * np.pi - 1e-9

    def distances(self) -> np.ndarray:
        k = np.arange(self.steps) / (self.steps - 1)
        return self.t_max * np.expm1(k * np.log1p(self.growth)) / self.growth

    def distance_to_x(self, t):
        """Fractional distance-node index of distances ``t``."""
        t = np.clip(np.asarray(t, dtype=np.float64), 0.0, self.t_max)
        return (self.steps - 1) * np.log1p(self.growth * t / self.t_max) / np.log1p(self.growth)

    def angles(self, directions):
        """(phi, theta) of unit directions (..., 3)."""
        d = np.asarray(directions, dtype=np.float64)
        theta = np.arccos(np.clip(d @ self.sun, -1.0, 1.0))
        phi = np.arctan2(d @ self.axis2, d @ self.axis1)
        return phi, theta

    def direction_to_x(self, directions):
        """(slice coordinate in [0, slices], sample coordinate in [0, samples - 1])."""
        phi, theta = self.angles(directions)
        u = np.mod(phi - self.phi0, 2.0 * np.pi) if self.full_turn else phi - self.phi0
        x = np.clip(u / self.phi_span, 0.0, 1.0) * self.slices
        y = np.clip((theta - self.theta0) / self.theta_span, 0.0, 1.0) * (self.samples - 1)
        return x, y

    def node_directions(self) -> np.ndarray:
        """(slices + 1, samples, 3) unit directions of the grid nodes."""
        phi = self.phi0 + self.phi_span * np.arange(self.slices + 1) / self.slices
        theta = self.theta0 + self.theta_span * np.arange(self.samples) / (self.samples - 1)
        across = np.cos(phi)[:, None] * self.axis1 + np.sin(phi)[:, None] * self.axis2      # (S+1, 3)
        return (np.cos(theta)[None, :, None] * self.sun + np.sin(theta)[None, :, None] * across[:, None, :])

    def as_values(self) -> dict:
        """The "OLS Frame Values" rows the node group reads."""
        return {"Epipolar Axis 1": self.axis1, "Epipolar Axis 2": self.axis2,
                "Epipolar Phi": (self.phi0, self.phi_span, float(self.full_turn)),
                "Epipolar Theta": (self.theta0, self.theta_span, 0.0),
                "Epipolar Depth": (self.t_max, self.growth, 0.0),
                "Epipolar Grid": (self.slices, self.samples, self.steps)}


def _unit(v):
    return v / np.linalg.norm(v)


def frame_for(camera: Camera, sun_direction, width: int, height: int, far: float,
              settings: EpipolarSettings, reach: float = 0.0) -> EpipolarFrame:
    """The parametrisation that covers the camera's screen out to view depth ``far``, and its
    rays out to distance ``reach`` (the clouds' march, cloud_reach)."""
    settings = settings.checked()
    sun = _unit(np.asarray(sun_direction, dtype=np.float64))
    forward = camera.forward
    across = forward - sun * (forward @ sun)
    if np.linalg.norm(across) < 1e-6:           # looking straight at (or away from) the sun
        across = np.asarray(camera.rotation)[:, 1] - sun * (np.asarray(camera.rotation)[:, 1] @ sun)
    axis1 = _unit(across)
    axis2 = np.cross(sun, axis1)
    frame = EpipolarFrame(sun, axis1, axis2, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, settings.slices, settings.samples,
                          settings.steps)
    border = _screen_border(camera, width, height)
    phi, theta = frame.angles(border)
    tx, ty = camera.tan_half_fov
    rotation = np.asarray(camera.rotation, dtype=np.float64)
    sun_inside = _on_screen(rotation, sun, tx, ty)
    anti_inside = _on_screen(rotation, -sun, tx, ty)
    theta_lo = 0.0 if sun_inside else float(theta.min())
    theta_hi = np.pi if anti_inside else float(theta.max())
    if sun_inside or anti_inside:
        phi_lo, phi_span = -np.pi, 2.0 * np.pi
    else:                                       # the screen subtends less than pi around the sun axis
        phi_lo, phi_span = float(phi.min()), float(phi.max() - phi.min())
    # Half a pixel's angle of margin so border pixels interpolate inside the grid.
    pixel = 2.0 * max(tx / width, ty / height)
    theta_lo, theta_hi = max(theta_lo - pixel, 0.0), min(theta_hi + pixel, np.pi)
    if phi_span < 2.0 * np.pi:
        phi_lo, phi_span = phi_lo - pixel, min(phi_span + 2.0 * pixel, 2.0 * np.pi)
    t_max = max(far / max(corner_cosine(camera), MIN_FORWARD_COSINE), 2.0 * MIN_NEAR, reach)
    return EpipolarFrame(sun, axis1, axis2, phi_lo, max(phi_span, 1e-6), theta_lo, max(theta_hi - theta_lo, 1e-6),
                         t_max, t_max / MIN_NEAR, settings.slices, settings.samples, settings.steps)


def cloud_reach(clouds, camera: Camera, width: int, height: int, earth_radius: float) -> float:
    """How far the sky's rays march to the cloud layer (lut_gen.clouds.shafts) across the
    screen's border, where its lowest and highest rays lie; 0 without clouds."""
    if clouds is None:
        return 0.0
    return cloud_shafts.reach(clouds[0], camera.position, _screen_border(camera, width, height), earth_radius)


def corner_cosine(camera: Camera) -> float:
    """Cosine between the view axis and the screen's corner rays."""
    tx, ty = camera.tan_half_fov
    return 1.0 / np.sqrt(1.0 + tx * tx + ty * ty)


def _screen_border(camera: Camera, width: int, height: int) -> np.ndarray:
    s = np.linspace(-1.0, 1.0, BORDER_POINTS)
    return _border_directions(camera, s, s)


def _border_directions(camera: Camera, x, y) -> np.ndarray:
    """Unit world directions through the border of the screen rectangle whose columns are at
    ``x`` and rows at ``y`` (increasing, in units of the half field of view's tangents)."""
    tx, ty = camera.tan_half_fov
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    xy = np.concatenate([np.stack(np.broadcast_arrays(x, y[0]), -1), np.stack(np.broadcast_arrays(x, y[-1]), -1),
                         np.stack(np.broadcast_arrays(x[0], y), -1), np.stack(np.broadcast_arrays(x[-1], y), -1)])
    local = np.stack([xy[:, 0] * tx, xy[:, 1] * ty, -np.ones(len(xy))], axis=-1)
    world = local @ np.asarray(camera.rotation, dtype=np.float64).T
    return world / np.linalg.norm(world, axis=-1, keepdims=True)


def screen_nodes(frame: EpipolarFrame, camera: Camera, width: int, height: int) -> np.ndarray:
    """(slices + 1, samples) bool: the grid nodes the pixels of a width x height render read.
    A pixel reads the four nodes around it (``trilinear``, the compositor's fetches); with one
    node more on every side (the compositor finds its cell in float32) these are all the nodes
    any pixel can read, and building only them leaves every pixel's look-up as it was. Where
    the screen covers only part of the grid's (phi, theta) rectangle (half of it for the
    sample's view) the rest need not be marched."""
    # Pixel centres lie inside the rectangle of the outermost ones: a cell holds pixels where a
    # corner node lies inside that rectangle or its border crosses the cell (the border's pixel
    # centres, a pixel apart, find every cell it crosses that a pixel centre can lie in).
    columns = (2.0 * np.arange(width) + 1.0) / width - 1.0
    rows = (2.0 * np.arange(height) + 1.0) / height - 1.0
    tx, ty = camera.tan_half_fov
    local = frame.node_directions() @ np.asarray(camera.rotation, dtype=np.float64)     # camera axes
    depth = -local[..., 2]
    inside = ((depth > 0.0) & (np.abs(local[..., 0]) <= columns[-1] * tx * depth)
              & (np.abs(local[..., 1]) <= rows[-1] * ty * depth))
    cells = inside[:-1, :-1] | inside[1:, :-1] | inside[:-1, 1:] | inside[1:, 1:]     # (slices, samples - 1)
    x, y = frame.direction_to_x(_border_directions(camera, columns, rows))
    cells[np.minimum(x.astype(np.int64), frame.slices - 1), np.minimum(y.astype(np.int64), frame.samples - 2)] = True
    cells = _grown(cells, frame.full_turn)
    nodes = np.zeros((frame.slices + 1, frame.samples), dtype=bool)
    for di in (0, 1):
        for dj in (0, 1):
            nodes[di:frame.slices + di, dj:frame.samples - 1 + dj] |= cells
    if frame.full_turn:                         # the last slice node is the first one's direction
        nodes[0] |= nodes[-1]
        nodes[-1] = nodes[0]
    return nodes


def _grown(cells, wrap: bool):
    """``cells`` (slices, samples - 1) and their eight neighbours; across the first and last
    slice too when ``wrap`` (a full turn)."""
    grown = cells.copy()
    grown[:, 1:] |= cells[:, :-1]
    grown[:, :-1] |= cells[:, 1:]
    along = grown.copy()
    grown[1:] |= along[:-1]
    grown[:-1] |= along[1:]
    if wrap:
        grown[0] |= along[-1]
        grown[-1] |= along[0]
    return grown


def _on_screen(rotation, direction, tx, ty) -> bool:
    local = rotation.T @ direction
    if local[2] >= 0.0:                         # behind the camera
        return False
    x, y = local[0] / -local[2], local[1] / -local[2]
    return abs(x) <= tx and abs(y) <= ty
