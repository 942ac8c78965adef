"""Print docs/analytic.md's table: the analytic model (lut_gen.model.analytic) against the
precomputed tables of the same media (default resolution, multiple scattering), which the
project tests against brute-force integration and Monte Carlo (docs/accuracy.md).

    python scripts/analytic_error_table.py [--resolution default|draft] [--picture docs/analytic_comparison.png]

Each row gives analytic / reference per channel (R G B) and for the luminance; the camera is
2 m up, the media the clear sky's."""
import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import lut_gen  # noqa: E402
from lut_gen.model import analytic  # noqa: E402
from lut_gen.passes import aerial  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
HEIGHT = 2.0


def direction(elevation_deg, azimuth_deg):
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])


def sky_rows(luts, media):
    cases = [("zenith", 60, (90, 0)), ("zenith", 20, (90, 0)), ("zenith", 5, (90, 0)),
             ("horizon, 90 deg from the sun", 60, (1, 90)), ("horizon, 90 deg from the sun", 20, (1, 90)),
             ("horizon, 90 deg from the sun", 5, (1, 90)), ("horizon, away from the sun", 20, (1, 180)),
             ("sun glow, 5 deg from the sun", 20, (25, 0)), ("sun glow, 5 deg from the sun", 60, (55, 0)),
             ("twilight zenith", -2, (90, 0)), ("twilight horizon toward the sun", -2, (1, 0))]
    for what, sun_el, (view_el, view_az) in cases:
        sun, view = direction(sun_el, 0), direction(view_el, view_az)
        reference = luts.sky_radiance(HEIGHT, view[2], sun[2], float(view @ sun))
        single = luts.sky_radiance(HEIGHT, view[2], sun[2], float(view @ sun), table="single")
        model = analytic.sky_parts(media, HEIGHT, view, sun)[0]
        yield f"{what}, sun {sun_el} deg", model, reference, single


def single_scattering_march(luts, start, end, sun, steps=4000):
    """Single scattering of the tables' own media (exponential profiles, ozone, the sun's extinction
    from the optical-depth table) along a segment, by the midpoint rule: the reference for the
    aerial rows' last column (Yusov 2013 eq. (8)'s difference of two look-ups along a horizontal ray
    carries the tables' horizon error, larger than the single-scattering part)."""
    params = luts.params
    length = float(np.linalg.norm(end - start))
    t = (np.arange(steps) + 0.5) / steps * length
    points = start + (end - start) / length * t[:, None]
    z = np.maximum(points[:, 2], 0.0)
    rayleigh_density, mie_density = np.exp(-z / params.rayleigh_scale_height), np.exp(-z / params.mie_scale_height)
    extinction = params.extinction_matrix()
    beta = rayleigh_density[:, None] * extinction[0] + mie_density[:, None] * extinction[1]
    depth = np.cumsum(beta, axis=0) * (length / steps) - beta * (length / steps) / 2
    cos_sun_view = float((end - start) @ sun / length)
    scattering = (rayleigh_density[:, None] * params.rayleigh * analytic.rayleigh_phase(cos_sun_view)
                  + mie_density[:, None] * params.mie * lut_gen.model.atmosphere.mie_phase(cos_sun_view, params.mie_g))
    sun_light = luts.transmittance_to_top(z, np.full_like(z, sun[2]))
    return (scattering * sun_light * np.exp(-depth)).sum(axis=0) * (length / steps)


def aerial_rows(luts, media):
    camera = np.array([0.0, 0.0, HEIGHT])
    for sun_el in (30, 5):
        sun = direction(sun_el, 0)
        for distance, az in ((1000.0, 90), (10_000.0, 90), (10_000.0, 0), (30_000.0, 90)):
            point = camera + direction(0, az) * distance
            point[2] = HEIGHT
            black = np.zeros(3)
            _, t_model, in_model = analytic.aerial_perspective(media, camera, point, black, sun)
            in_reference = aerial.aerial_perspective(luts, camera, point[None], black[None], sun)[0]
            in_single = single_scattering_march(luts, camera, point, sun)
            t_reference = aerial.segment_transmittance(luts, camera, point[None])[0]
            where = "toward" if az == 0 else "across"
            yield (f"aerial in-scattering, {distance / 1000:g} km {where} the sun, sun {sun_el} deg", in_model,
                   in_reference, in_single)
            if az == 90 and sun_el == 30:
                yield f"aerial transmittance, {distance / 1000:g} km", t_model, t_reference, None


PICTURE_SUNS = (60, 20, 5, -2)


def panel(radiance_of, width=360, height=100):
    """An equirectangular strip: azimuth from the sun -180..180 deg left to right, elevation 90
    down to -10 deg, 1 deg per pixel."""
    az = np.radians((np.arange(width) + 0.5) / width * 360.0 - 180.0)
    el = np.radians(90.0 - (np.arange(height) + 0.5) / height * 100.0)
    el, az = np.meshgrid(el, az, indexing="ij")
    view = np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)
    return radiance_of(view)


def picture(luts, media, path):
    """Rows: the suns of PICTURE_SUNS; left the tables, right the analytic model, both exposed
    for the tables' median luminance above the horizon (so the analytic model's darkness shows),
    Reinhard per channel, sRGB."""
    from lut_gen.store import png
    rows = []
    for sun_el in PICTURE_SUNS:
        sun = direction(sun_el, 0)

        def tables(view):
            sky = luts.sky_radiance(HEIGHT, view[..., 2], sun[2], view @ sun)
            return sky + luts.ground_radiance(HEIGHT, view[..., 2], sun[2], view @ sun)

        def model(view):
            return analytic.sky_radiance(media, HEIGHT, view, sun)

        left, right = panel(tables), panel(model)
        exposure = 0.18 / max(float(np.median(left[:90] @ LUMINANCE)), 1e-12)
        gap = np.ones((left.shape[0], 4, 3))
        row = np.concatenate([left * exposure, gap, right * exposure], axis=1)
        rows += [row / (1.0 + row), np.ones((4, row.shape[1], 3))]
    png.write_png(path, png.to_srgb8(np.concatenate(rows[:-1])), software="scripts/analytic_error_table.py")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", default="default", choices=("default", "draft"))
    parser.add_argument("--picture", help="also write the side-by-side PNG here")
    args = parser.parse_args()
    params = lut_gen.AtmosphereParams()
    with tempfile.TemporaryDirectory() as cache:
        luts, _, _ = lut_gen.cached_bake(params, resolution=args.resolution, directory=Path(cache) / "bake")
    media = analytic.media(params)
    if args.picture:
        picture(luts, media, args.picture)
    print("| case | analytic / tables (R, G, B) | luminance | analytic / single scattering of the same media (luminance) |")
    print("|---|---|---|---|")
    for rows in (sky_rows(luts, media), aerial_rows(luts, media)):
        for what, model, reference, single in rows:
            ratio = np.asarray(model) / np.maximum(np.asarray(reference), 1e-30)
            lum = float(np.asarray(model) @ LUMINANCE) / max(float(np.asarray(reference) @ LUMINANCE), 1e-30)
            alone = ("-" if single is None else
                     f"{float(np.asarray(model) @ LUMINANCE) / max(float(np.asarray(single).reshape(-1)[:3] @ LUMINANCE), 1e-30):.2f}")
            print(f"| {what} | {ratio[0]:.2f}, {ratio[1]:.2f}, {ratio[2]:.2f} | {lum:.2f} | {alone} |")


if __name__ == "__main__":
    main()
