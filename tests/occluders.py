"""Scenes built in numpy for the light-shaft tests: a ground plane with thin occluders (a row of
pillars, a fence of posts) against a low sun, a camera looking at them, and the two techniques
(epipolar sampling and brute force) run on the same shadow cascades, steps and modes. The
images are compared in display values through one fixed exposure curve."""
import numpy as np

from lut_gen.passes import scattering_pass, shadow_map
from lut_gen.verify.display import display_psnr
from lut_gen.passes.shadow_map import Camera

SUN_STRENGTH, SCALE = 10.0, 0.5


def box_triangles(lo, hi):
    """(12, 3, 3) triangles of an axis-aligned box."""
    x = np.array([[lo[0], lo[1], lo[2]], [hi[0], lo[1], lo[2]], [hi[0], hi[1], lo[2]], [lo[0], hi[1], lo[2]],
                  [lo[0], lo[1], hi[2]], [hi[0], lo[1], hi[2]], [hi[0], hi[1], hi[2]], [lo[0], hi[1], hi[2]]])
    faces = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return np.array([x[[a, b, c]] for a, b, c, d in faces] + [x[[a, c, d]] for a, b, c, d in faces])


def pillars(count=15, spacing=40.0, distance=300.0, height=120.0, width=16.0):
    """A row of square pillars across the view, ``distance`` metres ahead along +y."""
    return [(np.array([x - width / 2, distance - width / 2, 0.0]), np.array([x + width / 2, distance + width / 2, height]))
            for x in (np.arange(count) - count // 2) * spacing]


def fence(count=41, spacing=5.0, distance=60.0, height=15.0, width=2.0):
    return pillars(count, spacing, distance, height, width)


def ray_boxes(origin, directions, boxes):
    """Distance along each ray to the first box or the ground (z = 0), inf for the sky."""
    best = np.full(directions.shape[:-1], np.inf)
    down = directions[..., 2] < -1e-9
    best = np.where(down, -origin[2] / np.where(down, directions[..., 2], -1.0), best)
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1.0 / directions
        for lo, hi in boxes:
            t1, t2 = (lo - origin) * inverse, (hi - origin) * inverse
            near = np.nanmax(np.minimum(t1, t2), axis=-1)
            far = np.nanmin(np.maximum(t1, t2), axis=-1)
            hit = (far >= np.maximum(near, 0.0)) & (near > 0)
            best = np.where(hit & (near < best), near, best)
    return best


def look_at(position, target, fov_deg=60.0, aspect=16 / 9):
    forward = np.asarray(target, float) - position
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    tx = np.tan(np.radians(fov_deg) / 2)
    return Camera(np.asarray(position, float), np.stack([right, up, -forward], axis=1), (tx, tx / aspect), 1e5)


def sun_at(elevation, azimuth):
    """Unit vector toward the sun; azimuth 0 is +y (ahead of the default cameras)."""
    e, a = np.radians(elevation), np.radians(azimuth)
    return np.array([np.sin(a) * np.cos(e), np.cos(a) * np.cos(e), np.sin(e)])


class Scene:
    def __init__(self, boxes, camera, sun, width, height, cascades=4, resolution=512):
        self.camera, self.sun, self.width, self.height = camera, sun, width, height
        triangles = np.concatenate([box_triangles(lo, hi) for lo, hi in boxes]) if boxes else np.zeros((0, 3, 3))
        directions = camera.view_directions(width, height)
        distance = ray_boxes(camera.position, directions, boxes)
        geometry = np.isfinite(distance)
        far = float(min(np.max(np.where(geometry, distance, 0.0)) * 1.1 + 50.0, 5000.0))
        self.cascades = shadow_map.render_cascades(triangles, camera, sun, resolution, cascades, 0.8, 1.0, far)
        self.depth = np.where(geometry, distance * (directions @ camera.forward), 1e10)
        self.position = camera.position + directions * np.where(geometry, distance, 0.0)[..., None]
        self.image = np.where(geometry[..., None], 0.05, 2.0) * np.ones(3)       # sky: brighter than its air
        self.geometry = geometry

    def shafts(self, luts, **settings):
        chosen = scattering_pass.PassSettings(sun_strength=SUN_STRENGTH, scattering_scale=SCALE, **settings)
        return scattering_pass.scattering_pass(luts, self.image, self.position, self.depth, self.camera, self.sun,
                                               self.cascades, chosen)


def compare(scene, luts, **settings):
    brute = scene.shafts(luts, scattering_technique="BRUTE_FORCE", **settings)
    epi = scene.shafts(luts, scattering_technique="EPIPOLAR_SAMPLING", **settings)
    assert np.isfinite(epi).all() and epi.min() >= 0.0
    return display_psnr(epi, brute), brute, epi


CAMERA = look_at([0.0, 0.0, 2.0], [0.0, 100.0, 8.0])

