"""Earth's main magnetic field in ECI (tesla): the IGRF (:class:`IgrfModel`) and the tilted dipole of
its first-degree coefficients (:class:`DipoleModel`, the fast fallback). Both take ECI positions (m) and
times (days since J2000.0) and go through ECEF (:mod:`adcs_core.environment.frames`).

IGRF: the coefficients are the ``ppigrf`` library's (its IGRF-14 ``.shc`` file by default, read with its
``read_shc``; IGRF-14: IAGA V-MOD, 2024, doi:10.5281/zenodo.14012302; IGRF-13: Alken et al. 2021, Earth
Planets Space 73:49). The field is ``B = -grad V`` of the model's potential (Alken et al. 2021, eq. 1)::

    V = a sum_{n=1}^{13} (a/r)^{n+1} sum_{m=0}^{n} (g_n^m(t) cos m phi + h_n^m(t) sin m phi) P_n^m(cos theta)

    B_r     =  sum (n+1) (a/r)^{n+2} sum (g cos m phi + h sin m phi) P_n^m
    B_theta = -sum (a/r)^{n+2} sum (g cos m phi + h sin m phi) dP_n^m/dtheta
    B_phi   = -1/sin(theta) sum (a/r)^{n+2} sum m (-g sin m phi + h cos m phi) P_n^m

with ``a = 6371.2 km``, geocentric colatitude ``theta`` and longitude ``phi``, Schmidt semi-normalised
``P_n^m`` from the recursion of Wertz (ed.), Spacecraft Attitude Determination and Control (1978),
appendix H (the one ``ppigrf.get_legendre`` uses), and ``g, h`` interpolated linearly in time between
the 5-year models (the IGRF's definition; valid 1900-2030 for IGRF-14). The sums are written here
rather than called through ``ppigrf.igrf_gc`` because that function re-reads and re-interpolates the
coefficient file on every call and evaluates every date at every point: measured here, 32 ms for one
point, 81 ms for 1000 and 520 ms for 10 000 (0.5 s import, pandas); this evaluation agrees with it to
1e-9 relative (tests/test_environment_magnetic.py) and takes ~0.5-1 ms for one point. Near the poles the
colatitude is kept >= 1e-9 rad from them (7 mm at LEO) so that ``1/sin(theta)`` stays finite.

Dipole: the ``n = 1`` term alone, ``V = a^3 (g . r) / r^3`` with the dipole vector ``g = (g_1^1, h_1^1,
g_1^0)`` in ECEF axes, so ``B = (a/r)^3 (3 (g . r_hat) r_hat - g)`` (Wertz 1978, app. H, the dipole
model; Markley & Crassidis, Fundamentals of Spacecraft Attitude Determination and Control, 2014,
section 3.3.1), its coefficients frozen at one date (the scenario epoch).
"""
from __future__ import annotations

import math
from datetime import datetime
from functools import lru_cache

import numpy as np

from adcs_core.environment.frames import ecef_to_eci, eci_to_ecef

REFERENCE_RADIUS = 6371200.0   # m, the IGRF's geomagnetic reference radius a
NANOTESLA = 1e-9
POLE_GUARD = 1e-9              # rad: the colatitude is kept this far from the poles


def _ppigrf():
    """ppigrf's module, imported on first use: it brings pandas (0.5-1.3 s at import), which every
    node process paid at start although only an IGRF model reads its coefficients (issue #18)."""
    from ppigrf import ppigrf
    return ppigrf


def __getattr__(name: str):
    """``DEFAULT_COEFFICIENTS`` (ppigrf's IGRF-14 file) and ``IGRF13_COEFFICIENTS``, looked up in
    ppigrf on first use (PEP 562)."""
    if name == 'DEFAULT_COEFFICIENTS':
        return _ppigrf().shc_fn
    if name == 'IGRF13_COEFFICIENTS':
        return _ppigrf().shc_fn_igrf13
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


def _days(when: datetime) -> float:
    delta = when - datetime(2000, 1, 1, 12, 0, 0)
    return delta.days + (delta.seconds + delta.microseconds * 1e-6) / 86400.0


