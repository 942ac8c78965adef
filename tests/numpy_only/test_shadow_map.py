"""lut_gen.passes.shadow_map: the numpy shadow-map render against brute-force ray casting, cascade
splits and footprints, and the visibility test the light-shaft march uses."""
import numpy as np
import pytest

from lut_gen.passes import shadow_map as sm, shadow_raster


def heightfield_triangles(n=10, size=100.0, seed=1):
    rng = np.random.default_rng(seed)
    xs = np.linspace(-size / 2, size / 2, n + 1)
    z = rng.uniform(0.0, 15.0, (n + 1, n + 1))
    tris = []
    for i in range(n):
        for j in range(n):
            a, b = (xs[j], xs[i], z[i, j]), (xs[j + 1], xs[i], z[i, j + 1])
            c, d = (xs[j], xs[i + 1], z[i + 1, j]), (xs[j + 1], xs[i + 1], z[i + 1, j + 1])
            tris += [(a, b, d), (a, d, c)]
    return np.array(tris)


def brute_force_max_depth(triangles_light, center, half, res):
    """Per texel centre: intersect the light-space line (x, y) with every triangle."""
    texel = 2 * np.asarray(half) / res
    x = center[0] - half[0] + (np.arange(res) + 0.5) * texel[0]
    y = center[1] - half[1] + (np.arange(res) + 0.5) * texel[1]
    out = np.full((res, res), shadow_raster.EMPTY_DEPTH)
    for tri in triangles_light:
        (x0, y0, d0), (x1, y1, d1), (x2, y2, d2) = tri
        det = (y1 - y2) * (x0 - x2) + (x2 - x1) * (y0 - y2)
        if abs(det) < 1e-12:
            continue
        X, Y = np.meshgrid(x, y)
        l0 = ((y1 - y2) * (X - x2) + (x2 - x1) * (Y - y2)) / det
        l1 = ((y2 - y0) * (X - x2) + (x0 - x2) * (Y - y2)) / det
        l2 = 1 - l0 - l1
        inside = (l0 >= 0) & (l1 >= 0) & (l2 >= 0)
        out = np.where(inside, np.maximum(out, l0 * d0 + l1 * d1 + l2 * d2), out)
    return out


def test_rasterizer_matches_brute_force_ray_casting():
    sun = np.array([0.5, -0.3, 0.6])
    frame = sm.light_frame(sun)
    tris = heightfield_triangles() @ frame.T
    center, half = np.array([3.0, -2.0]), np.array([45.0, 40.0])
    fast = shadow_raster.rasterize_max_depth(tris, center, half, 64)
    slow = brute_force_max_depth(tris, center, half, 64)
    covered = slow > shadow_raster.EMPTY_DEPTH
    assert covered.mean() > 0.5 and (~covered).any()       # the terrain fills part of the map
    close = np.isclose(fast, slow, atol=1e-3 * 15)
    assert close.mean() > 0.995, f"{(~close).sum()} texels differ"


def test_rasterizer_handles_big_and_tiny_triangles_and_empty_input():
    big = np.array([[(-1e4, -1e4, 5.0), (1e4, -1e4, 5.0), (0.0, 1e4, 5.0)]])
    depth = shadow_raster.rasterize_max_depth(big, (0.0, 0.0), (10.0, 10.0), 32)
    assert np.all(depth == 5.0)
    tiny = np.array([[(0.01, 0.01, 1.0), (0.02, 0.01, 1.0), (0.01, 0.02, 1.0)]])
    assert np.all(shadow_raster.rasterize_max_depth(tiny, (0.0, 0.0), (10.0, 10.0), 32) == shadow_raster.EMPTY_DEPTH)
    assert np.all(shadow_raster.rasterize_max_depth(np.zeros((0, 3, 3)), (0, 0), (1, 1), 8)
                  == shadow_raster.EMPTY_DEPTH)
    with pytest.raises(ValueError, match="at least 1"):
        shadow_raster.rasterize_max_depth(big, (0, 0), (1, 1), 0)


