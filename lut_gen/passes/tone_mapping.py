"""The sample's tone mapping (ToneMapping.fxh of the Outdoor Light Scattering sample), in numpy:
the twin of the "OLS Tone Mapping" compositor group.

All operators scale the colour so that the average luminance maps to middle gray. Exp,
Reinhard, Reinhard mod, Logarithmic and Adaptive log map the luminance and restore the colour as
L_mapped * (C / L)^saturation; Uncharted 2 and Filmic ALU map each channel.
"""
from __future__ import annotations

import math

import numpy as np

# The sample's seven operators, then ours: BLENDER_VIEW applies only the exposure (auto exposure's
# middle gray / average, else none) and leaves the curve to the scene's view transform.
OPERATORS = ("EXP", "REINHARD", "REINHARD_MOD", "UNCHARTED2", "FILMIC_ALU", "LOGARITHMIC", "ADAPTIVE_LOG",
             "BLENDER_VIEW")
VIEW_TRANSFORM_OPERATORS = ("BLENDER_VIEW",)   # the scene's view transform stays on
RGB_TO_LUMINANCE = np.array([0.212671, 0.715160, 0.072169])
FIXED_AVERAGE_LUMINANCE = 0.1      # the sample's average luminance when auto exposure is off
MIN_LUMINANCE = 1e-10
UNCHARTED2_EXPOSURE_BIAS = 2.0
ADAPTIVE_LOG_BIAS = 0.85
ADAPTATION_RATE = 1.0              # 1/s, the sample's light adaptation rate


def uncharted2_curve(x):
    a, b, c, d, e, f = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30
    return (x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f) - e / f


def log_average_luminance(rgb) -> float:
    """exp(mean(log L)) over the image: the auto-exposure average."""
    lum = np.maximum(np.asarray(rgb)[..., :3] @ RGB_TO_LUMINANCE, MIN_LUMINANCE)
    return float(np.exp(np.mean(np.log(lum))))


def adaptation_weight(elapsed_s: float, rate: float = ADAPTATION_RATE) -> float:
    """How far the eye adapts toward the new luminance in ``elapsed_s``: 1 - exp(-rate dt)."""
    return 1.0 - math.exp(-rate * elapsed_s)


def adapt(previous: float, current: float, weight: float) -> float:
    """previous + (current - previous) weight: the luminance the operators use (weight 1: current)."""
    return previous + (current - previous) * weight


def adapted_luminance(previous: float, current: float, elapsed_s: float, rate: float = ADAPTATION_RATE) -> float:
    """Light adaptation between frames: old + (new - old)(1 - exp(-rate dt))."""
    return adapt(previous, current, adaptation_weight(elapsed_s, rate))


def tone_map(rgb, operator="UNCHARTED2", middle_gray=0.18, white_point=3.0, luminance_saturation=1.0,
             average_luminance=None, previous_luminance=None, adaptation_weight=1.0):
    """Linear display colour (before the sRGB transfer) of linear HDR ``rgb`` (..., 3).

    ``average_luminance``: the measured one (auto exposure's log average), else the sample's fixed
    0.1. Light adaptation: with ``previous_luminance`` (the previous frame's adapted luminance) the
    operators use ``adapt(previous, measured, adaptation_weight)`` instead."""
    if operator not in OPERATORS:
        raise ValueError(f"operator must be one of {', '.join(OPERATORS)}, got {operator!r}")
    colour = np.maximum(np.asarray(rgb, dtype=np.float64)[..., :3], 0.0)
    average = FIXED_AVERAGE_LUMINANCE if average_luminance is None else average_luminance
    if previous_luminance is not None:
        average = adapt(previous_luminance, average, adaptation_weight)
    scale = middle_gray / average
    lum = np.maximum(colour @ RGB_TO_LUMINANCE, MIN_LUMINANCE)[..., None]
    scaled_lum = lum * scale
    scaled = colour * scale
    chroma = np.power(colour / lum, luminance_saturation)
    if operator == "BLENDER_VIEW":
        return scaled if average_luminance is not None else colour
    if operator == "EXP":
        return (1.0 - np.exp(-scaled_lum)) * chroma
    if operator == "REINHARD":
        return scaled_lum / (1.0 + scaled_lum) * chroma
    if operator == "REINHARD_MOD":
        return scaled_lum * (1.0 + scaled_lum / (white_point * white_point)) / (1.0 + scaled_lum) * chroma
    if operator == "UNCHARTED2":
        return uncharted2_curve(UNCHARTED2_EXPOSURE_BIAS * scaled) / uncharted2_curve(white_point)
    if operator == "FILMIC_ALU":
        x = np.maximum(scaled - 0.004, 0.0)
        return np.power(x * (6.2 * x + 0.5) / (x * (6.2 * x + 1.7) + 0.06), 2.2)
    if operator == "LOGARITHMIC":
        return np.log10(1.0 + scaled_lum) / np.log10(1.0 + white_point) * chroma
    # ADAPTIVE_LOG (Drago et al.)
    exponent = math.log(ADAPTIVE_LOG_BIAS) / math.log(0.5)
    mapped = (1.0 / np.log10(1.0 + white_point) * np.log(1.0 + scaled_lum)
              / np.log(2.0 + 8.0 * np.power(scaled_lum / white_point, exponent)))
    return mapped * chroma


def srgb_encode(linear):
    c = np.clip(linear, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