def schmidt_legendre(theta: np.ndarray, nmax: int) -> tuple[dict, dict]:
    """Schmidt semi-normalised ``P_n^m(cos theta)`` and ``dP_n^m/dtheta`` for ``n <= nmax`` (dicts keyed
    by ``(n, m)`` of arrays shaped like ``theta``), Wertz (1978) app. H recursion::

        P_0^0 = 1,  P_1^1 = sin,  P_n^n = sqrt((2n-1)/(2n)) sin P_{n-1}^{n-1}   (n >= 2)
        P_n^m = ((2n-1) cos P_{n-1}^m - sqrt((n-1)^2 - m^2) P_{n-2}^m) / sqrt(n^2 - m^2)   (n > m)

    and their theta-derivatives term by term."""
    s, c = np.sin(theta), np.cos(theta)
    P = {(0, 0): np.ones_like(theta)}
    dP = {(0, 0): np.zeros_like(theta)}
    for n in range(1, nmax + 1):
        k = 1.0 if n == 1 else math.sqrt((2 * n - 1) / (2 * n))
        P[n, n] = k * s * P[n - 1, n - 1]
        dP[n, n] = k * (c * P[n - 1, n - 1] + s * dP[n - 1, n - 1])
        for m in range(n):
            root = math.sqrt(n * n - m * m)
            prev2 = math.sqrt((n - 1) ** 2 - m * m)
            p2, dp2 = (P[n - 2, m], dP[n - 2, m]) if n - 2 >= m else (0.0, 0.0)
            P[n, m] = ((2 * n - 1) * c * P[n - 1, m] - prev2 * p2) / root
            dP[n, m] = ((2 * n - 1) * (c * dP[n - 1, m] - s * P[n - 1, m]) - prev2 * dp2) / root
    return P, dP


class IgrfModel:
    """The IGRF from a ``.shc`` coefficient file (ppigrf's; IGRF-14 by default), up to ``max_degree``."""

    def __init__(self, coefficient_file: str | None = None, max_degree: int = 13) -> None:
        coefficient_file = coefficient_file or _ppigrf().shc_fn
        g, h = _ppigrf().read_shc(coefficient_file)
        keys = [k for k in g.columns if k[0] <= max_degree]
        self.max_degree = max(k[0] for k in keys)
        self.n = np.array([k[0] for k in keys])
        self.m = np.array([k[1] for k in keys])
        self._keys = keys
        self.epochs = np.array([_days(d) for d in g.index.to_pydatetime()])   # days since J2000.0
        self.g = g[keys].to_numpy(dtype=float)          # (n_epochs, K), nT
        self.h = h[keys].to_numpy(dtype=float)
        self._dg = np.diff(self.g, axis=0)               # change over each interval between epochs
        self._dh = np.diff(self.h, axis=0)
        for table in (self.epochs, self.g, self.h, self._dg, self._dh):
            table.flags.writeable = False                # shared by load_igrf: never modified
        self.coefficient_file = coefficient_file

    def coefficients(self, d) -> tuple[np.ndarray, np.ndarray]:
        """(g, h) (..., K) in nT at ``d`` days since J2000.0, linear between the model epochs; ValueError
        outside the file's span."""
        d = np.asarray(d, dtype=float)
        lo, hi = self.epochs[0], self.epochs[-1]
        if np.any(d < lo) or np.any(d > hi):
            raise ValueError(f'IGRF coefficients ({self.coefficient_file.rsplit("/", 1)[-1]}) cover days '
                             f'{lo:.1f}..{hi:.1f} since J2000.0 (1900-2030 for IGRF-14), got '
                             f'{d.min():.1f}..{d.max():.1f}')
        i = np.clip(np.searchsorted(self.epochs, d, side='right') - 1, 0, len(self.epochs) - 2)
        w = ((d - self.epochs[i]) / (self.epochs[i + 1] - self.epochs[i]))[..., None]
        return self.g[i] + w * self._dg[i], self.h[i] + w * self._dh[i]

    def field_spherical(self, radius, colatitude, longitude, d) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(B_r, B_theta, B_phi) in nT at geocentric radius (m), colatitude, longitude (rad) and time."""
        radius, theta, phi, d = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                                      for x in (radius, colatitude, longitude, d)))
        theta = np.clip(theta, POLE_GUARD, math.pi - POLE_GUARD)
        g, h = self.coefficients(d)
        P, dP = schmidt_legendre(theta, self.max_degree)
        # (a/r)^(n+2) and cos/sin(m phi) per degree and order (..., 14), then spread over the K terms.
        ratio = REFERENCE_RADIUS / radius
        powers = np.cumprod(np.broadcast_to(ratio[..., None], ratio.shape + (self.max_degree + 3,)), axis=-1)
        scale = powers[..., self.n + 1]                  # powers[..., j] = ratio^(j + 1)
        orders = np.arange(self.max_degree + 1)
        cos_m = np.cos(orders * phi[..., None])[..., self.m]
        sin_m = np.sin(orders * phi[..., None])[..., self.m]
        sP = scale * np.stack([P[k] for k in self._keys], axis=-1)
        sdP = scale * np.stack([dP[k] for k in self._keys], axis=-1)
        even = g * cos_m + h * sin_m
        odd = self.m * (h * cos_m - g * sin_m)
        b_r = np.sum((self.n + 1) * even * sP, axis=-1)
        b_theta = -np.sum(even * sdP, axis=-1)
        b_phi = -np.sum(odd * sP, axis=-1) / np.sin(theta)
        return b_r, b_theta, b_phi

    def field_ecef(self, r_ecef, d) -> np.ndarray:
        """B (..., 3) in tesla, ECEF axes, at ECEF positions (m) and times (days since J2000.0)."""
        r = np.asarray(r_ecef, dtype=float)
        p = np.hypot(r[..., 0], r[..., 1])
        radius = np.hypot(p, r[..., 2])
        theta = np.arctan2(p, r[..., 2])
        phi = np.arctan2(r[..., 1], r[..., 0])
        b_r, b_t, b_p = self.field_spherical(radius, theta, phi, d)
        st, ct, sp, cp = np.sin(theta), np.cos(theta), np.sin(phi), np.cos(phi)
        return NANOTESLA * np.stack([b_r * st * cp + b_t * ct * cp - b_p * sp,
                                     b_r * st * sp + b_t * ct * sp + b_p * cp,
                                     b_r * ct - b_t * st], axis=-1)

    def field_eci(self, r_eci, d) -> np.ndarray:
        """B (..., 3) in tesla, ECI axes, at ECI positions (m) and times (days since J2000.0)."""
        return ecef_to_eci(self.field_ecef(eci_to_ecef(r_eci, d), d), d)

    def dipole(self, d: float) -> DipoleModel:
        """The tilted dipole of this model's first-degree coefficients at ``d`` days since J2000.0."""
        g, h = self.coefficients(d)
        col = {k: i for i, k in enumerate(self._keys)}
        return DipoleModel(g[col[1, 0]], g[col[1, 1]], h[col[1, 1]])


