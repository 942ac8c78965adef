"""The cloud layer's settings and its geometry: a shell around the Earth between ``base`` and
``base + thickness`` above the ground, each column of it a homogeneous slab filling
field.thickness_fraction of the shell's thickness about its middle. Rays meet the layer at the
middle sphere, so the layer follows the Earth's curvature and sinks toward the horizon.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

# (default, low, high) per setting; NaN takes the default, the rest clamp (as the other controls).
# Density: 20 / 600 m gives an optical depth of 20 through a full-thickness default cloud, the
# middle of stratocumulus and fair-weather cumulus optical depths (5-40; cumulus liquid water
# of 0.3-0.5 g/m^3 in 10 um droplets gives 0.03-0.08 /m).
RANGES = {
    "coverage": (0.4, 0.0, 1.0),
    "base": (1500.0, 0.0, 15000.0),          # metres above the ground; the top stays below 20 km
    "thickness": (600.0, 10.0, 5000.0),
    "density": (20.0 / 600.0, 0.0, 1.0),     # extinction, 1/m
    "scale": (2000.0, 50.0, 100000.0),       # metres, the size of cloud features
}
TOP_LIMIT = 20000.0
# How far a sky pixel's light-shaft march may run to the cloud (clouds/shafts.py): beyond ~30 km
# the haze in front of the shafts (a 30 km path at sea level has Mie + Rayleigh optical depth
# ~0.6-0.8) hides them, and 32 steps over the path would be longer than a cloud feature (8 x 2 km
# tiles).
SHAFT_RANGE = 30_000.0


@dataclass(frozen=True)
class CloudLayer:
    coverage: float = RANGES["coverage"][0]
    base: float = RANGES["base"][0]
    thickness: float = RANGES["thickness"][0]
    density: float = RANGES["density"][0]
    scale: float = RANGES["scale"][0]
    offset: tuple = (0.0, 0.0)
    seed: int = 0

    def clamped(self) -> "CloudLayer":
        values = {}
        for name, (default, low, high) in RANGES.items():
            value = float(getattr(self, name))
            values[name] = default if math.isnan(value) else min(max(value, low), high)
        values["thickness"] = min(values["thickness"], TOP_LIMIT - values["base"])
        offset = tuple(0.0 if not math.isfinite(float(o)) else float(o) for o in self.offset)
        return replace(self, offset=offset, seed=int(self.seed), **values)

    @classmethod
    def enabled_in(cls, settings) -> "CloudLayer | None":
        """``of(settings)`` while its Clouds switch is on, else None."""
        return cls.of(settings) if getattr(settings, "clouds_enabled", False) else None

    @classmethod
    def of(cls, settings) -> "CloudLayer":
        """The clamped layer of anything holding the panel's names (scene.ols, PassSettings)."""
        return cls(coverage=settings.cloud_coverage, base=settings.cloud_base, thickness=settings.cloud_thickness,
                   density=settings.cloud_density, scale=settings.cloud_scale,
                   offset=tuple(settings.cloud_offset)[:2], seed=int(settings.cloud_seed)).clamped()

    @property
    def middle(self) -> float:
        return self.base + 0.5 * self.thickness


def middle_hit(layer: CloudLayer, camera_height, direction, earth_radius):
    """(distance along the ray to the layer's middle sphere, hit flag) for rays from
    ``camera_height`` above the ground at the origin with unit ``direction`` (..., 3), in the
    cancellation-free form the node group uses in float32. From below the middle every ray above
    the horizon meets it; from above only the rays that go down to it."""
    direction = np.asarray(direction, dtype=np.float64)
    radius = earth_radius + camera_height
    b = radius * direction[..., 2]
    middle = layer.middle
    # (R + h_m)^2 - (R + h_c)^2, factored
    q = (middle - camera_height) * (2.0 * earth_radius + camera_height + middle)
    disc = b * b + q
    root = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        upward = q / np.maximum(b + root, 1e-9)                 # camera below the middle
        downward = -q / np.maximum(root - b, 1e-9)              # camera above it, going down
    below = q > 0
    distance = np.where(below, upward, downward)
    hit = np.where(below, True, (disc >= 0) & (direction[..., 2] < 0))
    return np.where(hit, distance, 0.0), hit
