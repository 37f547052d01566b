"""Visibility moments by Funk-Hecke: ``V_c = filter_w(alpha Y_c)`` for many lobes at once, through
the spherical harmonics of ``alpha`` (``docs/lobes.md``, "Visibility moments by Funk-Hecke").

``filter_w`` is the normalized ``cos^w`` average of :mod:`envcap.prefilter.exact` (texel-centre
quadrature over the input's texels, exact solid angles ``Omega``).  Expanding the lobe in Legendre
polynomials, ``max(0, d.u)^w = (2 pi / (w + 1)) sum_lm lambda_l(w) Y_lm(d) Y_lm(u)``, turns both sums
of the quadrature into the input's *quadrature coefficients*::

    filter_w(f)(d) = sum_lm lambda_l(w) f_lm Y_lm(d) / sum_lm lambda_l(w) o_lm Y_lm(d),
    f_lm = sum_u Omega(u) f(u) Y_lm(u),   o_lm = sum_u Omega(u) Y_lm(u),

exact but for the degree cut (:func:`degree_plan`).  For ``f = alpha Y_c`` (``Y_c`` a polynomial of
degree ``<= order`` in ``x, y, z``) the coefficients follow from ``alpha``'s alone: multiplying a
degree-``l`` harmonic by ``x``, ``y`` or ``z`` gives degrees ``l +- 1`` (a polynomial identity, so
exact on the texel centres too), so ``alpha`` is projected up to degree ``L + order`` once and
``(alpha Y_c)_lm`` (``l <= L``) comes from the sparse :func:`multiplication_operators`.

Symmetry: the cube's texels are mapped onto each other by the eight sign flips of the
coordinates (a texel of face ``+X``'s first quadrant, its three mirrors on ``+X`` and their four
images on ``-X``), and a flip multiplies each real SH by ``+-1`` (:func:`mirror_signs`): ``Y_k(g u)
= chi_k(g) Y_k(u)``, ``chi_k`` one of the eight characters of the group.  So the harmonics are
evaluated on the first quadrant of faces ``+X, +Y, +Z`` only, the input summed over each orbit with
the eight characters (a Walsh-Hadamard transform) and each coefficient taken from its own
character's sums; outputs come back the same way.  An eighth of the arithmetic of the plain sums:
one float32 GEMM over the input's texels (the projection), then one per lobe at its output texels.
No GL context.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube as cube_geometry
from envcap.prefilter.wide_lobes import lobe_band_factors

__all__ = ["BAND_TOL", "CHUNK_BYTES", "FLOOR_DEGREE", "MAX_DEGREE", "band_limit", "degree_plan", "harmonic_visibility",
           "mirror_signs", "multiplication_operators", "probe_bytes", "real_sh_rows", "SparseRows"]

BAND_TOL = 1e-4
"""A lobe keeps the bands up to the last with ``|lambda_l(w)| > BAND_TOL`` (:func:`band_limit`)."""
FLOOR_DEGREE = 40
"""The wide lobes (``w <= 16``) keep at least this many bands (:func:`degree_plan`)."""
MAX_DEGREE = 80
"""Highest degree :func:`harmonic_visibility` expands to (lobes up to ``w`` ~ 340 at :data:`BAND_TOL`)."""
_SMALL_W = 16.0
_BLOCK_TEXELS = 4096          # projection: texels per block of harmonics (float32, 4 B x K each)
CHUNK_BYTES = 128 << 20
"""Probes per chunk of :func:`harmonic_visibility`: their working arrays (:func:`probe_bytes`) fit this."""


def _sh_count(degree: int) -> int:
    return (int(degree) + 1) ** 2


def band_limit(w: float, tol: float = BAND_TOL) -> int:
    """The least ``L`` with ``|lambda_l(w)| <= tol`` for every ``l > L`` (``lambda_l``: Legendre
    coefficients of the normalized ``cos^w`` lobe; ``|lambda_l|`` falls along each parity)."""
    w = float(w)
    if not (w >= 0 and math.isfinite(w)):
        raise ValueError(f"cosine power must be finite and >= 0, got {w!r}")
    lam = [1.0, (w + 1.0) / (w + 2.0)]
    l = 1
    while not (abs(lam[l]) <= tol and abs(lam[l - 1]) <= tol) and l < 8 * MAX_DEGREE:
        l += 1
        lam.append(lam[l - 2] * (w - l + 2.0) / (w + l + 1.0))
    return max(l - 2, 0)


def degree_plan(powers: Sequence[float], tol: float = BAND_TOL) -> tuple[int, list[int]]:
    """``(L, [L_i])``: each lobe's degree and the largest.  A lobe of ``w > 16`` keeps its
    :func:`band_limit`; a wider one (``lambda_l`` falls only as a power of ``l`` there: the clamped
    cosine's kink) every band up to ``max(FLOOR_DEGREE, the others' largest)``, at most its band
    limit.  ``ValueError`` past :data:`MAX_DEGREE`."""
    limits = [band_limit(w, tol) for w in powers]
    top = max([0] + [b for b, w in zip(limits, powers) if w > _SMALL_W])
    if top > MAX_DEGREE:
        raise ValueError(f"a lobe of w = {max(powers):g} needs SH degree {top} > {MAX_DEGREE}")
    limits = [b if w > _SMALL_W else min(b, max(FLOOR_DEGREE, top)) for b, w in zip(limits, powers)]
    return max(limits), limits


def real_sh_rows(d: ArrayLike, degree: int, dtype: type = np.float64) -> NDArray[np.floating]:
    """Orthonormal real SH (row ``l^2 + l + m``, z polar: the basis of
    :func:`envcap.prefilter.wide_lobes.real_sh`, no Condon-Shortley phase) at unit directions ``d``
    ``(M, 3)`` -> ``((degree + 1)^2, M)`` of ``dtype``; the same fully normalized Legendre recurrence,
    run for every order ``m`` at once."""
    d = np.asarray(d, np.float64).reshape(-1, 3)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    big_l = int(degree)
    count = d.shape[0]
    out = np.empty((_sh_count(big_l), count), dtype)
    s = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    angle = np.arctan2(y, x)[None] * np.arange(1, big_l + 1)[:, None]
    cos_m, sin_m = math.sqrt(2.0) * np.cos(angle), math.sqrt(2.0) * np.sin(angle)   # m = 1 .. L
    pmm = np.empty((big_l + 1, count))
    pmm[0] = math.sqrt(1.0 / (4.0 * math.pi))
    for m in range(1, big_l + 1):
        pmm[m] = pmm[m - 1] * (math.sqrt((2.0 * m + 1.0) / (2.0 * m)) * s)
    prev2 = prev = np.empty((0, count))
    for l in range(big_l + 1):
        cur = np.empty((l + 1, count))
        cur[l] = pmm[l]
        if l >= 1:
            cur[l - 1] = math.sqrt(2.0 * l + 1.0) * z * pmm[l - 1]
        if l >= 2:
            m = np.arange(l - 1, dtype=np.float64)[:, None]
            a = np.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b = np.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
            cur[:l - 1] = a * (z * prev[:l - 1] - b * prev2[:l - 1])
        c = l * l + l
        out[c] = cur[0]
        if l:
            out[c + 1:c + l + 1] = cur[1:] * cos_m[:l]
            out[c - l:c] = (cur[1:] * sin_m[:l])[::-1]
        prev2, prev = prev, cur
    return out


@lru_cache(maxsize=16)
def mirror_signs(axis: int, degree: int) -> NDArray[np.float64]:
    """``s_k`` (``((degree + 1)^2,)``) with ``Y_k(u') = s_k Y_k(u)``, ``u'`` = ``u`` with world axis
    ``axis`` negated (real SH of :func:`real_sh_rows`): ``x``: ``phi -> pi - phi``, ``(-1)^m`` for the
    cosines, ``-(-1)^m`` for the sines; ``y``: ``phi -> -phi``, ``-1`` for the sines; ``z``:
    ``(-1)^(l + m)``."""
    out = np.empty(_sh_count(degree))
    for l in range(degree + 1):
        for m in range(-l, l + 1):
            am = abs(m)
            if axis == 0:
                s = (-1.0) ** am * (1.0 if m >= 0 else -1.0)
            elif axis == 1:
                s = 1.0 if m >= 0 else -1.0
            else:
                s = (-1.0) ** (l + am)
            out[l * l + l + m] = s
    return out


def _character_rows(degree: int) -> list[NDArray[np.intp]]:
    """The harmonics (rows ``k``) of each character ``c = 4 b_x + 2 b_y + b_z`` (``b_a = 1``: ``Y_k``
    changes sign when axis ``a`` is flipped)."""
    bits = [(mirror_signs(a, degree) < 0).astype(int) for a in range(3)]
    code = 4 * bits[0] + 2 * bits[1] + bits[2]
    return [np.flatnonzero(code == c) for c in range(8)]


_HADAMARD = np.array([[(-1.0) ** bin(c & g).count("1") for g in range(8)] for c in range(8)], np.float32)


def _walsh(a: NDArray[np.float32]) -> NDArray[np.float32]:
    """``sum_g (-1)^(c.g) a[g]`` over the leading axis of 8 (``g``, ``c``: bits ``x, y, z``): the
    character table of the sign flips (symmetric, its own inverse up to 8)."""
    return (_HADAMARD @ a.reshape(8, -1)).reshape(a.shape)


@lru_cache(maxsize=8)
def _orbits(n: int) -> tuple[tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.float64]], ...]:
    """Per face ``+X, +Y, +Z``: the directions ``(Q, 3)`` of its first quadrant's texels, the flat
    texel indices ``(8, Q)`` (into ``(6, n, n)``) of their images under the flips ``g = 4 f_x + 2
    f_y + f_z``, and ``1 / |stabilizer|`` ``(Q,)`` (an odd face's middle row or column is its own
    mirror)."""
    h = (n + 1) // 2
    dirs = cube_geometry.texel_directions(n)
    out = []
    for f in (0, 2, 4):
        d = np.ascontiguousarray(dirs[f][:h, :h].reshape(-1, 3))
        idx = []
        for g in range(8):
            flip = np.array([-1.0 if g & 4 else 1.0, -1.0 if g & 2 else 1.0, -1.0 if g & 1 else 1.0])
            face, row, col = cube_geometry.direction_to_texel(d * flip, n)
            idx.append(face * n * n + row * n + col)
        idx_a = np.stack(idx)
        out.append((d, idx_a, 1.0 / (idx_a == idx_a[0]).sum(axis=0)))
    return tuple(out)


@dataclass(frozen=True)
class SparseRows:
    """A sparse matrix by padded rows: row ``r`` is ``sum_j vals[r, j] e_{cols[r, j]}`` (padding:
    column 0, value 0)."""

    cols: NDArray[np.intp]
    vals: NDArray[np.float64]

    def apply(self, src: NDArray[np.float64], rows: int | None = None) -> NDArray[np.float64]:
        """The first ``rows`` rows (all by default) times ``src`` ``(K, ...)``."""
        rows = self.cols.shape[0] if rows is None else rows
        out = np.zeros((rows,) + src.shape[1:])
        for j in range(self.cols.shape[1]):
            out += self.vals[:rows, j].reshape((rows,) + (1,) * (src.ndim - 1)) * src[self.cols[:rows, j]]
        return out


@lru_cache(maxsize=4)
def multiplication_operators(degree: int) -> tuple[SparseRows, SparseRows, SparseRows]:
    """``(M_x, M_y, M_z)``, sparse ``(degree^2, (degree + 1)^2)``: the coefficients (``l < degree``) of
    ``x f``, ``y f``, ``z f`` from those of ``f`` (``l <= degree``), for the real SH of
    :func:`real_sh_rows` and their own ``x, y, z`` (``docs/lobes.md``: ``z P_l^m = A_l^m P_{l+1}^m +
    A_{l-1}^m P_{l-1}^m``, ``sin(theta) P_l^m`` raised and lowered in ``m``, the azimuths by product
    formulas)."""
    big = int(degree)
    ops: dict[str, tuple[list[int], list[int], list[float]]] = {a: ([], [], []) for a in "xyz"}

    def put(axis: str, l2: int, m2: int, l: int, m: int, v: float) -> None:
        if 0 <= l2 < big and abs(m2) <= l2 and v != 0.0:
            r, c, vals = ops[axis]
            r.append(l2 * l2 + l2 + m2)
            c.append(l * l + l + m)
            vals.append(v)

    h = 1.0 / math.sqrt(2.0)
    for l in range(big + 1):
        below = (2 * l - 1) * (2 * l + 1)
        above = (2 * l + 1) * (2 * l + 3)
        for m in range(l + 1):
            a_up = math.sqrt(((l + 1) ** 2 - m * m) / above)
            a_dn = math.sqrt((l * l - m * m) / below) if l else 0.0
            for mm in ((m, -m) if m else (0,)):
                put("z", l + 1, mm, l, mm, a_up)
                put("z", l - 1, mm, l, mm, a_dn)
            b1 = math.sqrt((l + m + 1) * (l + m + 2) / above)
            b2 = math.sqrt((l - m) * (l - m - 1) / below) if l else 0.0
            c1 = math.sqrt((l - m + 1) * (l - m + 2) / above)
            c2 = math.sqrt((l + m) * (l + m - 1) / below) if l else 0.0
            if m == 0:
                for axis, mm in (("x", 1), ("y", -1)):
                    put(axis, l + 1, mm, l, 0, h * b1)
                    put(axis, l - 1, mm, l, 0, -h * b2)
                continue
            lo = h if m == 1 else 0.5            # P cos(0 phi) is Y_l0 itself, P cos(k phi) is Y_lk / sqrt 2
            for axis, mm, src, sgn in (("x", m + 1, m, 1.0), ("y", -(m + 1), m, 1.0), ("x", -(m + 1), -m, 1.0),
                                       ("y", m + 1, -m, -1.0)):
                put(axis, l + 1, mm, l, src, sgn * 0.5 * b1)
                put(axis, l - 1, mm, l, src, -sgn * 0.5 * b2)
            put("x", l + 1, m - 1, l, m, -lo * c1)
            put("x", l - 1, m - 1, l, m, lo * c2)
            put("y", l + 1, m - 1, l, -m, -lo * c1)
            put("y", l - 1, m - 1, l, -m, lo * c2)
            if m > 1:
                put("y", l + 1, -(m - 1), l, m, 0.5 * c1)
                put("y", l - 1, -(m - 1), l, m, -0.5 * c2)
                put("x", l + 1, -(m - 1), l, -m, -0.5 * c1)
                put("x", l - 1, -(m - 1), l, -m, 0.5 * c2)
    out = []
    for axis in "xyz":
        r, c, v = (np.asarray(x) for x in ops[axis])
        order = np.argsort(r, kind="stable")
        r, c, v = r[order], c[order], v[order]
        slot = np.arange(r.size) - np.searchsorted(r, r)          # position within its row
        cols = np.zeros((big * big, int(slot.max()) + 1), np.intp)
        vals = np.zeros(cols.shape)
        cols[r, slot], vals[r, slot] = c, v
        out.append(SparseRows(cols, vals))
    return out[0], out[1], out[2]


def _monomials(order: int, basis_fn: Callable[[NDArray[np.float64]], NDArray[np.float64]]
               ) -> tuple[list[tuple[int, int, int]], NDArray[np.float64]]:
    """The monomials ``x^a y^b z^c`` (``a + b + c <= order``) and ``beta`` ``(monomials, n_sh)`` with
    ``basis_fn(u) = monomials(u) @ beta`` on the sphere (least squares: exact for columns that are
    polynomials of degree ``<= order``)."""
    exps = [(a, b, k - a - b) for k in range(order + 1) for a in range(k, -1, -1) for b in range(k - a, -1, -1)]
    u = np.random.default_rng(0).normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    mono = np.stack([u[:, 0] ** a * u[:, 1] ** b * u[:, 2] ** c for a, b, c in exps], axis=1)
    beta = np.linalg.lstsq(mono, basis_fn(u), rcond=None)[0]
    beta[np.abs(beta) < 1e-12] = 0.0
    return exps, beta


def _project(alpha: NDArray, degree: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Quadrature coefficients up to ``degree`` of the cubes ``alpha`` ``(P, 6, N, N)`` (any float
    array or view) and of 1: ``((K, P), (K,))``, from the first quadrants of faces ``+X, +Y, +Z``
    with the input summed over each orbit per character (module docstring), in blocks of texels."""
    p_all, _, n, _ = alpha.shape
    k = _sh_count(degree)
    h = (n + 1) // 2
    w = np.tile(cube_geometry.texel_solid_angles(n)[0][:h, :h].reshape(-1), 3)   # every face alike, flip-symmetric
    orbits = _orbits(n)
    d = np.concatenate([o[0] for o in orbits])
    face, rest = np.divmod(np.concatenate([o[1] for o in orbits], axis=1), n * n)
    row, col = np.divmod(rest, n)
    w = (w * np.concatenate([o[2] for o in orbits])).astype(np.float32)
    rows = _character_rows(degree)
    probe = np.arange(p_all)[None, :, None]
    coef, one = np.zeros((k, p_all)), np.zeros(k)
    for t0 in range(0, d.shape[0], _BLOCK_TEXELS):
        t = slice(t0, min(d.shape[0], t0 + _BLOCK_TEXELS))
        y = real_sh_rows(d[t], degree, np.float32)                             # (K, T)
        ones = _walsh(np.ones((8, y.shape[1]), np.float32)) * w[t]             # the orbit sums of 1
        images = np.asarray(alpha[probe, face[:, None, t], row[:, None, t], col[:, None, t]], np.float32)  # (8, P, T)
        sums = _walsh(images)
        sums *= w[t]
        for c in range(8):
            one[rows[c]] += y[rows[c]] @ ones[c]
            coef[rows[c]] += y[rows[c]] @ sums[c].T
    return coef, one


def probe_bytes(n: int, degree: int, n_sh: int, out_face: int = 32) -> int:
    """Working bytes per probe of a chunk of :func:`harmonic_visibility` (faces of ``n`` texels,
    expansion degree ``degree``, ``n_sh`` functions ``Y_c``, lobes on faces of at most ``out_face``
    texels): the orbit sums of one block of texels (two float32 arrays of ``8 T``), the coefficients
    (float64 of ``alpha`` and its monomials up to order 1 and of ``alpha Y_c``, float32 scaled per
    lobe of a level), the four lobes' sums per character at the orbits of three faces and three
    float32 arrays of one lobe's values."""
    block = min(_BLOCK_TEXELS, 3 * ((n + 1) // 2) ** 2)
    k = _sh_count(degree + 1)
    return 64 * block + 8 * k * (4 + n_sh) + 16 * k * n_sh + 4 * 8 * 3 * ((out_face + 1) // 2) ** 2 * (4 + 3) * n_sh


def _moments(coef: NDArray[np.float64], degree: int, order: int,
             basis_fn: Callable[[NDArray[np.float64]], NDArray[np.float64]]) -> NDArray[np.float64]:
    """``(K, P, n_sh)``: the coefficients (``l <= degree``) of ``alpha Y_c`` from those of ``alpha``
    ``coef`` (``(K', P)``, ``l <= degree + order``), by the monomials of ``Y_c`` and the
    multiplication operators (each product is exact one degree below its factor)."""
    ops = multiplication_operators(degree + order)
    exps, beta = _monomials(order, basis_fn)
    kb = _sh_count(degree)
    mono: dict[tuple[int, int, int], NDArray[np.float64]] = {(0, 0, 0): coef}
    out = np.zeros((kb, coef.shape[1], beta.shape[1]))
    for e, row in zip(exps, beta):
        if e not in mono:
            axis = 0 if e[0] else (1 if e[1] else 2)
            src = mono[(e[0] - (axis == 0), e[1] - (axis == 1), e[2] - (axis == 2))]
            deg = math.isqrt(src.shape[0]) - 1
            mono[e] = ops[axis].apply(src, deg * deg)
        for c in np.flatnonzero(row):
            out[..., c] += row[c] * mono[e][:kb]
    return out


def _synthesize(moments: NDArray[np.float64], one: NDArray[np.float64], powers: Sequence[float],
                limits: Sequence[int], sizes: Sequence[int], out: list[NDArray[np.float32]]) -> None:
    """Fill ``out[i]`` ``(P, 6, s, s, n_sh)`` with lobe ``i``: its bands scaled by ``lambda_l`` at the
    texels of the first quadrants of ``+X, +Y, +Z`` per character, then unfolded onto the orbits
    (:func:`_walsh`), over the normalizer's own sum."""
    kb, p_all, n_sh = moments.shape
    flat_m = moments.reshape(kb, p_all * n_sh).astype(np.float32)
    for s in sorted(set(sizes)):
        idx = [i for i, si in enumerate(sizes) if si == s]
        deg = max(limits[i] for i in idx)
        rows = _character_rows(deg)
        orbits = _orbits(s)                                                     # faces +X, +Y, +Z stacked
        face, rest = np.divmod(np.concatenate([o for _, o, _ in orbits], axis=1).reshape(-1), s * s)
        row, col = np.divmod(rest, s)
        y = real_sh_rows(np.concatenate([d for d, _, _ in orbits]), deg, np.float32).T   # (3 Q, K)
        width = p_all * n_sh + 1
        c = np.zeros((_sh_count(deg), len(idx) * width), np.float32)           # every lobe of the level side by side
        for j, i in enumerate(idx):
            k = _sh_count(limits[i])
            lam = np.repeat(lobe_band_factors(float(powers[i]), limits[i]), 2 * np.arange(limits[i] + 1) + 1)
            np.multiply(flat_m[:k], lam.astype(np.float32)[:, None], out=c[:k, j * width:(j + 1) * width - 1])
            c[:k, (j + 1) * width - 1] = one[:k] * lam                           # the normalizer's
        parts = np.empty((8, y.shape[0], c.shape[1]), np.float32)               # per character, every lobe
        for ch, r in enumerate(rows):
            np.matmul(y[:, r], c[r], out=parts[ch])
        for j, i in enumerate(idx):
            v = _walsh(np.ascontiguousarray(parts[..., j * width:(j + 1) * width]))   # the 8 images' values
            v = v[..., :-1] / v[..., -1:]
            out[i][:, face, row, col] = np.moveaxis(v.reshape(-1, p_all, n_sh), 1, 0)


def harmonic_visibility(alpha: ArrayLike, powers: Sequence[float], sizes: Sequence[int], order: int,
                        basis_fn: Callable[[NDArray[np.float64]], NDArray[np.float64]],
                        tol: float = BAND_TOL, out: Sequence[NDArray[np.float32]] | None = None
                        ) -> list[NDArray[np.float32]]:
    """``filter_w(alpha Y_c)`` of ``P`` cubes ``alpha`` ``(P, 6, N, N)`` (finite, checked by the caller)
    for each lobe ``powers[i]`` on ``sizes[i]``-texel faces: ``[(P, 6, s_i, s_i, n_sh)]`` float32,
    ``Y_c = basis_fn(u)[:, c]`` (``(M, 3) -> (M, n_sh)``, polynomials of degree ``<= order`` on the
    sphere).  The filter of :mod:`envcap.prefilter.exact` but for the bands :func:`degree_plan` drops
    (module docstring); ``ValueError`` past :data:`MAX_DEGREE`.  ``out``: float32 arrays of those
    shapes to fill instead of new ones (views strided along the first axis are fine)."""
    a = np.asarray(alpha)
    if a.ndim != 4 or a.shape[1] != 6 or a.shape[2] != a.shape[3] or len(powers) != len(sizes):
        raise ValueError(f"alpha must be (P, 6, N, N) with one size per power, got {a.shape}, {len(powers)} powers, "
                         f"{len(sizes)} sizes")
    n_sh = np.asarray(basis_fn(np.eye(3))).shape[-1]
    res = [np.empty((a.shape[0], 6, s, s, n_sh), np.float32) for s in sizes] if out is None else list(out)
    if [r.shape for r in res] != [(a.shape[0], 6, s, s, n_sh) for s in sizes]:
        raise ValueError("out must hold one (P, 6, s, s, n_sh) array per lobe")
    if not sizes:
        return res
    big, limits = degree_plan(powers, tol)
    per = max(1, int(CHUNK_BYTES // probe_bytes(a.shape[2], big, n_sh, max(sizes))))
    for p0 in range(0, a.shape[0], per):       # chunks of probes: bounded memory, the harmonics again per chunk
        coef, one = _project(a[p0:p0 + per], big + order)
        _synthesize(_moments(coef, big, order, basis_fn), one, powers, limits, sizes, [r[p0:p0 + per] for r in res])
    return res
    big, limits = degree_plan(powers, tol)
    coef, one = _project(a, big + order)
    _synthesize(_moments(coef, big, order, basis_fn), one, powers, limits, sizes, res)
    return res
