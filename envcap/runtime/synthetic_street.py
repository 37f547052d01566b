"""An analytic street for tests and examples of the runtime: radiance by ray tracing three planes.

A street runs along world axis ``along`` (0 = x, 2 = z) between two facade planes (cross-axis
coordinates ``planes[0] < planes[1]``) above a ground plane at height ``planes[2]``; the facades
are unbounded in height and along the street.  Radiance seen from a point along a direction:

* facades: a window pattern (bright warm windows 1.2 m x 1.6 m on a 3 m x 3 m grid; the min
  facade is brick red, the max facade pale blue); ground: a 1 m grey checker;
* rays that hit no plane (upward along the street, or up with no facade in the way) see the sky:
  the street radiance is then 0 with alpha 0 (premultiplied), and :func:`sky_radiance` applies.

All radiance values are linear RGB in arbitrary units (~1 = overcast sky at the horizon).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube
from envcap.core.lobes import lobe_ladder
from envcap.runtime.limits import FAR
from envcap.runtime.parallax import exit_distance
from envcap.runtime.street import RuntimeStreet

SUN_DIR = np.array([0.3, 0.8, 0.52]) / np.linalg.norm([0.3, 0.8, 0.52])


def sky_radiance(d: ArrayLike, sun: bool = True) -> NDArray[np.float64]:
    """Smooth sky ``(..., 3)`` for unit directions ``d`` ``(..., 3)``: blue zenith, bright
    horizon, dark ground below, plus a soft sun glow (peak 20) toward :data:`SUN_DIR`."""
    d = np.asarray(d, dtype=np.float64)
    y = d[..., 1]
    up = np.clip(y, 0, 1)[..., None]
    zen = np.array([0.25, 0.45, 1.0])
    hor = np.array([1.0, 0.95, 0.9])
    below = np.array([0.15, 0.13, 0.12])
    col = np.where(y[..., None] >= 0, hor + (zen - hor) * np.sqrt(up), below + (hor - below) * np.exp(8 * np.minimum(y, 0))[..., None])
    if sun:
        c = np.einsum("...i,i->...", d, SUN_DIR)
        col = col + 20.0 * np.exp(40.0 * (c - 1.0))[..., None] * np.array([1.0, 0.9, 0.7])
    return col


BUILDING_HEIGHT = 12.0
"""Height (m) of the facades above the ground: above it a facade ray sees the sky (alpha 0)."""


def street_radiance(origin: ArrayLike, d: ArrayLike, planes: ArrayLike, along: int,
                    height: float = BUILDING_HEIGHT) -> NDArray[np.float64]:
    """Premultiplied RGBA ``(..., 4)`` seen from ``origin`` (inside the street) along unit ``d``.

    Facades end ``height`` m above the ground; rays passing above them see the sky (alpha 0)."""
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    pl = np.asarray(planes, dtype=np.float64)
    o, d = np.broadcast_arrays(o, d)
    pl = np.broadcast_to(pl, o.shape)
    c = 2 - along
    t = exit_distance(o, d, pl, along)
    hit = t < FAR
    h = o + np.where(hit, t, 0)[..., None] * d
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = np.where(d[..., 1] < 0, (pl[..., 2] - o[..., 1]) / np.where(d[..., 1] < 0, d[..., 1], -1), np.inf)
    on_ground = hit & (tg <= t)
    hit = hit & (on_ground | (h[..., 1] - pl[..., 2] <= height))
    a = h[..., along]
    # ground: 1 m checker in (along, cross)
    chk = (np.floor(a) + np.floor(h[..., c])) % 2
    ground = (0.2 + 0.25 * chk)[..., None] * np.array([1.0, 1.0, 1.0])
    # facades: windows on a 3 m grid
    fa = np.mod(a, 3.0)
    fy = np.mod(h[..., 1] - pl[..., 2], 3.0)
    win = (np.abs(fa - 1.5) < 0.6) & (np.abs(fy - 1.7) < 0.8) & (h[..., 1] - pl[..., 2] > 1.0)
    left = h[..., c] <= 0.5 * (pl[..., 0] + pl[..., 1])
    wall = np.where(left[..., None], np.array([0.55, 0.25, 0.18]), np.array([0.35, 0.45, 0.6]))
    facade = np.where(win[..., None], np.array([3.0, 2.4, 1.2]), wall)
    rgb = np.where(on_ground[..., None], ground, facade)
    rgb = np.where(hit[..., None], rgb, 0.0)
    return np.concatenate([rgb, hit[..., None].astype(np.float64)], axis=-1)


def environment_radiance(origin: ArrayLike, d: ArrayLike, planes: ArrayLike, along: int,
                         height: float = BUILDING_HEIGHT) -> NDArray[np.float64]:
    """Full radiance ``(..., 3)``: street where a plane is hit, :func:`sky_radiance` elsewhere."""
    st = street_radiance(origin, d, planes, along, height)
    return st[..., :3] + (1.0 - st[..., 3:4]) * sky_radiance(d)


def _supersampled_dirs(n: int, ss: int) -> NDArray[np.float64]:
    """Directions ``(6, n, n, ss*ss, 3)`` on an ss x ss grid inside every texel."""
    sub = (np.arange(n * ss) + 0.5) / (n * ss) * 2 - 1
    v, u = np.meshgrid(sub, sub, indexing="ij")
    d = cube.face_uv_to_direction(np.arange(6)[:, None, None], u[None], v[None])
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    d = d.reshape(6, n, ss, n, ss, 3).transpose(0, 1, 3, 2, 4, 5).reshape(6, n, n, ss * ss, 3)
    return d


def box_mips(level0: NDArray, levels: int) -> list[NDArray]:
    """A box-filtered chain (each level the 2x2 mean of the previous), ``(..., 6, N, N, C)`` in."""
    out = [np.asarray(level0, dtype=np.float32)]
    for _ in range(1, levels):
        a = out[-1]
        n = a.shape[-2]
        if n == 1:
            raise ValueError("too many levels for the face size")
        a = a.reshape(a.shape[:-3] + (n // 2, 2, n // 2, 2, a.shape[-1])).mean(axis=(-4, -2))
        out.append(a.astype(np.float32))
    return out


def probe_cubes(positions: ArrayLike, planes: ArrayLike, along: int, n: int, ss: int = 2) -> NDArray[np.float32]:
    """Level-0 probe array ``(P, 6, n, n, 4)``: premultiplied street radiance of each probe,
    the mean of ``ss x ss`` rays per texel."""
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    pl = np.broadcast_to(np.asarray(planes, dtype=np.float64), pos.shape)
    d = _supersampled_dirs(n, ss)
    out = np.empty((pos.shape[0], 6, n, n, 4), dtype=np.float32)
    for i in range(pos.shape[0]):
        out[i] = street_radiance(pos[i], d, pl[i], along).mean(axis=-2)
    return out


def sky_cube(n: int, ss: int = 2) -> NDArray[np.float32]:
    """Level-0 sky cube ``(6, n, n, 4)`` (alpha 1), mean of ``ss x ss`` rays per texel."""
    rgb = sky_radiance(_supersampled_dirs(n, ss)).mean(axis=-2)
    return np.concatenate([rgb, np.ones(rgb.shape[:-1] + (1,))], axis=-1).astype(np.float32)


def probe_positions(start: float, end: float, count: int, planes: Sequence[float], along: int,
                    height: float = 1.6) -> NDArray[np.float64]:
    """``count`` probe positions evenly spaced on the street's center line at ``height`` above ground."""
    if count < 1:
        raise ValueError("count must be >= 1")
    s = np.linspace(start, end, count)
    p = np.zeros((count, 3))
    p[:, along] = s
    p[:, 2 - along] = 0.5 * (planes[0] + planes[1])
    p[:, 1] = planes[2] + height
    return p