def test_cascade_splits_blend_uniform_and_logarithmic():
    uniform = sm.cascade_splits(1.0, 1000.0, 4, 0.0)
    log = sm.cascade_splits(1.0, 1000.0, 4, 1.0)
    assert np.allclose(uniform, [1, 250.75, 500.5, 750.25, 1000])
    assert np.allclose(log, [1, 10 ** 0.75, 10 ** 1.5, 10 ** 2.25, 1000])
    mixed = sm.cascade_splits(1.0, 1000.0, 4, 0.95)
    assert np.all(np.diff(mixed) > 0) and mixed[0] == 1 and mixed[-1] == 1000
    for bad in ((0.0, 10.0, 2), (5.0, 1.0, 2), (1.0, 10.0, 0)):
        with pytest.raises(ValueError):
            sm.cascade_splits(*bad, 0.5)


def camera_looking_along_y():

    rotation = np.column_stack([[1, 0, 0], [0, 0, 1], [0, -1, 0]]).astype(float)
    return sm.Camera(np.array([0.0, -40.0, 5.0]), rotation, (0.6, 0.35))


def test_cascades_are_nested_and_cover_their_frustum_slice():
    camera = camera_looking_along_y()
    assert np.allclose(camera.forward, [0, 1, 0])
    frame = sm.light_frame([0.3, 0.8, 0.4])
    splits = sm.cascade_splits(1.0, 200.0, 4, 0.9)
    centers, halves = sm.cascade_footprints(camera, frame, splits, 128)
    rng = np.random.default_rng(0)
    for i in range(4):
        if i:
            assert np.all(np.abs(centers[i - 1] - centers[i]) + halves[i - 1] <= halves[i] + 1e-9)
        depth = rng.uniform(0, splits[i + 1], 500)
        local = np.stack([rng.uniform(-0.6, 0.6, 500) * depth, rng.uniform(-0.35, 0.35, 500) * depth, -depth], -1)
        points = local @ camera.rotation.T + camera.position
        xy = points @ frame[:2].T
        assert np.all(np.abs(xy - centers[i]) <= halves[i] + 1e-9)


def occluder_scene(sun):
    """Ground plane at z = 0 and a 20 m square roof at z = 30 over the origin."""
    ground = np.array([[(-500, -500, 0), (500, -500, 0), (500, 500, 0)], [(-500, -500, 0), (500, 500, 0), (-500, 500, 0)]], float)
    roof = np.array([[(-10, -10, 30), (10, -10, 30), (10, 10, 30)], [(-10, -10, 30), (10, 10, 30), (-10, 10, 30)]], float)
    return np.vstack([ground, roof])


@pytest.mark.parametrize("best_search", [True, False])
def test_visibility_under_an_occluder(best_search):
    sun = np.array([0.0, 0.0, 1.0])
    camera = camera_looking_along_y()
    cascades = sm.render_cascades(occluder_scene(sun), camera, sun, 256, 3, 0.5, 1.0, 300.0)
    points = np.array([(0.0, 0.0, 1.0), (0.0, 0.0, 40.0), (50.0, 20.0, 1.0), (9.0, 0.0, 10.0), (11.5, 0.0, 10.0)])
    lit = sm.visibility(cascades, points, camera, best_search=best_search)
    assert lit.tolist() == [0.0, 1.0, 1.0, 0.0, 1.0]
    # Far outside every cascade nothing is tested.
    assert sm.visibility(cascades, np.array([(0.0, 5000.0, 1.0)]), camera)[0] == 1.0
    # PCF: a fraction at the roof's edge, never outside [0, 1].
    edge = np.stack([np.linspace(8, 12, 200), np.zeros(200), np.full(200, 5.0)], -1)
    soft = sm.visibility(cascades, edge, camera, smooth=True, best_search=best_search)
    assert np.all((soft >= 0) & (soft <= 1)) and np.any((soft > 0) & (soft < 1))


def test_first_cascade_skips_the_nearest_cascades():
    sun = np.array([0.0, 0.0, 1.0])
    camera = sm.Camera(np.array([0.0, -5.0, 5.0]), camera_looking_along_y().rotation, (0.6, 0.35))
    cascades = sm.render_cascades(occluder_scene(sun), camera, sun, 128, 4, 1.0, 1.0, 1000.0)
    edge = np.array([[9.9, 0.0, 1.0], [10.3, 0.0, 1.0]])     # just inside, just outside the roof's shadow
    texel = cascades.texel_sizes()[:, 0]
    assert texel[0] < 0.1 < texel[3]
    assert sm.visibility(cascades, edge, camera, first_cascade=0).tolist() == [0.0, 1.0]
    # Skipped cascades are tested in the first marched one: coarse texels blur the edge.
    coarse = sm.visibility(cascades, edge, camera, first_cascade=3)
    assert coarse.tolist() != [0.0, 1.0]


