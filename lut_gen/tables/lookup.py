"""Look-ups into baked tables: the numpy twin of the add-on's node groups.

A ``Luts`` holds the tables of one bake. Every look-up broadcasts its arguments and returns
(..., 3) RGB per unit extraterrestrial sun.

Storage convention of the 4D tables: radiance *divided by the Rayleigh phase function* of the
node's sun-view angle, with single Mie scattering kept apart in its own table *without* its
phase function (Bruneton 2017's idea). A look-up interpolates both and returns
stored * P_R(nu) + mie * P_M(nu, g): the Mie phase, which rises 100-fold within a few degrees
of the sun, is applied exactly per query instead of being interpolated across the 16 sun-view
nodes (that gave a square, banded aureole 35% too dark). Dividing by the Rayleigh phase keeps
the (1 + cos^2) curvature across the sparse mid-angle cells of Yusov 2013 eq. (7) out of the
interpolation (~2% median error otherwise). Yusov 2013 eq. (8) is unaffected: both of its look-ups
share the sun-view angle. The "single" and "multiple" tables have the Mie part, "higher" has none.
Rays that hit the ground are also divided by parameterization.look_up_scale, a function of
their length (see geometry.ground_ray_scale), and multiplied by it at look-up.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Tuple

import numpy as np

from . import parameterization as par
from ..model.atmosphere import AtmosphereParams, mie_phase, rayleigh_phase
from . import ground
from .interpolation import interpolate, interpolate_packed, packed_rows, packed_side_by_side
from .optical_depth import table_net_density

# The 4D tables are blended geometrically along height and sun zenith (lut_gen.tables.interpolation):
# at twilight and near the ground the radiance changes by a factor per node there, not by a
# step, and linear blending overshot it (single table vs the spectral reference over 5000 rays:
# p99 6.6% -> 4.3%, median 0.42% -> 0.27%; the same with 64 sun nodes linear gave p99 5.3%).
# Where the sky changes slowly both blends agree.
GEOMETRIC_AXES = (0, 2)

TABLES = ("single", "higher", "multiple")
SKY_IRRADIANCE_ZENITHS = 24     # quadrature of sky_irradiance (the ambient table's bake)
SKY_IRRADIANCE_AZIMUTHS = 32
TABLES_WITH_MIE = ("single", "multiple")
STORED_TABLES = TABLES + ("single_mie", "single_fog")      # what phase_free look-ups may read
def with_phases(params: AtmosphereParams, stored: np.ndarray, mie: Optional[np.ndarray], cos_sun_view,
                fog: Optional[np.ndarray] = None) -> np.ndarray:
    """(..., 3) float32 stored * P_R + mie * P_M + fog * P_F from the interpolated "stored" table
    (divided by the Rayleigh phase) and single Mie and fog tables (no phase; None for tables
    without a Mie part and without fog)."""
    radiance = stored * rayleigh_phase(cos_sun_view)[..., None].astype(np.float32)
    if mie is not None:
        radiance += mie * mie_phase(cos_sun_view, params.mie_g)[..., None].astype(np.float32)
    if fog is not None:
        radiance += fog * mie_phase(cos_sun_view, params.fog_g)[..., None].astype(np.float32)
    return radiance


@dataclass
class Luts:
    """Tables of one bake.

    single, higher, multiple: (n_h, n_alpha, n_phi, n_theta, 3) scattering tables / P_R
    single_mie: the same shape, single Mie scattering without its phase function
    single_fog: the same for the fog (None without fog)
    optical_depth: (n_height, n_cos, 4) net Rayleigh / Mie / ozone / fog density to the top (m;
        the fog's divided by optical_depth.fog_column_scale)
    ambient: (n_cos, 3) ambient skylight irradiance on a horizontal plane at 20 m
    """

    params: AtmosphereParams
    single: np.ndarray
    higher: np.ndarray
    optical_depth: np.ndarray
    ambient: np.ndarray
    orders: object = 4          # as asked: a count or scattering_orders.CONVERGED
    orders_used: Optional[int] = None    # integrated (None: ``orders``)
    # the orders after ``orders`` added as a geometric series (scattering_orders.geometric_tail)
    tail: bool = True
    multiple: Optional[np.ndarray] = None
    timings: dict = field(default_factory=dict)
    single_mie: Optional[np.ndarray] = None
    single_fog: Optional[np.ndarray] = None
    # Packed copies of the 4D tables for look-ups (interpolation.packed_rows), kept once
    # keep_packed() is called: a caller that looks up every frame (the add-on's epipolar
    # tables) saves the copy each look-up makes (0.5 s a frame for the default tables), for
    # a third more memory per table used.
    _packed: Optional[dict] = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        if self.multiple is None:
            self.multiple = (self.single + self.higher).astype(np.float32)
        if self.single_mie is None:
            self.single_mie = np.zeros_like(self.single)
        if self.orders_used is None:
            self.orders_used = self.orders
        if self.optical_depth.shape[-1] == 3:     # a table without the fog's column
            self.optical_depth = np.concatenate([self.optical_depth, np.zeros_like(self.optical_depth[..., :1])], axis=-1)

    def value_problem(self) -> Optional[str]:
        """What makes the tables unusable (a non-finite or negative value), None when they are
        fine. Checked after a bake and on every load: NaN in a table turns a whole render NaN.
        The optical-depth table holds EARTH_HIT_NET_DENSITY where rays hit the Earth."""
        for name in ("single", "single_mie", "single_fog", "higher", "multiple", "optical_depth", "ambient"):
            table = getattr(self, name)
            if table is None:
                continue
            if not np.all(np.isfinite(table)):
                return f"the {name} table holds non-finite values"
            if np.any(table < 0):
                return f"the {name} table holds negative values"
        return None

    @property
    def dims(self) -> Tuple[int, int, int, int]:
        return tuple(int(n) for n in self.single.shape[:4])

    def keep_packed(self) -> "Luts":
        if self._packed is None:
            self._packed = {}
        return self

    def _packed_table(self, name: str):
        if self._packed is None:
            return None
        if name not in self._packed:
            self._packed[name] = packed_rows(getattr(self, name))
        return self._packed[name]

    def _packed_side_by_side(self, names: tuple):
        """The tables ``names`` packed side by side (kept like _packed_table's)."""
        if self._packed is None:
            return packed_side_by_side([self.table(name) for name in names])
        if names not in self._packed:
            self._packed[names] = packed_side_by_side([self.table(name) for name in names])
        return self._packed[names]

    def table(self, name: str) -> np.ndarray:
        if name not in STORED_TABLES:
            raise ValueError(f"table must be one of {', '.join(STORED_TABLES)}, got {name!r}")
        if name == "single_fog" and self.single_fog is None:
            return np.zeros_like(self.single)
        return getattr(self, name)

    # -- 4D scattering ---------------------------------------------------------
    def sky_radiance(self, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view,
                     table: str = "multiple", above_horizon=None, phase_free: bool = False) -> np.ndarray:
        """In-scattered radiance toward a viewer at ``height_m`` looking along the given
        direction, per unit sun, phase functions included. ``above_horizon`` forces the side of
        the horizon seam (pass the flag of an earlier look-up on the same ray). ``phase_free``:
        the stored table alone (``table`` may then be "single_mie", or a tuple of names: then a
        tuple of radiances, found with one set of coordinates and corners), no phase function
        and no Mie part added."""
        several = isinstance(table, tuple)
        if (several or table not in TABLES) and not phase_free:
            raise ValueError(f"the {table!r} table has no phase function of its own: look it up phase_free")
        cos_sun_view = par.clamp_sun_view(cos_view_zenith, cos_sun_zenith, cos_sun_view)
        xh, xa, xs, xt, above = par.world_to_x(self.params, self.dims, height_m, cos_view_zenith,
                                               cos_sun_zenith, cos_sun_view, above_horizon)
        coords = (xh, xa, xs, xt)
        if several:
            scale = par.look_up_scale(self.params, height_m, cos_view_zenith, above)[..., None].astype(np.float32)
            tables = [self.table(name) for name in table]
            channels = [t.shape[-1] for t in tables]
            together = interpolate_packed(self.dims, [self._packed_side_by_side(table)], [sum(channels)], coords,
                                          geometric_axes=GEOMETRIC_AXES)[0]
            bounds = np.cumsum([0] + channels)
            return tuple(together[..., a:b] * scale for a, b in zip(bounds[:-1], bounds[1:]))
        radiance = interpolate(self.table(table), coords, geometric_axes=GEOMETRIC_AXES,
                               packed=self._packed_table(table))
        if not phase_free:
            mie = fog = None
            if table in TABLES_WITH_MIE:
                mie = interpolate(self.single_mie, coords, geometric_axes=GEOMETRIC_AXES,
                                  packed=self._packed_table("single_mie"))
                if self.single_fog is not None:
                    fog = interpolate(self.single_fog, coords, geometric_axes=GEOMETRIC_AXES,
                                      packed=self._packed_table("single_fog"))
            radiance = with_phases(self.params, radiance, mie, cos_sun_view, fog)
        scale = par.look_up_scale(self.params, height_m, cos_view_zenith, above)
        return radiance * scale[..., None].astype(np.float32)

    # -- optical depth and transmittance -------------------------------------
    def net_density_to_top(self, height_m, cos_zenith) -> np.ndarray:
        return table_net_density(self.params, self.optical_depth, height_m, cos_zenith,
                                 self._packed_table("optical_depth"))

    def transmittance_to_top(self, height_m, cos_zenith) -> np.ndarray:
        """Sun/sky transmittance from a point to the top of the atmosphere; 0 where the ray
        hits the Earth."""
        net = self.net_density_to_top(height_m, cos_zenith).astype(np.float64)
        trans = np.exp(-net @ self.params.extinction_matrix())
        hits = np.asarray(cos_zenith) < par.cos_horizon(height_m, self.params.earth_radius)
        return np.where(hits[..., None], 0.0, trans)

    # -- the ground ------------------------------------------------------------
    def ground_radiance(self, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view) -> np.ndarray:
        """(..., 3) light the Lambertian ground reflects toward the viewer, attenuated on the way,
        per unit sun; 0 for rays that miss the ground (lut_gen.tables.ground)."""
        params = self.params
        height_m = np.clip(np.asarray(height_m, dtype=np.float64), 0.0, params.atmosphere_height)
        cos_sun_view = par.clamp_sun_view(cos_view_zenith, cos_sun_zenith, cos_sun_view)
        _, cos_sun_at, cos_back = ground.ground_point(params, height_m, cos_view_zenith, cos_sun_zenith, cos_sun_view)
        extinction = params.extinction_matrix()
        packed = self._packed_table("optical_depth")
        net = ground.net_density_to_ground(params, self.optical_depth, height_m, cos_view_zenith, cos_back, packed)
        view = np.exp(-np.minimum(net @ extinction, 80.0))
        lit = (ground.direct_irradiance(params, self.optical_depth, extinction, cos_sun_at, packed)
               + self.ambient_skylight(cos_sun_at))
        hits = ground.hits_ground(params, height_m, cos_view_zenith)
        return np.where(hits[..., None], view * lit * (params.ground_albedo / np.pi), 0.0).astype(np.float32)

    # -- ambient skylight ------------------------------------------------------
    def sky_irradiance(self, height_m: float, cos_sun_zenith, zeniths: int = SKY_IRRADIANCE_ZENITHS,
                       azimuths: int = SKY_IRRADIANCE_AZIMUTHS) -> np.ndarray:
        """(n, 3) E_sky(h, c_s): the 4D table's radiance over the upper hemisphere at
        ``height_m``, times (w . N), per unit sun, for each of the (n,) sun zenith cosines
        (Yusov 2013 eq. 3; the ambient table is this at AMBIENT_HEIGHT_M). Gauss-Legendre in the
        zenith cosine, midpoints over half a circle of azimuth (the sky is symmetric about the
        sun's plane)."""
        mu, mu_w = np.polynomial.legendre.leggauss(zeniths)
        mu, mu_w = 0.5 * (mu + 1), 0.5 * mu_w
        az = (np.arange(azimuths) + 0.5) * np.pi / azimuths
        az_w = 2 * np.pi / azimuths                     # half circle, counted twice
        cos_sun = np.atleast_1d(np.asarray(cos_sun_zenith, dtype=np.float64))
        sin_sun = np.sqrt(np.maximum(1 - cos_sun ** 2, 0.0))
        ca = mu[None, :, None]
        ct = ca * cos_sun[:, None, None] + np.sqrt(1 - ca ** 2) * sin_sun[:, None, None] * np.cos(az)
        radiance = self.sky_radiance(height_m, ca, cos_sun[:, None, None], ct)              # (n, mu, az, 3)
        return np.einsum("nmac,m->nc", radiance, mu * mu_w * az_w)

    def ambient_skylight(self, cos_sun_zenith) -> np.ndarray:
        """Irradiance on a horizontal plane from the whole sky (Yusov 2013 eq. 3), per unit sun."""
        x = par.unit_to_centre_x(np.asarray(cos_sun_zenith) * 0.5 + 0.5, self.ambient.shape[0])
        return interpolate(self.ambient, (x,))