def synthetic_probe_set(n: int = 32, count: int = 3, along: int = 0, planes: Sequence[float] = (-6.0, 6.0, 0.0),
                        start: float = 0.0, end: float = 20.0
                        ) -> tuple[list[NDArray], list[NDArray], RuntimeStreet, NDArray[np.float64]]:
    """A small probe set of the analytic street: ``count`` probes from ``start`` to ``end`` (m)
    along axis ``along`` (0 = x, 2 = z), faces of ``n`` texels, box-filtered chains (the lobe
    ladder of ``n`` gives the powers; box mips are not cos^w-exact: for examples, benchmarks and
    GLSL-vs-twin tests, not for accuracy claims).

    Returns ``(probe_levels, sky_levels, street, powers)``: probe level k ``(count, 6, N_k, N_k, 4)``,
    sky level k ``(6, N_k, N_k, 4)``, the :class:`envcap.runtime.street.RuntimeStreet` and the powers.
    """
    pos = probe_positions(start, end, count, planes, along)
    pl = np.tile(np.asarray(planes, float), (count, 1))
    lad = lobe_ladder(n)
    probes = box_mips(probe_cubes(pos, pl, along, n), lad.levels)
    sky = box_mips(sky_cube(n), lad.levels)
    street = RuntimeStreet(along, pos, pl, np.arange(count))
    return probes, sky, street, np.asarray(lad.powers, dtype=np.float64)