def test_render_cascades_rejects_bad_input():
    camera = camera_looking_along_y()
    tris = occluder_scene(None)
    with pytest.raises(ValueError, match="at least 16"):
        sm.render_cascades(tris, camera, (0, 0, 1), 0, 2, 0.5, 1.0, 100.0)
    with pytest.raises(ValueError, match="non-zero"):
        sm.render_cascades(tris, camera, (0, 0, 0), 64, 2, 0.5, 1.0, 100.0)
    with pytest.raises(ValueError, match="near < far"):
        sm.render_cascades(tris, camera, (0, 0, 1), 64, 2, 0.5, 100.0, 100.0)


def test_pack_atlas_into_last_frames_buffer_equals_a_fresh_pack():
    """The add-on packs each frame into the previous frame's atlas: nothing of that frame may
    survive (here 4 cascades: block 1 holds one, its G and B channels stay empty)."""
    rng = np.random.default_rng(3)

    def cascades(count, res=8):
        depths = rng.uniform(-50.0, 50.0, (count, res, res)).astype(np.float32)
        return sm.ShadowCascades(np.eye(3), np.zeros((count, 2)), np.ones((count, 2)), np.ones(count), depths)

    first, second = cascades(6), cascades(4)
    buffer = sm.pack_atlas(first)
    reused = sm.pack_atlas(second, out=buffer)
    assert reused is buffer
    fresh = sm.pack_atlas(second)
    np.testing.assert_array_equal(reused, fresh)
    assert np.all(fresh[:, 8:, 1:3] == shadow_raster.EMPTY_DEPTH) and np.all(fresh[..., 3] == 1.0)
    np.testing.assert_array_equal(fresh[:, 8:, 0], second.depths[3])
    np.testing.assert_array_equal(fresh[:, :8, 2], second.depths[2])
    assert sm.pack_atlas(cascades(4, res=16), out=buffer) is not buffer     # another size: a new array


def test_cascades_rasterised_on_threads_equal_the_serial_ones():
    """render_cascades(threads=N): each cascade written by one thread, the maps bit for bit
    those of one thread (the frame update rasterises on every core)."""
    sun = np.array([0.3, -0.5, 0.4])
    camera = sm.Camera(np.array([0.0, -60.0, 12.0]), np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]]),
                       (0.6, 0.35), 500.0)
    tris = heightfield_triangles(n=40, size=200.0, seed=4)
    serial = sm.render_cascades(tris, camera, sun, 128, 4, 0.7, 1.0, 300.0)
    threaded = sm.render_cascades(tris, camera, sun, 128, 4, 0.7, 1.0, 300.0, threads=3)
    assert (serial.depths > shadow_raster.EMPTY_DEPTH).mean() > 0.3
    np.testing.assert_array_equal(threaded.depths, serial.depths)


def test_min_max_maps_filled_while_rasterising_equal_those_built_after():
    """render_cascades(on_cascade=min_max.fill_cascade): each cascade's min/max maps built on
    its rasterising thread equal min_max.build over the finished cascades, smooth or not, and
    the maps decide points (some lit, some shadowed) rather than being empty."""
    from lut_gen.passes import min_max
    sun = np.array([0.3, -0.5, 0.4])
    camera = sm.Camera(np.array([0.0, -60.0, 12.0]), np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]]),
                       (0.6, 0.35), 500.0)
    tris = heightfield_triangles(n=40, size=200.0, seed=5)
    for smooth in (True, False):
        maps = min_max.allocate(4, 100, smooth)        # 100 texels: not a multiple of the block
        cascades = sm.render_cascades(tris, camera, sun, 100, 4, 0.7, 1.0, 300.0, threads=2,
                                      on_cascade=lambda i, depths: min_max.fill_cascade(maps, i, depths))
        built = min_max.build(cascades, smooth)
        np.testing.assert_array_equal(maps.high, built.high)
        np.testing.assert_array_equal(maps.low, built.low)
        assert np.all(maps.high >= maps.low) and np.ptp(maps.high) > 1.0
