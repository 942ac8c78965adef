"""lut_gen.tables.interpolation: tables looked up side by side in one packed table give, bit for
bit, what each table's own look-up gives (the epipolar in-scattering tables read three so)."""
import numpy as np

from lut_gen.tables import interpolation


def test_tables_side_by_side_equal_their_own_look_ups():
    rng = np.random.default_rng(7)
    axes = (6, 12, 9, 5)
    # Values over twelve decades: the geometric axis's floors act on each channel alone.
    tables = [(rng.random(axes + (3,)) * 10.0 ** rng.uniform(-12, 0, axes + (3,))).astype(np.float32)
              for _ in range(3)]
    coords = [rng.uniform(-1.0, n, 4000) for n in axes]
    own = interpolation.interpolate_many(tables, coords, geometric_axes=(2,))
    together, = interpolation.interpolate_packed(axes, [interpolation.packed_side_by_side(tables)], [9], coords,
                                                 geometric_axes=(2,))
    assert np.all(np.isfinite(together)) and together.max() > 0.0
    for i, table in enumerate(own):
        np.testing.assert_array_equal(together[:, 3 * i:3 * i + 3], table)
    # A point on a node gives the node's value: the look-up is not trivially the same wrong thing.
    node, = interpolation.interpolate_packed(axes, [interpolation.packed_side_by_side(tables)], [9],
                                             [np.array([2.0]), np.array([5.0]), np.array([4.0]), np.array([1.0])])
    np.testing.assert_allclose(node[0, 3:6], tables[1][2, 5, 4, 1], rtol=1e-6)
