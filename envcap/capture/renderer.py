"""HDR cube capture of a scene mesh with moderngl: one pass per effect the scene calls for.

A :class:`CubeCapture` uploads a :class:`~envcap.scene.model.SceneMesh` once, runs the per-set
passes once (sky irradiance SH projection for ``sky_light``, the sun shadow map for
``sun_shadows``), and then captures probes: per probe, six draws (one per cube face, 90 degree
frustum, GL face orientation of :mod:`envcap.core.cube`) into one reused RGBA32F render target laid
out as a 3 x 2 grid of faces with a float32 reversed depth buffer, and one readback.  Each face
draws only the triangle chunks that can reach its frustum (:func:`chunk_triangles`,
:func:`chunk_face_visibility`; ``cull_chunks=False`` draws everything, same output).

Outputs (see ``docs/capture.md`` for the shading model and its assumptions):

* ``rgba``: ``(6, N, N, 4)`` float32, ``[face, row = t, column = s, RGBA]``, linear HDR radiance,
  premultiplied alpha: alpha 1 where geometry is seen, 0 (and RGB 0) where the sky shows.
* ``distance``: ``(6, N, N)`` float32, radial (Euclidean) distance in meters from the probe
  center to the surface seen through the texel center; 0 where alpha is 0.
* ``backfacing``: ``(6, N, N)`` bool, the texel sees the unlit side of a surface (back face,
  radiance 0).  A probe inside a closed building sees only back faces
  (:func:`probe_inside_geometry`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Iterable, Protocol, Sequence

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube
from envcap.core.resources import shader_source
from envcap.scene.model import EFFECTS, Scene, SceneMesh

# Cube faces as 3x3 matrices R_f with (sc, tc, ma) = R_f @ d, where the face coordinates of a
# direction d are u = sc / ma, v = tc / ma (envcap.core.cube.direction_to_face_uv) and ma > 0 in front.
_FACE_ROWS = np.array(
    [
        [[0, 0, -1], [0, -1, 0], [1, 0, 0]],    # +X: sc = -z, tc = -y, ma =  x
        [[0, 0, 1], [0, -1, 0], [-1, 0, 0]],    # -X: sc =  z, tc = -y, ma = -x
        [[1, 0, 0], [0, 0, 1], [0, 1, 0]],      # +Y: sc =  x, tc =  z, ma =  y
        [[1, 0, 0], [0, 0, -1], [0, -1, 0]],    # -Y: sc =  x, tc = -z, ma = -y
        [[1, 0, 0], [0, -1, 0], [0, 0, 1]],     # +Z: sc =  x, tc = -y, ma =  z
        [[-1, 0, 0], [0, -1, 0], [0, 0, -1]],   # -Z: sc = -x, tc = -y, ma = -z
    ],
    dtype=np.float64,
)

# Real SH basis constants (Ramamoorthi & Hanrahan 2001), order matches capture_frag.glsl.
_SH_C = (0.282094791773878, 0.488602511902920, 1.092548430592079, 0.315391565252520, 0.546274215296040)
_SH_A = np.array([math.pi] + [2.0 * math.pi / 3.0] * 3 + [math.pi / 4.0] * 5)  # cosine lobe A_l

PASSES: tuple[str, ...] = ("sky_sh", "shadow_map", "render", "readback")
"""Pass names recorded in ``passes_run``: per set (``sky_sh``, ``shadow_map``), per probe
(``render``: the six face draws, ``readback``: one read of all faces)."""


class SunLike(Protocol):
    direction: NDArray[np.floating]
    illuminance: NDArray[np.floating]


class SkyLike(Protocol):
    """What the capture needs from :class:`envcap.sky.sky.Sky`."""

    sun: SunLike | None

    def radiance(self, dirs: NDArray[np.floating]) -> NDArray[np.floating]: ...


def face_clip_matrix(face: int, near: float = 0.05, far: float = math.inf) -> NDArray[np.float64]:
    """4x4 matrix mapping ``(world - probe, 1)`` to GL clip space for cube face ``face``.

    NDC ``x = u = 2s - 1`` and ``y = v = 2t - 1`` (framebuffer row 0 = t near 0, so a readback
    needs no flip), ``w`` = distance along the face's major axis; depth maps ``near`` to -1 and
    ``far`` (``inf`` allowed: infinite projection) to +1.  Row-major (``M @ x``).
    """
    if not (0 < near < far):
        raise ValueError(f"need 0 < near < far, got near={near}, far={far}")
    r = _FACE_ROWS[face]
    m = np.zeros((4, 4))
    m[0, :3] = r[0]
    m[1, :3] = r[1]
    m[3, :3] = r[2]
    if math.isinf(far):
        a, b = 1.0, -2.0 * near
    else:
        a, b = (far + near) / (far - near), -2.0 * far * near / (far - near)
    m[2, :3] = a * r[2]
    m[2, 3] = b
    return m


def sh9_basis(d: NDArray[np.floating]) -> NDArray[np.float64]:
    """Real SH basis ``Y_lm`` (l <= 2) of unit directions ``d`` (..., 3) -> (..., 9), float64."""
    d = np.asarray(d, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    c0, c1, c2, c3, c4 = _SH_C
    return np.stack(
        [np.full_like(x, c0), c1 * y, c1 * z, c1 * x, c2 * x * y, c2 * y * z, c3 * (3 * z * z - 1), c2 * x * z,
         c4 * (x * x - y * y)],
        axis=-1,
    )


def sky_irradiance_sh(sky: SkyLike, n: int = 64) -> NDArray[np.float64]:
    """Irradiance SH coefficients ``E_lm = A_l L_lm``, shape ``(9, 3)``, of the sky dome.

    ``L_lm`` is the projection of ``sky.radiance`` (sun excluded: the sun is its own pass) over
    the upper hemisphere (directions with y < 0 contribute 0: ground bounce is ignored), summed
    over the texel centers of an ``n``-texel cube weighted by their exact solid angles.
    ``E(normal) = sum_lm E_lm Y_lm(normal)`` (:func:`sh9_basis`) is the irradiance of a surface.
    Raises ``ValueError`` if the sky radiance has the wrong shape or is not finite.
    """
    dirs = cube.texel_directions(n)
    w = cube.texel_solid_angles(n)
    rad = np.asarray(sky.radiance(dirs), dtype=np.float64)
    if rad.shape != dirs.shape:
        raise ValueError(f"sky.radiance returned shape {rad.shape}, expected {dirs.shape}")
    if not np.all(np.isfinite(rad)):
        raise ValueError("sky radiance contains NaN or Inf")
    rad = np.where(dirs[..., 1:2] >= 0.0, rad, 0.0)
    basis = sh9_basis(dirs)  # (6, n, n, 9)
    lm = np.einsum("fijk,fij,fijc->kc", basis, w, rad)
    return lm * _SH_A[:, None]


def _check_size(size: Any) -> int:
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
        raise ValueError(f"capture resolution must be an integer >= 1, got {size!r}")
    return int(size)


def _check_position(p: Any) -> NDArray[np.float64]:
    a = np.asarray(p, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"probe position must have shape (3,), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"probe position must be finite, got {a.tolist()}")
    return a


def probe_inside_geometry(backfacing: NDArray[np.bool_], threshold: float = 0.25) -> bool:
    """True when more than ``threshold`` of the sphere (solid-angle weighted) sees back faces.

    ``backfacing`` is ``(6, N, N)`` bool (:attr:`ProbeCapture.backfacing`).  Seen from inside a
    closed building every texel sees a back face (fraction 1); from outside, only meshes with
    wrong normals or open shells show any.
    """
    b = np.asarray(backfacing, dtype=bool)
    cube.check_cube(b[..., None], "backfacing")
    w = cube.texel_solid_angles(b.shape[1])
    return bool(np.sum(w * b) / (4.0 * math.pi) > threshold)


@dataclass
class ProbeCapture:
    """One captured probe.  Arrays per the module docstring; ``position`` (3,) meters."""

    position: NDArray[np.float64]
    rgba: NDArray[np.float32]
    distance: NDArray[np.float32]
    backfacing: NDArray[np.bool_]
    passes_run: list[str]
    pass_times_s: dict[str, float]
    draw_stats: dict[str, float] = field(default_factory=dict)
    """``cull_s`` (CPU seconds choosing chunks), ``triangles`` (drawn, summed over the six faces),
    ``draw_calls`` (summed over the faces)."""

    @property
    def inside_geometry(self) -> bool:
        return probe_inside_geometry(self.backfacing)


@dataclass
class CaptureSet:
    """Probes captured with one :class:`CubeCapture`: arrays with a leading probe axis ``P``.

    ``rgba`` (P, 6, N, N, 4), ``distance`` (P, 6, N, N), ``backfacing`` (P, 6, N, N),
    ``positions`` (P, 3).  ``pass_times_s`` sums each pass over the set (per-set passes once).
    """

    positions: NDArray[np.float64]
    rgba: NDArray[np.float32]
    distance: NDArray[np.float32]
    backfacing: NDArray[np.bool_]
    passes_run: list[str]
    pass_times_s: dict[str, float] = field(default_factory=dict)


def _light_basis(l: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows: right, up, back (= l) of an orthonormal light frame looking along -l."""
    helper = np.array([0.0, 1.0, 0.0]) if abs(l[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(helper, l)
    right /= np.linalg.norm(right)
    up = np.cross(l, right)
    return np.stack([right, up, l])


def light_clip_matrix(sun_dir: NDArray[np.floating], lo: NDArray[np.floating], hi: NDArray[np.floating],
                      margin: float = 1.0) -> tuple[NDArray[np.float64], float, float]:
    """Orthographic world -> light clip matrix fitted to the box ``[lo, hi]`` seen from the sun.

    Returns ``(matrix, extent_xy, depth_range)``: the larger side (m) of the square light-space
    window and the depth range (m) that maps to [-1, 1] (nearest the sun -> -1).  ``margin``
    meters pad every side so that flat boxes still have a non-zero depth range.
    """
    l = np.asarray(sun_dir, dtype=np.float64)
    l = l / np.linalg.norm(l)
    basis = _light_basis(l)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    e = corners @ basis.T
    emin, emax = e.min(axis=0) - margin, e.max(axis=0) + margin
    center = 0.5 * (emin + emax)
    half = 0.5 * max(emax[0] - emin[0], emax[1] - emin[1])
    depth = emax[2] - emin[2]
    m = np.zeros((4, 4))
    m[0, :3] = basis[0] / half
    m[0, 3] = -center[0] / half
    m[1, :3] = basis[1] / half
    m[1, 3] = -center[1] / half
    # z_ndc = -1 at the sun-most point (l . p = emax_z), +1 at the far side.
    m[2, :3] = -2.0 * basis[2] / depth
    m[2, 3] = 2.0 * emax[2] / depth - 1.0
    m[3, 3] = 1.0
    return m, 2.0 * half, depth


def _gl_mat(m: NDArray[np.floating]) -> bytes:
    # GLSL mat4 uniforms are column-major.
    return np.ascontiguousarray(np.asarray(m, dtype=np.float32).T).tobytes()


def face_clip_matrix_reversed(face: int, near: float = 0.05, far: float = math.inf) -> NDArray[np.float64]:
    """Like :func:`face_clip_matrix` but with reversed depth for ``glClipControl(.., ZERO_TO_ONE)``.

    ``x``, ``y``, ``w`` rows are those of :func:`face_clip_matrix`; NDC depth ``z / w`` is 1 at
    ``ma = near`` and 0 at ``ma = far`` (``inf``: ``z / w = near / ma``).  Stored in a float32
    depth buffer this keeps a relative precision of about 2^-24 in distance at every range
    (a 24-bit buffer with the standard mapping resolves only ~10 cm at 300 m).  Row-major.
    """
    if not (0 < near < far):
        raise ValueError(f"need 0 < near < far, got near={near}, far={far}")
    m = face_clip_matrix(face, near, far)
    r = _FACE_ROWS[face]
    if math.isinf(far):
        a, b = 0.0, near
    else:
        a, b = -near / (far - near), near * far / (far - near)
    m[2, :3] = a * r[2]
    m[2, 3] = b
    return m


class _DepthGL:
    """The raw GL calls moderngl 5.13 lacks for reversed depth: a float32 depth renderbuffer
    attached to a moderngl framebuffer, and ``glClipControl`` (core since OpenGL 4.5)."""

    GL_FRAMEBUFFER = 0x8D40
    GL_RENDERBUFFER = 0x8D41
    GL_DEPTH_ATTACHMENT = 0x8D00
    GL_DEPTH_COMPONENT32F = 0x8CAC
    GL_FRAMEBUFFER_COMPLETE = 0x8CD5
    GL_FRAMEBUFFER_BINDING = 0x8CA6
    GL_CLIP_ORIGIN = 0x935C
    GL_CLIP_DEPTH_MODE = 0x935D
    GL_ZERO_TO_ONE = 0x935F
    GL_LOWER_LEFT = 0x8CA1
    GL_DEPTH_FUNC = 0x0B74
    GL_GREATER = 0x0204

    def __init__(self) -> None:
        import ctypes

        from envcap.gpu.gl import load_gl_functions

        c = ctypes
        sig: dict[str, tuple[Any, tuple[Any, ...]]] = {
            "glClipControl": (None, (c.c_uint, c.c_uint)),
            "glDepthFunc": (None, (c.c_uint,)),
            "glGetIntegerv": (None, (c.c_uint, c.POINTER(c.c_int))),
            "glGenRenderbuffers": (None, (c.c_int, c.POINTER(c.c_uint))),
            "glDeleteRenderbuffers": (None, (c.c_int, c.POINTER(c.c_uint))),
            "glBindRenderbuffer": (None, (c.c_uint, c.c_uint)),
            "glRenderbufferStorage": (None, (c.c_uint, c.c_uint, c.c_int, c.c_int)),
            "glBindFramebuffer": (None, (c.c_uint, c.c_uint)),
            "glFramebufferRenderbuffer": (None, (c.c_uint, c.c_uint, c.c_uint, c.c_uint)),
            "glCheckFramebufferStatus": (c.c_uint, (c.c_uint,)),
        }
        for name, fn in load_gl_functions(sig).items():
            setattr(self, name, fn)
        self._c = c

    def get(self, pname: int) -> int:
        v = self._c.c_int(0)
        self.glGetIntegerv(pname, self._c.byref(v))
        return int(v.value)

    def attach_float_depth(self, fbo_glo: int, width: int, height: int) -> int:
        """Replace the depth attachment of framebuffer ``fbo_glo`` by a new DEPTH_COMPONENT32F
        renderbuffer; returns its name.  Raises ``RuntimeError`` if the result is incomplete."""
        c = self._c
        rb = c.c_uint(0)
        self.glGenRenderbuffers(1, c.byref(rb))
        self.glBindRenderbuffer(self.GL_RENDERBUFFER, rb.value)
        self.glRenderbufferStorage(self.GL_RENDERBUFFER, self.GL_DEPTH_COMPONENT32F, width, height)
        prev = self.get(self.GL_FRAMEBUFFER_BINDING)
        self.glBindFramebuffer(self.GL_FRAMEBUFFER, fbo_glo)
        self.glFramebufferRenderbuffer(self.GL_FRAMEBUFFER, self.GL_DEPTH_ATTACHMENT, self.GL_RENDERBUFFER, rb.value)
        status = self.glCheckFramebufferStatus(self.GL_FRAMEBUFFER)
        self.glBindFramebuffer(self.GL_FRAMEBUFFER, prev)
        self.glBindRenderbuffer(self.GL_RENDERBUFFER, 0)
        if status != self.GL_FRAMEBUFFER_COMPLETE:
            self.delete_renderbuffer(rb.value)
            raise RuntimeError(f"float32 depth framebuffer incomplete (status 0x{status:04X})")
        return int(rb.value)

    def delete_renderbuffer(self, name: int) -> None:
        rb = self._c.c_uint(name)
        self.glDeleteRenderbuffers(1, self._c.byref(rb))


@dataclass(frozen=True)
class TriangleChunks:
    """Triangles grouped into spatial chunks: contiguous ranges of a reordered index buffer.

    ``order`` (T,) int64: triangle ``k`` of the reordered buffer is input triangle ``order[k]``.
    ``first``, ``count`` (C,) int64: chunk ``c`` is reordered triangles ``first[c] ..
    first[c] + count[c] - 1``.  ``lo``, ``hi`` (C, 3) float64: the chunk's axis-aligned bounding
    box in meters (exact bounds of its float32 vertices).  Chunks are stored in the order of
    their keys (level, x cell, z cell); within a chunk triangles keep their input order.
    """

    order: NDArray[np.int64]
    first: NDArray[np.int64]
    count: NDArray[np.int64]
    lo: NDArray[np.float64]
    hi: NDArray[np.float64]


def chunk_triangles(positions: NDArray[np.floating], indices: NDArray[np.integer],
                    cell: float = 8.0) -> TriangleChunks:
    """Sort triangles into chunks of a loose grid in x-z with cells of ``cell`` meters.

    A triangle whose x-z extent is ``e`` goes to level ``k``, the smallest with
    ``e <= cell * 4**k``, and to the level-``k`` cell (side ``cell * 4**k``) holding its centroid;
    so a chunk's box is at most about twice its cell and a few huge triangles (a ground plane)
    do not inflate the boxes of the many small ones.  ``positions`` (V, 3), ``indices`` (T, 3).
    Raises ``ValueError`` for a non-finite or non-positive ``cell``.
    """
    if not (math.isfinite(cell) and cell > 0):
        raise ValueError(f"chunk cell size must be a finite number of meters > 0, got {cell!r}")
    pos = np.asarray(positions, dtype=np.float64)
    tri = pos[np.asarray(indices, dtype=np.int64)]  # (T, 3, 3)
    t = tri.shape[0]
    if t == 0:
        z = np.zeros(0, np.int64)
        return TriangleChunks(z, z, z, np.zeros((0, 3)), np.zeros((0, 3)))
    tlo, thi = tri.min(axis=1), tri.max(axis=1)
    ext = np.maximum(thi[:, 0] - tlo[:, 0], thi[:, 2] - tlo[:, 2])
    level = np.zeros(t, np.int64)
    big = ext > cell
    level[big] = np.ceil(np.log(ext[big] / cell) / math.log(4.0) - 1e-12).astype(np.int64)
    level = np.maximum(level, 0)
    while True:  # guard the float log against landing one level short
        short = ext > cell * 4.0 ** level
        if not short.any():
            break
        level[short] += 1
    size = cell * 4.0 ** level
    cen = 0.5 * (tlo + thi)
    ix = np.floor(cen[:, 0] / size).astype(np.int64)
    iz = np.floor(cen[:, 2] / size).astype(np.int64)
    order = np.lexsort((np.arange(t), iz, ix, level))  # stable: input order within a chunk
    keys = np.stack([level[order], ix[order], iz[order]], axis=1)
    new = np.ones(t, bool)
    new[1:] = np.any(keys[1:] != keys[:-1], axis=1)
    first = np.flatnonzero(new).astype(np.int64)
    count = np.diff(np.append(first, t)).astype(np.int64)
    lo = np.minimum.reduceat(tlo[order], first, axis=0)
    hi = np.maximum.reduceat(thi[order], first, axis=0)
    return TriangleChunks(order.astype(np.int64), first, count, lo, hi)


def _face_planes() -> NDArray[np.float64]:
    """(6, 4, 3) inward normals of each face frustum's side planes: ``n . r >= 0`` inside."""
    r = _FACE_ROWS
    return np.stack([r[:, 2] - r[:, 0], r[:, 2] + r[:, 0], r[:, 2] - r[:, 1], r[:, 2] + r[:, 1]], axis=1)


_SIDE_PLANES = _face_planes()


def chunk_face_visibility(lo: NDArray[np.floating], hi: NDArray[np.floating], probe: NDArray[np.floating],
                          near: float = 0.05, far: float = math.inf) -> NDArray[np.bool_]:
    """Which boxes ``[lo, hi]`` (C, 3) meters may reach each cube face's frustum: (6, C) bool.

    Face ``f`` sees ``r = x - probe`` where ``ma >= |sc|``, ``ma >= |tc|`` and
    ``near <= ma <= far`` (``(sc, tc, ma) = R_f r``, as :func:`face_clip_matrix`).  A box is
    rejected only when it lies wholly outside one of these planes, tested at its corner farthest
    along the plane's inward normal, with a margin of ``1e-5`` of the box's distance scale (plus
    1 micrometer) so that float32 rounding on the GPU can never make a rejected box produce a
    fragment.  Conservative: a box kept may still draw nothing.
    """
    p = np.asarray(probe, dtype=np.float64)
    blo = np.asarray(lo, dtype=np.float64) - p
    bhi = np.asarray(hi, dtype=np.float64) - p
    scale = np.maximum(np.abs(blo), np.abs(bhi)).sum(axis=1)  # (C,) >= |r| over the box
    eps = 1e-5 * scale + 1e-6
    n = _SIDE_PLANES  # (6, 4, 3)
    # max over the box of n . r = sum_i max(n_i lo_i, n_i hi_i)
    reach = np.maximum(n[None] * blo[:, None, None, :], n[None] * bhi[:, None, None, :]).sum(axis=-1)  # (C, 6, 4)
    vis = np.all(reach >= -eps[:, None, None], axis=2)  # (C, 6)
    ma = _FACE_ROWS[:, 2]  # (6, 3)
    ma_max = np.maximum(ma[None] * blo[:, None, :], ma[None] * bhi[:, None, :]).sum(axis=-1)  # (C, 6)
    vis &= ma_max >= near - eps[:, None]
    if math.isfinite(far):
        ma_min = np.minimum(ma[None] * blo[:, None, :], ma[None] * bhi[:, None, :]).sum(axis=-1)
        vis &= ma_min <= far + eps[:, None]
    return vis.T


def _box_far_distance(lo: NDArray[np.float64], hi: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance (m) from ``p`` to the farthest corner of each box, (C,): the draw-order key.

    Ordering by it draws small nearby chunks first and big boxes (the ground, long facades with
    details 1.5 cm in front of them) late, which lets the early depth test reject more hidden
    fragments than ordering by the nearest point (measured: 1.32 vs 1.55 shaded fragments per
    visible texel on canyon; 1.41 in buffer order).
    """
    d = np.maximum(np.abs(lo - p), np.abs(hi - p))
    return np.sqrt(np.einsum("ci,ci->c", d, d))


def _runs(ids: NDArray[np.int64], first: NDArray[np.int64],
          count: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Merge chunks drawn in the order ``ids`` into draw ranges (first triangles, triangle counts):
    a chunk that directly follows the previous one in the buffer extends its range."""
    if ids.size == 0:
        z = np.zeros(0, np.int64)
        return z, z
    brk = np.ones(ids.size, bool)
    brk[1:] = ids[1:] != ids[:-1] + 1
    starts = np.flatnonzero(brk)
    ends = np.append(starts[1:], ids.size) - 1
    f0 = first[ids[starts]]
    return f0, first[ids[ends]] + count[ids[ends]] - f0


class CubeCapture:
    """Captures HDR cube probes of one scene mesh at many positions (see the module docstring).

    Parameters
    ----------
    mesh:
        The scene geometry (uploaded once).
    size:
        Face resolution ``N`` (integer >= 1).
    sky:
        An :class:`envcap.sky.sky.Sky` (or anything with ``sun`` and ``radiance(dirs)``); needed by
        ``sun_light`` (its ``sun``) and ``sky_light`` (its ``radiance``).  ``None`` means no sky:
        the sun and sky terms are then not compiled in.
    effects:
        Subset of :data:`envcap.scene.model.EFFECTS`; each runs only when listed.
    ctx:
        A moderngl context (OpenGL >= 4.3); default: a new headless one (released by
        :meth:`release`).
    near, far:
        Clip distances along each face's axis in meters; ``far = inf`` is an infinite
        projection.  Distances are written from the fragment shader in float32 (not rebuilt
        from depth), so ``far`` does not limit their accuracy.
    shadow_resolution, shadow_bounds:
        Shadow-map size in texels (square) and the world box ``(lo (3,), hi (3,))`` it covers
        (default: the mesh bounds).
    sh_resolution:
        Cube face size on which the sky's radiance is projected to SH.
    cull_chunks:
        Draw, for each face, only the triangle chunks whose box reaches that face's frustum,
        near chunks first (:func:`chunk_triangles`, :func:`chunk_face_visibility`).  The output
        is the same as with ``False`` (every triangle drawn for every face, one draw call), only
        faster; ``False`` is the simple reference path.
    chunk_size:
        Cell size in meters of the chunk grid (x-z), used when ``cull_chunks``.
    """

    def __init__(self, mesh: SceneMesh, size: int, *, sky: SkyLike | None = None,
                 effects: Iterable[str] = (), ctx: Any = None, near: float = 0.05, far: float = math.inf,
                 shadow_resolution: int = 2048,
                 shadow_bounds: tuple[Sequence[float], Sequence[float]] | None = None,
                 sh_resolution: int = 64, cull_chunks: bool = True, chunk_size: float = 8.0) -> None:
        self.size = _check_size(size)
        effects = frozenset(effects)
        unknown = sorted(effects - set(EFFECTS))
        if unknown:
            raise ValueError(f"unknown effect(s) {unknown}; known: {list(EFFECTS)}")
        if "sun_shadows" in effects and "sun_light" not in effects:
            raise ValueError("effect 'sun_shadows' needs 'sun_light'")
        if not (math.isfinite(near) and 0 < near < far):
            raise ValueError(f"need 0 < near < far, got near={near}, far={far}")
        shadow_resolution = _check_size(shadow_resolution)
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(chunk_size) and chunk_size > 0):
            raise ValueError(f"chunk cell size must be a finite number of meters > 0, got {chunk_size!r}")
        self.mesh = mesh
        self.cull_chunks = bool(cull_chunks)
        self.near, self.far = float(near), float(far)
        self.effects = effects
        self.sky = sky
        self._own_ctx = ctx is None
        if ctx is None:
            from envcap.gpu.gl import create_context

            ctx = create_context()
        self.ctx = ctx
        max_size = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
        if 3 * self.size > max_size:
            raise ValueError(f"capture resolution {self.size} too large: 3 x {self.size} exceeds GL_MAX_TEXTURE_SIZE {max_size}")
        if shadow_resolution > max_size:
            raise ValueError(f"shadow_resolution {shadow_resolution} exceeds GL_MAX_TEXTURE_SIZE {max_size}")

        sun = getattr(sky, "sun", None) if sky is not None else None
        sun_ok = sun is not None and np.all(np.isfinite(sun.direction)) and np.linalg.norm(sun.direction) > 0 \
            and np.all(np.isfinite(sun.illuminance))
        if sun is not None and not sun_ok:
            raise ValueError("sky.sun has a zero or non-finite direction or illuminance")
        self.applied: frozenset[str] = frozenset(
            e for e in effects
            if e == "emissive_windows"
            or (e in ("sun_light", "sun_shadows") and sun_ok)
            or (e == "sky_light" and sky is not None)
        )
        has_tris = mesh.triangle_count > 0
        if not has_tris:
            self.applied = self.applied - {"sun_shadows"}  # nothing can cast a shadow
        self.passes_run: list[str] = []
        self.pass_times_s: dict[str, float] = {}

        defines = {k.upper(): 1 for k in sorted(self.applied)}
        self._prog = ctx.program(vertex_shader=shader_source("capture_vert.glsl"),
                                 fragment_shader=shader_source("capture_frag.glsl", defines or None))
        self._vao = None
        self._vbo = self._ibo = self._indirect = None
        self.chunks = None
        if has_tris:
            data = np.concatenate([mesh.positions, mesh.normals, mesh.albedo, mesh.emission], axis=1)
            self._vbo = ctx.buffer(np.ascontiguousarray(data, dtype=np.float32).tobytes())
            # Triangles reordered into spatial chunks (contiguous index ranges); both paths draw
            # this buffer, so the culled path draws a subset of the same triangles.
            self.chunks: TriangleChunks | None = chunk_triangles(mesh.positions, mesh.indices, chunk_size)
            idx = mesh.indices[self.chunks.order]
            self._ibo = ctx.buffer(np.ascontiguousarray(idx, dtype=np.uint32).tobytes())
            # Indirect draw commands, 20 bytes each, at most one per chunk and face.
            self._indirect = ctx.buffer(reserve=20 * 6 * max(int(self.chunks.first.size), 1))
            # Attributes that a shader variant does not use are optimized away: skip their bytes.
            names = [a for a in ("in_position", "in_normal", "in_albedo", "in_emission")
                     if self._prog.get(a, None) is not None]
            fmt = " ".join("3f" if self._prog.get(a, None) is not None else "12x"
                           for a in ("in_position", "in_normal", "in_albedo", "in_emission"))
            self._vao = ctx.vertex_array(self._prog, [(self._vbo, fmt, *names)],
                                         index_buffer=self._ibo, index_element_size=4)
        n = self.size
        self._color = ctx.texture((3 * n, 2 * n), 4, dtype="f4")
        self._depth = ctx.depth_renderbuffer((3 * n, 2 * n))
        self._fbo = ctx.framebuffer([self._color], self._depth)
        # Reversed depth in a float32 buffer (face_clip_matrix_reversed): the 24-bit buffer that
        # moderngl makes cannot separate a window from its wall (1.5 cm) beyond ~110 m.
        self._gl = _DepthGL()
        self._depth32 = self._gl.attach_float_depth(self._fbo.glo, 3 * n, 2 * n)
        self._face_mats = [_gl_mat(face_clip_matrix_reversed(f, self.near, self.far)) for f in range(6)]
        self._shadow_tex = self._shadow_fbo = None
        self._shadow_objs: list[Any] = []

        if "sun_light" in self.applied:
            l = np.asarray(sun.direction, dtype=np.float64)
            self._prog["sun_dir"].value = tuple((l / np.linalg.norm(l)).astype(np.float32))
            self._prog["sun_E"].value = tuple(np.asarray(sun.illuminance, dtype=np.float32).reshape(3))
        if "sky_light" in self.applied:
            t0 = time.perf_counter()
            self.sky_sh = sky_irradiance_sh(sky, _check_size(sh_resolution))
            self._prog["sky_sh"].write(self.sky_sh.astype(np.float32).tobytes())
            self._record("sky_sh", time.perf_counter() - t0)
        if "sun_shadows" in self.applied:
            self._render_shadow_map(np.asarray(sun.direction, dtype=np.float64), shadow_resolution, shadow_bounds)

    # -- per-set passes ---------------------------------------------------------------------------
    def _record(self, name: str, seconds: float) -> None:
        if name not in self.passes_run:
            self.passes_run.append(name)
        self.pass_times_s[name] = self.pass_times_s.get(name, 0.0) + seconds

    def _render_shadow_map(self, sun_dir: NDArray[np.float64], res: int,
                           bounds: tuple[Sequence[float], Sequence[float]] | None) -> None:
        t0 = time.perf_counter()
        ctx = self.ctx
        if bounds is None:
            lo, hi = self.mesh.positions.min(axis=0).astype(np.float64), self.mesh.positions.max(axis=0).astype(np.float64)
        else:
            lo, hi = np.asarray(bounds[0], np.float64), np.asarray(bounds[1], np.float64)
            if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite([lo, hi])) or np.any(hi < lo):
                raise ValueError(f"shadow_bounds must be finite (lo (3,), hi (3,)) with lo <= hi, got {bounds}")
        m, extent, depth_range = light_clip_matrix(sun_dir, lo, hi)
        self.shadow_texel_m = extent / res
        self.shadow_resolution = res
        prog = ctx.program(vertex_shader=shader_source("shadow_vert.glsl"),
                           fragment_shader=shader_source("shadow_frag.glsl"))
        prog["light_clip"].write(_gl_mat(m))
        vao = ctx.vertex_array(prog, [(self._vbo, "3f 36x", "in_position")],
                               index_buffer=self._ibo, index_element_size=4)
        tex = ctx.depth_texture((res, res))
        fbo = ctx.framebuffer(depth_attachment=tex)
        fbo.use()
        fbo.viewport = (0, 0, res, res)
        fbo.clear(depth=1.0)
        ctx.disable(ctx.CULL_FACE)
        ctx.enable(ctx.DEPTH_TEST)
        vao.render()
        ctx.finish()
        tex.compare_func = "<="
        import moderngl

        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = False
        self._shadow_tex, self._shadow_fbo = tex, fbo
        self._shadow_objs = [prog, vao, fbo, tex]
        p = self._prog
        p["light_clip"].write(_gl_mat(m))
        p["shadow_texel"].value = 1.0 / res
        # Bias (docs/capture.md): receivers move 1.5 shadow texels along their normal; depth bias
        # of half a texel plus one texel per unit tan(incidence), in depth units.
        p["shadow_normal_offset"].value = 1.5 * self.shadow_texel_m
        p["shadow_bias_const"].value = 0.5 * self.shadow_texel_m / depth_range
        p["shadow_bias_slope"].value = 1.0 * self.shadow_texel_m / depth_range
        p["shadow_map"].value = 0
        self._record("shadow_map", time.perf_counter() - t0)

    # -- per-probe passes -------------------------------------------------------------------------
    def capture(self, position: Sequence[float]) -> ProbeCapture:
        """Capture the probe at ``position`` (3,) meters; see the module docstring for outputs."""
        p = _check_position(position)
        n = self.size
        rgba = np.empty((6, n, n, 4), dtype=np.float32)
        distance = np.empty((6, n, n), dtype=np.float32)
        backfacing = np.empty((6, n, n), dtype=bool)
        times, stats = self._capture_into(p, rgba, distance, backfacing)
        return ProbeCapture(position=p, rgba=rgba, distance=distance, backfacing=backfacing,
                            passes_run=self.passes_run + ["render", "readback"],
                            pass_times_s={**self.pass_times_s, **times}, draw_stats=stats)

    def _capture_into(self, p: NDArray[np.float64], rgba: NDArray[np.float32], distance: NDArray[np.float32],
                      backfacing: NDArray[np.bool_]) -> tuple[dict[str, float], dict[str, float]]:
        """Render the probe at ``p`` and write its outputs into the given (C-contiguous) arrays.

        Writing straight into the caller's arrays matters for :meth:`capture_many`: a copy into
        fresh output memory costs its page faults a second time (measured 3-10 ms per 6 x 256^2
        probe here).  Returns (pass seconds, draw stats).
        """
        n = self.size
        ctx = self.ctx
        stats = {"cull_s": 0.0, "triangles": 0.0, "draw_calls": 0.0}
        draws = self._face_draws(p, stats)  # CPU time in stats["cull_s"], not in "render"
        t0 = time.perf_counter()
        self._fbo.use()
        self._fbo.viewport = (0, 0, 3 * n, 2 * n)
        self._fbo.clear(0.0, 0.0, 0.0, 0.0, depth=0.0)  # reversed depth: 0 is infinitely far
        if self._vao is not None:
            gl = self._gl
            saved = (gl.get(gl.GL_CLIP_ORIGIN), gl.get(gl.GL_CLIP_DEPTH_MODE), gl.get(gl.GL_DEPTH_FUNC))
            gl.glClipControl(gl.GL_LOWER_LEFT, gl.GL_ZERO_TO_ONE)
            gl.glDepthFunc(gl.GL_GREATER)
            try:
                ctx.enable(ctx.DEPTH_TEST)
                ctx.disable(ctx.CULL_FACE)  # both sides: back faces are seen (and marked) from inside buildings
                ctx.disable(ctx.BLEND)
                self._prog["probe"].value = tuple(p.astype(np.float32))
                if self._shadow_tex is not None:
                    self._shadow_tex.use(0)
                for f in range(6):
                    if draws is not None and draws[f][1] == 0:
                        continue
                    self._fbo.viewport = ((f % 3) * n, (f // 3) * n, n, n)
                    self._prog["face_clip"].write(self._face_mats[f])
                    if draws is None:
                        self._vao.render()
                    else:  # one multi-draw per face (glMultiDrawElementsIndirect)
                        self._vao.render_indirect(self._indirect, count=draws[f][1], first=draws[f][0])
            finally:
                gl.glClipControl(saved[0], saved[1])  # leave the context as found
                gl.glDepthFunc(saved[2])
            ctx.finish()
        t1 = time.perf_counter()
        # Read each face's n x n block straight into its slot of (6, N, N, 4): no transpose copy.
        for f in range(6):
            self._fbo.read_into(rgba[f], viewport=((f % 3) * n, (f // 3) * n, n, n), components=4, dtype="f4")
        t2 = time.perf_counter()
        signed = rgba[..., 3]
        np.abs(signed, out=distance)
        np.less(signed, 0.0, out=backfacing)
        # RGB is already 0 where alpha is: the clear value, since every fragment writes |alpha| =
        # its distance >= near > 0 (it lies in the frustum, ma >= near), so a miss was never drawn.
        np.not_equal(distance, 0.0, out=rgba[..., 3], casting="unsafe")
        return {"render": t1 - t0, "readback": t2 - t1}, stats

    def _face_draws(self, p: NDArray[np.float64], stats: dict[str, float]) -> list[tuple[int, int]] | None:
        """Cull and order chunks for the probe at ``p``; write the draw ranges as indirect draw
        commands (count, 1, first index, 0, 0) into ``self._indirect``.  Returns per face
        (first command, number of commands); ``None``: draw everything."""
        ch = self.chunks
        if ch is None:
            return [(0, 0)] * 6
        if not self.cull_chunks:
            stats["triangles"], stats["draw_calls"] = 6.0 * int(ch.count.sum()), 6.0
            return None
        t0 = time.perf_counter()
        vis = chunk_face_visibility(ch.lo, ch.hi, p, self.near, self.far)  # (6, C)
        dist = _box_far_distance(ch.lo, ch.hi, p)
        cmds, faces, k = [], [], 0
        for f in range(6):
            ids = np.flatnonzero(vis[f])
            ids = ids[np.argsort(dist[ids], kind="stable")]  # near first: early depth rejects the rest
            f0, cnt = _runs(ids, ch.first, ch.count)
            c = np.zeros((f0.size, 5), np.uint32)
            c[:, 0], c[:, 1], c[:, 2] = 3 * cnt, 1, 3 * f0
            cmds.append(c)
            faces.append((k, int(f0.size)))
            k += int(f0.size)
            stats["triangles"] += float(cnt.sum())
        stats["draw_calls"] = float(k)
        if k:
            self._indirect.write(np.concatenate(cmds).tobytes())
        stats["cull_s"] = time.perf_counter() - t0
        return faces

    def capture_many(self, positions: NDArray[np.floating], progress: bool = True) -> CaptureSet:
        """Capture probes at ``positions`` (P, 3) meters, with a tqdm bar when on a TTY."""
        from tqdm import tqdm

        pos = np.asarray(positions, dtype=np.float64)
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise ValueError(f"probe positions must have shape (P, 3), got {pos.shape}")
        for q in pos:
            _check_position(q)
        n, count = self.size, pos.shape[0]
        out = CaptureSet(positions=pos, rgba=np.empty((count, 6, n, n, 4), np.float32),
                         distance=np.empty((count, 6, n, n), np.float32),
                         backfacing=np.empty((count, 6, n, n), bool),
                         passes_run=list(self.passes_run) + ["render", "readback"],
                         pass_times_s=dict(self.pass_times_s))
        for i in tqdm(range(count), desc="capture", unit="probe", disable=None if progress else True):
            times, _ = self._capture_into(pos[i], out.rgba[i], out.distance[i], out.backfacing[i])
            for k in ("render", "readback"):
                out.pass_times_s[k] = out.pass_times_s.get(k, 0.0) + times[k]
        return out

    @classmethod
    def from_scene(cls, scene: Scene, size: int, *, sky: SkyLike | None = None, ctx: Any = None,
                   **kwargs: Any) -> "CubeCapture":
        """A capture of ``scene`` with its effects; ``sky`` defaults to ``envcap.sky.sky.sky_from_spec``."""
        if sky is None and scene.effects & {"sun_light", "sky_light"}:
            from envcap.sky.sky import sky_from_spec

            sky = sky_from_spec(scene.sky, scene.base_dir)
        return cls(scene.mesh, size, sky=sky, effects=scene.effects, ctx=ctx, **kwargs)

    def release(self) -> None:
        """Free the GL objects (and the context if this capture created it)."""
        for o in [self._vao, self._vbo, self._ibo, self._indirect, self._fbo, self._color, self._depth, self._prog, *self._shadow_objs]:
            if o is not None:
                o.release()
        if self._depth32:
            self._gl.delete_renderbuffer(self._depth32)
            self._depth32 = 0
        self._vao = None
        self._shadow_objs = []
        if self._own_ctx:
            self.ctx.release()

    def __enter__(self) -> "CubeCapture":
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
