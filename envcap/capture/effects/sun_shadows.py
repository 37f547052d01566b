"""``sun_shadows``: occlusion of the sun with a shadow map (needs ``sun_light``), with cascades
that follow the probe when one map cannot hold the asked texel.

* Needs: the sky's sun and a mesh with triangles (nothing else can cast a shadow); requires
  ``sun_light``, whose sun term it multiplies by the visibility ``sun_visibility``
  (``shaders/capture/shadow_lookup.glsl``).
* Parameters: ``resolution`` (default 2048) shadow-map texels per side (square);
  ``bounds`` (default ``None``: the mesh bounds) the world box ``(lo (3,), hi (3,))`` meters it
  covers, padded 1 m (:func:`envcap.capture.projection.light_clip_matrix`); the map's depth
  still reaches every mesh vertex toward the sun, so geometry outside the box casts into it;
  ``texel_m`` (default ``None``) the texel size to reach: the resolution becomes
  ``ceil(window / texel_m)``.  When that is more than ``max_resolution`` (default 8192, and at
  most ``GL_MAX_TEXTURE_SIZE``) the map becomes **cascades** (:func:`plan_shadow_map`):
  ``cascade_resolution``-square maps (default 2048) of texels ``texel_m * 4^k`` around the
  probe, redrawn when the probe leaves their tile, and the whole window as the last, coarse
  cascade; more than :data:`MAX_CASCADES` cascades or an atlas past :data:`ATLAS_BYTES_LIMIT`
  is a clear error.  The light frustum is fitted relative to the mesh origin
  (``EffectInputs.origin``), like the vertices it draws.  Reports ``facts["texel_m"]`` (the
  finest texel, m), ``facts["resolution"]`` and, with cascades, ``facts["cascades"]`` and
  ``facts["cascade<k>_texel_m"]``.
* Per-set pass ``shadow_map``: the mesh drawn depth-only (24-bit) into an orthographic
  light-space map (with cascades: into the coarse cell of an atlas; the fine cells are drawn
  per probe when their tile changes, timed under the same pass).  Points outside the map are lit.
* Uniforms: ``shadow_map`` (compare sampler), ``light_clip`` (origin-relative -> light clip),
  ``shadow_texel`` (1 / resolution) and the bias: receivers move 1.5 shadow texels along their
  normal (``shadow_normal_offset``, m); depth bias of half a texel (``shadow_bias_const``) plus
  one texel per unit tan(incidence) (``shadow_bias_slope``), in depth units (docs/capture.md);
  ``shadow_cascades`` (0: single map) and the per-cascade ``shadow_cascade_uv``,
  ``shadow_cascade_cell``, ``shadow_cascade_bias`` (the same bias rule at each cascade's
  texel) and ``shadow_atlas_texel``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import moderngl
import numpy as np
from numpy.typing import NDArray

from envcap.capture.effects.base import CaptureEffect, EffectInputs, EffectParameter, EffectSetup, positive_int
from envcap.capture.projection import light_clip_matrix
from envcap.core.resources import shader_source
from envcap.gpu.uniforms import set_uniforms

CASCADE_RATIO = 4
"""Texel ratio between consecutive fine cascades."""
MAX_CASCADES = 5
"""Most cascades (fine ones and the coarse one) a map may need; the shader holds up to 8."""
CASCADE_GAP = 2
"""Texels between atlas cells, cleared to the far depth (lit): the coarse cell's PCF reads them."""
ATLAS_BYTES_LIMIT = 1 << 30
"""Largest cascade atlas (bytes, 4 per texel)."""
DEFAULT_MAX_RESOLUTION = 8192
"""Largest single map side (texels) before cascades (256 MiB)."""


@dataclass(frozen=True)
class ShadowPlan:
    """The maps a ``sun_shadows`` capture draws.

    ``extent_m``: side (m) of the whole light-space window; ``resolution``: the single map's
    side, or each cascade's (texels); ``texels_m``: texel size (m) of each map, finest first
    (one entry: a single map; else the fine cascades ``texel_m * 4^k`` and the coarse one
    ``extent_m / resolution``); ``atlas``: the depth texture's (width, height) texels and
    ``cells`` each map's first texel in it (cascade k, coarse last).
    """

    extent_m: float
    resolution: int
    texels_m: tuple[float, ...]
    atlas: tuple[int, int]
    cells: tuple[tuple[int, int], ...]

    @property
    def cascades(self) -> int:
        """Number of cascades, 0 for a single map."""
        return len(self.texels_m) if len(self.texels_m) > 1 else 0

    @property
    def bytes(self) -> int:
        """GPU memory of the depth texture (4 bytes per texel)."""
        return 4 * self.atlas[0] * self.atlas[1]

    def describe(self) -> str:
        """One line: texel(s), sizes, memory."""
        mib = self.bytes / 2**20
        if not self.cascades:
            return f"one {self.resolution}^2 shadow map, {self.texels_m[0]:.4g} m texels, {mib:.0f} MiB"
        texels = ", ".join(f"{t:.4g}" for t in self.texels_m)
        return (f"{self.cascades} shadow cascades of {self.resolution}^2 (texels {texels} m over a "
                f"{self.extent_m:.0f} m window), {mib:.0f} MiB")