@lru_cache(maxsize=4)
def load_igrf(coefficient_file: str | None = None, max_degree: int = 13) -> IgrfModel:
    """A shared :class:`IgrfModel` per file and degree (reading the file takes ~30 ms: a Monte Carlo
    builds one environment per run; None: ppigrf's IGRF-14 file). The model is never modified after
    construction."""
    return IgrfModel(coefficient_file, max_degree)


class DipoleModel:
    """Tilted dipole ``B = (a/r)^3 (3 (g . r_hat) r_hat - g)``, ``g = (g_1^1, h_1^1, g_1^0)`` nT (ECEF)."""

    def __init__(self, g10: float, g11: float, h11: float) -> None:
        self.vector = np.array([g11, h11, g10], dtype=float) * NANOTESLA   # T

    def field_ecef(self, r_ecef, d=None) -> np.ndarray:
        """B (..., 3) in tesla, ECEF axes (``d`` unused: the coefficients are frozen)."""
        r = np.asarray(r_ecef, dtype=float)
        radius = np.linalg.norm(r, axis=-1, keepdims=True)
        u = r / radius
        g = self.vector
        gu = (u[..., 0] * g[0] + u[..., 1] * g[1] + u[..., 2] * g[2])[..., None]   # fixed order, not BLAS
        return (REFERENCE_RADIUS / radius) ** 3 * (3.0 * gu * u - self.vector)

    def field_eci(self, r_eci, d) -> np.ndarray:
        """B (..., 3) in tesla, ECI axes, at ECI positions (m) and times (days since J2000.0)."""
        return ecef_to_eci(self.field_ecef(eci_to_ecef(r_eci, d)), d)
