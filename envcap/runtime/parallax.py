"""Numpy twin of the runtime GLSL (``shaders/envcap_street.glsl``, ``envcap_lobes.glsl``,
``envcap_runtime.glsl``): probe selection, three-plane parallax, mip shift, sky composite, z(w)
from the lobe table and the lobes of Eq. 3 for a Lafortune BRDF.

Every function is vectorized (inputs broadcast; vectors are ``(..., 3)``), float64 by default;
``dtype=np.float32`` evaluates in float32 in the GLSL operation order, to compare with the GPU.
Conventions: world right-handed, meters, +Y up; a street runs along world axis ``along``
(0 = x, 2 = z), its cross axis is ``2 - along``; ``planes = (facade_min, facade_max, ground)``
in absolute world coordinates (m).  Math and fallbacks: ``docs/runtime.md``.  Nothing here
returns NaN or Inf for finite inputs; the fallbacks are the GLSL ones.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

FAR = 1.0e6
"""Hits farther than this (m) count as no hit (plane at infinity)."""
MIN_DIST = 1.0e-4
"""Distances (m) below this are clamped (zero-length probe vector, point on a plane)."""
MAX_RATIO = 256.0
"""Bound of the distance ratio d_probe / d_shade (at most 8 doublings of the lobe angle)."""
MAX_LOG2_WEIGHT = 64.0
"""Upper bound of log2 |Cv|^w for Lafortune lobe weights."""
MAX_LEVELS = 16
MAX_PROBES = 64

Array = NDArray[np.floating]


def _f(a: ArrayLike, dtype: Any) -> NDArray:
    return np.asarray(a, dtype=dtype)


def _check_along(along: int) -> int:
    if along not in (0, 2):
        raise ValueError(f"street axis index must be 0 (x) or 2 (z), got {along!r}")
    return along


def _dot3(a: NDArray, b: NDArray) -> NDArray:
    # GLSL order: (a.x*b.x + a.y*b.y) + a.z*b.z
    return (a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]) + a[..., 2] * b[..., 2]


def lobe_table(powers: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """``x_k = log2(1 + powers[k])`` for the GLSL uniform ``xk`` (computed in float64).

    ``powers`` is the manifest's strictly decreasing table of lobe powers (>= 0), at most
    ``MAX_LEVELS`` long.  Raises ``ValueError`` otherwise.
    """
    p = np.asarray(powers, dtype=np.float64)
    if p.ndim != 1 or not 1 <= p.size <= MAX_LEVELS:
        raise ValueError(f"powers must be a 1-D table of 1..{MAX_LEVELS} values, got shape {p.shape}")
    if not np.all(np.isfinite(p)) or np.any(p < 0) or np.any(np.diff(p) >= 0):
        raise ValueError(f"powers must be finite, >= 0 and strictly decreasing, got {p.tolist()}")
    return np.log2(1.0 + p).astype(dtype)


def z_of_w(w: ArrayLike, xk: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """Continuous mip level of power(s) ``w`` from the table ``xk = lobe_table(powers)``.

    Same rule as :func:`envcap.core.lobes.z_of_w` (piecewise linear in log2(1 + w), clamped to
    [0, L-1]), written as the GLSL loop.  Unlike ``envcap.core.lobes.z_of_w`` it does not raise:
    ``w < 0`` and NaN count as 0 (as in GLSL), ``+inf`` gives 0.
    """
    xk = _f(xk, dtype)
    w = _f(w, dtype)
    n = xk.size
    with np.errstate(invalid="ignore", over="ignore"):
        x = np.log2(dtype(1.0) + np.where(w > 0, w, dtype(0.0)))
    z = np.full(x.shape, dtype(n - 1), dtype=dtype)
    done = ~(x < xk[0])
    z[done] = 0.0
    for k in range(1, n):
        m = ~done & (x >= xk[k])
        z[m] = dtype(k - 1) + (xk[k - 1] - x[m]) / (xk[k - 1] - xk[k])
        done |= m
    return z


def nearest_probe(s: ArrayLike, along_coords: ArrayLike) -> NDArray[np.int64]:
    """Index of the probe nearest to along-street coordinate(s) ``s`` (ties: lower index).

    ``along_coords`` (m) sorted ascending, 1..MAX_PROBES of them.
    """
    a = np.asarray(along_coords, dtype=np.float64)
    if a.ndim != 1 or not 1 <= a.size <= MAX_PROBES:
        raise ValueError(f"need 1..{MAX_PROBES} probe coordinates, got shape {a.shape}")
    s = np.asarray(s, dtype=np.float64)
    return np.argmin(np.abs(s[..., None] - a), axis=-1)


def probe_pair(s: ArrayLike, along_coords: ArrayLike, dtype: Any = np.float64) -> tuple[NDArray, NDArray, NDArray]:
    """The two probes bracketing ``s`` and the weight ``t`` of the second (blend ``(1-t), t``).

    Linear in ``s`` between probes, so continuous; outside the probe range both indices are the
    end probe and ``t = 0``.  Returns ``(i0, i1, t)``.
    """
    a = _f(along_coords, dtype)
    if a.ndim != 1 or not 1 <= a.size <= MAX_PROBES:
        raise ValueError(f"need 1..{MAX_PROBES} probe coordinates, got shape {a.shape}")
    s = _f(s, dtype)
    n = a.size
    i = np.clip(np.searchsorted(a, s, side="right") - 1, 0, max(n - 2, 0))
    i0 = i.copy()
    i1 = np.minimum(i + 1, n - 1)
    span = a[i1] - a[i0]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(span > 0, np.clip((s - a[i0]) / np.where(span > 0, span, 1), 0, 1), 0).astype(dtype)
    lo = ~(s > a[0])
    hi = ~lo & ~(s < a[n - 1])
    i0 = np.where(lo, 0, np.where(hi, n - 1, i0))
    i1 = np.where(lo, 0, np.where(hi, n - 1, i1))
    t = np.where(lo | hi, dtype(0), t)
    return i0, i1, t


def clamp_to_street(x: ArrayLike, planes: ArrayLike, along: int, dtype: Any = np.float64) -> NDArray:
    """``x`` moved into the street volume (cross coordinate into the facades, height >= ground)."""
    c = 2 - _check_along(along)
    x = _f(x, dtype).copy()
    pl = _f(planes, dtype)
    x, pl = np.broadcast_arrays(x, pl)
    x = x.copy()
    x[..., c] = np.minimum(np.maximum(x[..., c], pl[..., 0]), pl[..., 1])
    x[..., 1] = np.maximum(x[..., 1], pl[..., 2])
    return x


def exit_distance(x: ArrayLike, d: ArrayLike, planes: ArrayLike, along: int, dtype: Any = np.float64) -> NDArray:
    """Distance (m) along unit ``d`` from ``x`` (inside the street) to the first plane, or FAR.

    +0.0 and -0.0 direction components mean "parallel" (no division happens for them).
    """
    c = 2 - _check_along(along)
    x = _f(x, dtype)
    d = _f(d, dtype)
    pl = _f(planes, dtype)
    far = dtype(FAR)
    dc = d[..., c]
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        tpos = (pl[..., 1] - x[..., c]) / np.where(dc > 0, dc, 1)
        tneg = (pl[..., 0] - x[..., c]) / np.where(dc < 0, dc, 1)
        tc = np.where(dc > 0, tpos, np.where(dc < 0, tneg, far))
        tg = np.where(d[..., 1] < 0, (pl[..., 2] - x[..., 1]) / np.where(d[..., 1] < 0, d[..., 1], 1), far)
    return np.minimum(np.minimum(tc, tg), far)


def parallax(x: ArrayLike, d: ArrayLike, p: ArrayLike, planes: ArrayLike, along: int,
             dtype: Any = np.float64) -> tuple[NDArray, NDArray]:
    """Three-plane parallax: ``(r, ratio)`` for shading points ``x``, unit directions ``d``,
    probe positions ``p`` and planes (all broadcast; vectors ``(..., 3)``).

    ``r`` (``(..., 3)``) is the unit vector from the probe to the hit point; ``ratio`` = |hit - p|
    / |hit - x| clamped to [1/MAX_RATIO, MAX_RATIO].  Fallbacks: no hit -> ``(d, 1)``; hit within
    MIN_DIST of the probe -> ``(d, 1/MAX_RATIO)``; ``x`` on a plane -> |hit - x| taken as MIN_DIST.
    Points outside the street or below the ground are first clamped into it.
    """
    x, d, p, planes = (np.asarray(a, dtype=dtype) for a in (x, d, p, planes))
    shape = np.broadcast_shapes(x.shape, d.shape, p.shape, planes.shape)
    x, d, p, planes = (np.broadcast_to(a, shape) for a in (x, d, p, planes))
    xc = clamp_to_street(x, planes, along, dtype)
    t = exit_distance(xc, d, planes, along, dtype)
    hit = t < dtype(FAR)
    r = (xc - p) + t[..., None] * d
    dp = np.sqrt(_dot3(r, r))
    ok = hit & (dp > dtype(MIN_DIST))
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = dp / np.maximum(t, dtype(MIN_DIST))
        ratio = np.minimum(np.maximum(ratio, dtype(1.0 / MAX_RATIO)), dtype(MAX_RATIO))
        rn = r / np.where(ok, dp, 1)[..., None]
    r_out = np.where(ok[..., None], rn, d)
    ratio_out = np.where(ok, ratio, np.where(hit, dtype(1.0 / MAX_RATIO), dtype(1.0))).astype(dtype)
    return r_out.astype(dtype), ratio_out


def shift_power(w: ArrayLike, ratio: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """Lobe power seen from the probe: ``max(w, 0) * ratio**2`` (docs/runtime.md)."""
    w = _f(w, dtype)
    ratio = _f(ratio, dtype)
    return np.maximum(w, dtype(0)) * (ratio * ratio)


def clamp_level(z: ArrayLike, n: int, dtype: Any = np.float64) -> NDArray:
    """Mip level clamped to [0, n - 1]; NaN -> 0."""
    z = _f(z, dtype)
    return np.where(z > 0, np.minimum(z, dtype(max(n, 1) - 1)), dtype(0))


def composite(street: ArrayLike, sky: ArrayLike, dtype: Any = np.float64) -> NDArray:
    """``street.rgb + (1 - clamp(street.a, 0, 1)) * sky`` (premultiplied street, ``(..., 4)``)."""
    st = _f(street, dtype)
    sk = _f(sky, dtype)
    return st[..., :3] + (dtype(1) - np.clip(st[..., 3:4], 0, 1)) * sk[..., :3]


def lafortune_lobe(v: ArrayLike, C: ArrayLike, w: ArrayLike, dtype: Any = np.float64) -> tuple[NDArray, NDArray]:
    """Axis ``c`` (``(..., 3)``, local frame, unit) and weight of one Lafortune lobe for Eq. 3.

    ``v``: view directions in the local shading frame (z = normal), unit, ``(..., 3)``;
    ``C``: lobe coefficients ``(Cx, Cy, Cz)``; ``w``: lobe power.  ``weight = |Cv|^w * 2 pi /
    (1 + w) * max(c_z, 0)`` with ``Cv = C * v``.  Fallbacks: |Cv| = 0 -> c = (0,0,1), weight 0;
    log2 |Cv|^w clamped to MAX_LOG2_WEIGHT; w < 0 as 0.
    """
    v, C, w = _f(v, dtype), _f(C, dtype), _f(w, dtype)
    w = np.maximum(w, dtype(0))
    cv = C * v
    ln = np.sqrt(_dot3(cv, cv))
    ok = ln > 0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        c = cv / np.where(ok, ln, 1)[..., None]
        e = np.minimum(w * np.log2(np.where(ok, ln, 1)), dtype(MAX_LOG2_WEIGHT))
        mag = np.where(e < -126, dtype(0), np.exp2(e))
        wt = mag * (dtype(2.0 * np.pi) / (dtype(1) + w)) * np.maximum(c[..., 2], dtype(0))
    c = np.where(ok[..., None], c, np.array([0, 0, 1], dtype=dtype))
    wt = np.where(ok, wt, dtype(0))
    return c.astype(dtype), wt.astype(dtype)


@dataclass(frozen=True)
class RuntimeStreet:
    """One street of a probe set, as the runtime needs it (from the manifest's street entry).

    ``along``: world axis index of the street (0 = x, 2 = z).  ``positions``: ``(P, 3)`` probe
    positions (m), sorted along the street; ``planes``: ``(P, 3)`` (facade_min, facade_max,
    ground) per probe (m); ``layers``: ``(P,)`` cube-array layer of each probe.
    """

    along: int
    positions: NDArray[np.float64]
    planes: NDArray[np.float64]
    layers: NDArray[np.int64]

    def __post_init__(self) -> None:
        _check_along(self.along)
        P = self.positions.shape[0]
        if self.positions.shape != (P, 3) or self.planes.shape != (P, 3) or self.layers.shape != (P,):
            raise ValueError("RuntimeStreet: positions and planes must be (P, 3) and layers (P,)")
        if not 1 <= P <= MAX_PROBES:
            raise ValueError(f"RuntimeStreet: need 1..{MAX_PROBES} probes, got {P}")
        if not (np.all(np.isfinite(self.positions)) and np.all(np.isfinite(self.planes))):
            raise ValueError("RuntimeStreet: probe positions and planes must be finite")
        if np.any(np.diff(self.positions[:, self.along]) < 0):
            raise ValueError("RuntimeStreet: probes must be sorted along the street")
        if np.any(self.planes[:, 1] <= self.planes[:, 0]):
            raise ValueError("RuntimeStreet: facade_max must be greater than facade_min")

    @property
    def along_coords(self) -> NDArray[np.float64]:
        return self.positions[:, self.along]

    @staticmethod
    def from_manifest(street: Mapping[str, Any]) -> "RuntimeStreet":
        """Build from a manifest street entry ``{"axis", "probes": [{"layer", "position", "planes"}]}``."""
        axis = street.get("axis")
        if axis not in ("x", "z"):
            raise ValueError(f"street {street.get('name', '?')!r}: axis must be 'x' or 'z', got {axis!r}")
        probes = sorted(street["probes"], key=lambda q: q["position"][0 if axis == "x" else 2])
        if not probes:
            raise ValueError(f"street {street.get('name', '?')!r} has no probes")
        pos = np.array([q["position"] for q in probes], dtype=np.float64)
        pl = np.array([[q["planes"]["facade_min"], q["planes"]["facade_max"], q["planes"]["ground"]] for q in probes],
                      dtype=np.float64)
        layers = np.array([int(q["layer"]) for q in probes], dtype=np.int64)
        return RuntimeStreet(0 if axis == "x" else 2, pos, pl, layers)

    def uniforms(self, powers: Sequence[float], prefix: str = "") -> dict[str, Any]:
        """Uniform values for the GLSL library: ``along_s``, ``pos`` (xyz, layer), ``planes``,
        ``count``, ``along``, ``xk``, ``nlevels`` (names with ``prefix``)."""
        P = self.positions.shape[0]
        pos = np.concatenate([self.positions, self.layers[:, None].astype(np.float64)], axis=1)
        pl = np.concatenate([self.planes, np.zeros((P, 1))], axis=1)
        xk = lobe_table(powers)
        return {prefix + "along_s": self.along_coords.astype(np.float32), prefix + "pos": pos.astype(np.float32),
                prefix + "planes": pl.astype(np.float32), prefix + "count": int(P), prefix + "along": int(self.along),
                prefix + "xk": xk.astype(np.float32), prefix + "nlevels": int(xk.size)}


# --- Texture-sampling twins (float64; texture lookups through envcap.core.cube_sampling) ----------

def sample_probe(probe_levels: Sequence[NDArray], sky_levels: Sequence[NDArray], x: ArrayLike, d: ArrayLike,
                 w: ArrayLike, layer: ArrayLike, p: ArrayLike, planes: ArrayLike, along: int,
                 powers: Sequence[float]) -> NDArray[np.float64]:
    """Twin of GLSL ``envcap_sample_probe``: cos^w-convolved radiance ``(..., 3)`` seen from ``x``
    along unit ``d`` using one probe (``layer``, position ``p``, ``planes``).

    ``probe_levels[k]``: ``(L, 6, N_k, N_k, 4)`` premultiplied RGBA; ``sky_levels[k]``:
    ``(6, M_k, M_k, >=3)``; ``powers``: the lobe table (same ladder for probes and sky).
    """
    from envcap.core import cube_sampling

    xk = lobe_table(powers)
    n = xk.size
    r, ratio = parallax(x, d, p, planes, along)
    zs = clamp_level(z_of_w(shift_power(w, ratio), xk), n)
    zk = clamp_level(z_of_w(np.broadcast_to(np.asarray(w, np.float64), r.shape[:-1]), xk), n)
    d = np.broadcast_to(np.asarray(d, dtype=np.float64), r.shape)
    st = cube_sampling.sample_cube_array(probe_levels, r, np.broadcast_to(layer, r.shape[:-1]), zs)
    sk = cube_sampling.sample_cube(sky_levels, d, zk)
    return composite(st, sk)


def sample_street(probe_levels: Sequence[NDArray], sky_levels: Sequence[NDArray], street: RuntimeStreet,
                  x: ArrayLike, d: ArrayLike, w: ArrayLike, powers: Sequence[float], blend: bool = False) -> NDArray[np.float64]:
    """Twin of GLSL ``envcap_sample_nearest`` (``blend=False``) or ``envcap_sample_blended``.

    ``x``, ``d``: ``(..., 3)`` shading points (m) and unit directions; ``w`` lobe power(s).
    """
    from envcap.core import cube_sampling

    x = np.asarray(x, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    shape = np.broadcast_shapes(x.shape, d.shape)
    x, d = np.broadcast_to(x, shape), np.broadcast_to(d, shape)
    w = np.broadcast_to(np.asarray(w, dtype=np.float64), shape[:-1])
    s = x[..., street.along]
    if not blend:
        i = nearest_probe(s, street.along_coords)
        return sample_probe(probe_levels, sky_levels, x, d, w, street.layers[i], street.positions[i], street.planes[i],
                            street.along, powers)
    xk = lobe_table(powers)
    n = xk.size
    i0, i1, t = probe_pair(s, street.along_coords)
    acc = np.zeros(shape[:-1] + (4,), dtype=np.float64)
    for idx, wt in ((i0, 1.0 - t), (i1, t)):
        r, ratio = parallax(x, d, street.positions[idx], street.planes[idx], street.along)
        z = clamp_level(z_of_w(shift_power(w, ratio), xk), n)
        acc += wt[..., None] * cube_sampling.sample_cube_array(probe_levels, r, street.layers[idx], z)
    zk = clamp_level(z_of_w(w, xk), n)
    return composite(acc, cube_sampling.sample_cube(sky_levels, d, zk))


def shade_lafortune(env: Any, v_local: ArrayLike, frame: ArrayLike, rho_d: ArrayLike, C: ArrayLike, w: ArrayLike,
                    rho_s: ArrayLike) -> NDArray[np.float64]:
    """Eq. 3 for a Lafortune BRDF (twin of GLSL ``envcap_shade_lafortune``), float64.

    ``env(dirs (..., 3) world, w (...)) -> (..., 3)`` returns the cos^w-convolved environment
    (e.g. a closure over :func:`sample_street`).  ``v_local``: ``(..., 3)`` unit view directions
    in the local frame; ``frame``: ``(..., 3, 3)`` rows T, B, N (world); ``rho_d``: ``(3,)``;
    ``C``: ``(K, 3)``; ``w``: ``(K,)``; ``rho_s``: ``(K, 3)``.  Returns ``(..., 3)``::

        L = rho_d E_1(N) + sum_i rho_s[i] |Cv_i|^w_i 2 pi / (1 + w_i) max(c_i . N, 0) E_wi(c_i)
    """
    v = np.asarray(v_local, dtype=np.float64)
    F = np.asarray(frame, dtype=np.float64)
    Nw = F[..., 2, :]
    L = np.asarray(rho_d, np.float64) * env(Nw, np.ones(v.shape[:-1]))
    for Ci, wi, rs in zip(np.asarray(C, np.float64), np.asarray(w, np.float64), np.asarray(rho_s, np.float64)):
        c, wt = lafortune_lobe(v, Ci, wi)
        cw = np.einsum("...i,...ij->...j", c, F)
        L = L + rs * wt[..., None] * env(cw, np.full(v.shape[:-1], wi))
    return L