def plan_shadow_map(extent_m: float, *, resolution: int = 2048, texel_m: float | None = None,
                    max_resolution: int = DEFAULT_MAX_RESOLUTION, cascade_resolution: int = 2048,
                    max_texture_size: int = 16384) -> ShadowPlan:
    """The maps for a light-space window of side ``extent_m`` (m): one ``resolution`` map when
    ``texel_m`` is ``None``; else one map of ``ceil(extent_m / texel_m)`` texels when that is at
    most ``min(max_resolution, max_texture_size)``, and cascades otherwise: fine levels of
    texel ``texel_m * 4^k`` for every k with ``texel_m * 4^k <= extent_m / (2 R)`` (at least
    twice finer than the coarse map), ``R = min(cascade_resolution, limit // 2)``, then the
    coarse map of the whole window at ``extent_m / R``.  Raises ``ValueError`` (one line, with
    the numbers) past ``GL_MAX_TEXTURE_SIZE``, :data:`MAX_CASCADES` or :data:`ATLAS_BYTES_LIMIT`."""
    if texel_m is None:
        if resolution > max_texture_size:
            raise ValueError(f"sun_shadows resolution {resolution} exceeds GL_MAX_TEXTURE_SIZE {max_texture_size}")
        return ShadowPlan(extent_m, resolution, (extent_m / resolution,), (resolution, resolution), ((0, 0),))
    need = math.ceil(extent_m / texel_m) if extent_m / texel_m < 2.0**53 else math.inf   # texels per side
    limit = min(max_resolution, max_texture_size)
    if need <= limit:
        res = int(need)
        return ShadowPlan(extent_m, res, (extent_m / res,), (res, res), ((0, 0),))
    r = max(16, min(cascade_resolution, limit // 2))
    fine = [texel_m * CASCADE_RATIO ** k for k in range(64) if texel_m * CASCADE_RATIO ** k <= extent_m / (2 * r)]
    texels = (*fine, extent_m / r)
    if len(texels) > MAX_CASCADES:
        raise ValueError(f"sun_shadows: a texel of {texel_m:g} m over a {extent_m:.1f} m window needs {need:.0f} texels, "
                         f"past the single-map limit {limit}, and {len(texels)} cascades of {r}^2, more than "
                         f"{MAX_CASCADES}: fit a smaller box (bounds), a larger texel or a larger cascade_resolution")
    per_row = max(1, (max_texture_size + CASCADE_GAP) // (r + CASCADE_GAP))
    rows = -(-len(texels) // per_row)
    cols = min(per_row, len(texels))
    atlas = (cols * (r + CASCADE_GAP) - CASCADE_GAP, rows * (r + CASCADE_GAP) - CASCADE_GAP)
    cells = tuple(((k % per_row) * (r + CASCADE_GAP), (k // per_row) * (r + CASCADE_GAP)) for k in range(len(texels)))
    plan = ShadowPlan(extent_m, r, texels, atlas, cells)
    if atlas[1] > max_texture_size or plan.bytes > ATLAS_BYTES_LIMIT:
        raise ValueError(f"sun_shadows: {plan.describe()}: past GL_MAX_TEXTURE_SIZE {max_texture_size} or "
                         f"{ATLAS_BYTES_LIMIT >> 20} MiB: use a smaller cascade_resolution or a larger texel")
    return plan


def _check_bounds(bounds: Any) -> tuple[np.ndarray, np.ndarray] | None:
    if bounds is None:
        return None
    try:
        lo, hi = np.asarray(bounds[0], np.float64), np.asarray(bounds[1], np.float64)
    except (TypeError, ValueError, IndexError):
        lo = hi = np.zeros(0)
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite([lo, hi])) or np.any(hi < lo):
        raise ValueError("sun_shadows parameter 'bounds' must be finite (lo (3,), hi (3,)) with lo <= hi, "
                         f"got {bounds}")
    return lo, hi


def _check_texel(value: Any) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value > 0):
        raise ValueError(f"sun_shadows parameter 'texel_m' must be a positive number of meters, got {value!r}")
    return float(value)


def _bias(texel_m: float, depth_range: float) -> tuple[float, float, float]:
    """(normal offset m, constant depth bias, slope depth bias) for a map of ``texel_m``."""
    return 1.5 * texel_m, 0.5 * texel_m / depth_range, 1.0 * texel_m / depth_range


class _Atlas:
    """The depth texture, the depth-only program and the draw of one cell."""

    def __init__(self, inputs: EffectInputs, plan: ShadowPlan) -> None:
        ctx = self.ctx = inputs.ctx
        self.prog = ctx.program(vertex_shader=shader_source("capture/shadow_vert.glsl"),
                                fragment_shader=shader_source("capture/shadow_frag.glsl"))
        self.vao = ctx.vertex_array(self.prog, [(inputs.vertex_buffer, "3f 36x", "in_position")],
                                    index_buffer=inputs.index_buffer, index_element_size=4)
        self.tex = ctx.depth_texture(plan.atlas)
        self.fbo = ctx.framebuffer(depth_attachment=self.tex)
        self.size = plan.resolution

    def draw(self, clip: NDArray[np.float64], cell: tuple[int, int] = (0, 0), clear_all: bool = False) -> None:
        """Draw the mesh with ``clip`` (row-major light clip matrix) into the cell at ``cell``."""
        ctx = self.ctx
        set_uniforms(self.prog, {"light_clip": clip.T})  # GLSL matrices are column-major
        self.fbo.use()
        view = (cell[0], cell[1], self.size, self.size)
        self.fbo.clear(depth=1.0, viewport=None if clear_all else view)
        self.fbo.viewport = view
        ctx.disable(ctx.CULL_FACE)
        ctx.enable(ctx.DEPTH_TEST)
        self.vao.render()


class _FollowingCascades:
    """``EffectSetup.per_probe`` of cascades: per fine level k (texel ``t_k``, window
    ``W = R t_k``), the light-space plane is tiled in squares of ``W / 2``; the probe's tile,
    grown by ``W / 4`` on every side, is the window, drawn anew when the tile changes."""

    def __init__(self, atlas: _Atlas, plan: ShadowPlan, m: NDArray[np.float64], uv: NDArray[np.float64]) -> None:
        half = 0.5 * plan.extent_m
        self.atlas, self.plan, self.m, self.uv = atlas, plan, m, uv
        self.axes = m[:2, :3] * half                 # light-space right, up (unit rows)
        self.lower = -m[:2, 3] * half - half          # light-space coordinates (m) of the window's corner
        self.tiles: list[tuple[int, int] | None] = [None] * (len(plan.texels_m) - 1)

    def __call__(self, local: NDArray[np.float64]) -> dict[str, Any]:
        plan, e = self.plan, self.plan.extent_m
        q = self.axes @ np.asarray(local, np.float64)
        changed = False
        for k, tile in enumerate(self.tiles):
            w = plan.resolution * plan.texels_m[k]
            now = (int(math.floor(q[0] / (0.5 * w))), int(math.floor(q[1] / (0.5 * w))))
            if now == tile:
                continue
            corner = np.array(now, np.float64) * (0.5 * w) - 0.25 * w       # window corner, light m
            o, s = (corner - self.lower) / e, e / w                           # in [0, 1] of light_clip
            self.uv[k] = (s, s, -o[0] * s, -o[1] * s)
            clip = self.m.copy()
            clip[:2] *= s
            clip[:2, 3] += s * (1.0 - 2.0 * o) - 1.0
            self.atlas.draw(clip, plan.cells[k])
            self.tiles[k] = now
            changed = True
        return {"shadow_cascade_uv": self.uv.astype(np.float32)} if changed else {}


def _defines(params: Mapping[str, Any]) -> dict[str, object]:
    """The cascade lookup is compiled in only when a texel size is asked (the only case that can
    need cascades): without it the shader is the single map's alone."""
    return {"SUN_SHADOW_CASCADES": 1} if params["texel_m"] is not None else {}


def _prepare(inputs: EffectInputs, params: Mapping[str, Any]) -> EffectSetup:
    bounds: Sequence[np.ndarray] | None = params["bounds"]
    mesh_lo, mesh_hi = inputs.positions.min(axis=0).astype(np.float64), inputs.positions.max(axis=0).astype(np.float64)
    occluders = None
    if bounds is None:
        lo, hi = mesh_lo, mesh_hi
    else:  # world -> relative to the mesh origin, in float64
        lo, hi = bounds[0] - inputs.origin, bounds[1] - inputs.origin
        occluders = np.array([[x, y, z] for x in (mesh_lo[0], mesh_hi[0]) for y in (mesh_lo[1], mesh_hi[1])
                              for z in (mesh_lo[2], mesh_hi[2])])
    m, extent, depth_range = light_clip_matrix(np.asarray(inputs.sky.sun.direction, dtype=np.float64), lo, hi,
                                               occluders=occluders)
    plan = plan_shadow_map(extent, resolution=params["resolution"], texel_m=params["texel_m"],
                           max_resolution=params["max_resolution"], cascade_resolution=params["cascade_resolution"],
                           max_texture_size=inputs.max_texture_size)
    atlas = _Atlas(inputs, plan)
    objs = [atlas.prog, atlas.vao, atlas.fbo, atlas.tex]
    k_count, r = plan.cascades, plan.resolution
    uv = np.zeros((max(k_count, 1), 4))
    cells = np.zeros((max(k_count, 1), 4))
    biases = np.zeros((max(k_count, 1), 4))
    per_probe = None
    facts = {"texel_m": plan.texels_m[0], "resolution": float(r)}
    if k_count:
        atlas.draw(m, plan.cells[-1], clear_all=True)      # the coarse cascade, once
        uv[-1] = (1.0, 1.0, 0.0, 0.0)
        for k, (t, c) in enumerate(zip(plan.texels_m, plan.cells)):
            cells[k] = (c[0], c[1], r, 0.0)
            biases[k, :3] = _bias(t, depth_range)
            facts[f"cascade{k}_texel_m"] = t
        facts["cascades"] = float(k_count)
        per_probe = _FollowingCascades(atlas, plan, m, uv)
    else:
        atlas.draw(m)
    inputs.ctx.finish()
    tex = atlas.tex
    tex.compare_func = "<="
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = False
    offset, const, slope = _bias(plan.texels_m[-1] if not k_count else plan.texels_m[0], depth_range)
    return EffectSetup(
        uniforms={"light_clip": m.T, "shadow_texel": 1.0 / r,
                  "shadow_normal_offset": offset, "shadow_bias_const": const, "shadow_bias_slope": slope,
                  "shadow_cascades": k_count, "shadow_cascade_uv": uv.astype(np.float32),
                  "shadow_cascade_cell": cells.astype(np.float32), "shadow_cascade_bias": biases.astype(np.float32),
                  "shadow_atlas_texel": (1.0 / np.array(plan.atlas, np.float64)).astype(np.float32)},
        textures={"shadow_map": tex},
        gl_objects=objs,
        facts=facts,
        per_probe=per_probe,
    )


EFFECT = CaptureEffect(
    name="sun_shadows",
    summary="occlusion of the sun with a shadow map (needs sun_light)",
    needs=frozenset({"sun", "triangles"}),
    requires=("sun_light",),
    parameters={
        "resolution": EffectParameter(2048, "shadow-map texels per side",
                                      positive_int("sun_shadows parameter 'resolution'")),
        "bounds": EffectParameter(None, "world box (lo (3,), hi (3,)) in meters covered by the map; "
                                        "None: the mesh bounds", _check_bounds),
        "texel_m": EffectParameter(None, "texel size (m) to reach; sets the resolution; None: use 'resolution'",
                                   _check_texel),
        "max_resolution": EffectParameter(DEFAULT_MAX_RESOLUTION, "largest single map (texels per side) "
                                          "before cascades", positive_int("sun_shadows parameter 'max_resolution'")),
        "cascade_resolution": EffectParameter(2048, "texels per side of each cascade",
                                              positive_int("sun_shadows parameter 'cascade_resolution'")),
    },
    uniforms=("shadow_map", "light_clip", "shadow_texel", "shadow_normal_offset", "shadow_bias_const",
              "shadow_bias_slope", "shadow_cascades", "shadow_cascade_uv", "shadow_cascade_cell",
              "shadow_cascade_bias", "shadow_atlas_texel"),
    pass_name="shadow_map",
    prepare=_prepare,
    glsl_declarations='#include "capture/shadow_lookup.glsl"\n',
    glsl_defines=_defines,
)
