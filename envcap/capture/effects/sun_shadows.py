"""``sun_shadows``: occlusion of the sun with a shadow map (needs ``sun_light``).

* Needs: the sky's sun and a mesh with triangles (nothing else can cast a shadow); requires
  ``sun_light``, whose sun term it multiplies by the visibility ``sun_visibility``
  (``shaders/capture/shadow_lookup.glsl``).
* Parameters: ``resolution`` (default 2048) shadow-map texels per side (square);
  ``bounds`` (default ``None``: the mesh bounds) the world box ``(lo (3,), hi (3,))`` meters it
  covers, padded 1 m (:func:`envcap.capture.projection.light_clip_matrix`); the map's depth
  still reaches every mesh vertex toward the sun, so geometry outside the box casts into it;
  ``texel_m`` (default ``None``) the texel size to reach: the resolution becomes
  ``ceil(window / texel_m)`` (a clear error past ``GL_MAX_TEXTURE_SIZE``: fit a smaller box).
  The light frustum is fitted relative to the mesh origin (``EffectInputs.origin``), like the
  vertices it draws.  Reports ``facts["texel_m"]``, the texel size in meters.
* Per-set pass ``shadow_map``: the mesh drawn depth-only (24-bit) into an orthographic
  light-space map.  Points outside the map are lit.
* Uniforms: ``shadow_map`` (compare sampler), ``light_clip`` (origin-relative -> light clip),
  ``shadow_texel`` (1 / resolution) and the bias: receivers move 1.5 shadow texels along their
  normal (``shadow_normal_offset``, m); depth bias of half a texel (``shadow_bias_const``) plus
  one texel per unit tan(incidence) (``shadow_bias_slope``), in depth units (docs/capture.md).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import moderngl
import numpy as np

from envcap.capture.effects.base import CaptureEffect, EffectInputs, EffectParameter, EffectSetup, positive_int
from envcap.capture.projection import light_clip_matrix
from envcap.core.resources import shader_source
from envcap.gpu.uniforms import set_uniforms


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


def _prepare(inputs: EffectInputs, params: Mapping[str, Any]) -> EffectSetup:
    res: int = params["resolution"]
    bounds: Sequence[np.ndarray] | None = params["bounds"]
    mesh_lo, mesh_hi = inputs.positions.min(axis=0).astype(np.float64), inputs.positions.max(axis=0).astype(np.float64)
    occluders = None
    if bounds is None:
        lo, hi = mesh_lo, mesh_hi
    else:  # world -> relative to the mesh origin, in float64
        lo, hi = bounds[0] - inputs.origin, bounds[1] - inputs.origin
        occluders = np.array([[x, y, z] for x in (mesh_lo[0], mesh_hi[0]) for y in (mesh_lo[1], mesh_hi[1])
                              for z in (mesh_lo[2], mesh_hi[2])])
    ctx = inputs.ctx
    m, extent, depth_range = light_clip_matrix(np.asarray(inputs.sky.sun.direction, dtype=np.float64), lo, hi,
                                               occluders=occluders)
    if params["texel_m"] is not None:
        res = int(np.ceil(extent / params["texel_m"]))
        if res > inputs.max_texture_size:
            raise ValueError(f"sun_shadows: a texel of {params['texel_m']:g} m over a {extent:.1f} m window needs "
                             f"{res} texels, past GL_MAX_TEXTURE_SIZE {inputs.max_texture_size}: fit a smaller box "
                             f"(bounds) or a larger texel")
    if res > inputs.max_texture_size:
        raise ValueError(f"sun_shadows resolution {res} exceeds GL_MAX_TEXTURE_SIZE {inputs.max_texture_size}")
    texel_m = extent / res
    prog = ctx.program(vertex_shader=shader_source("capture/shadow_vert.glsl"),
                       fragment_shader=shader_source("capture/shadow_frag.glsl"))
    set_uniforms(prog, {"light_clip": m.T})  # GLSL matrices are column-major
    vao = ctx.vertex_array(prog, [(inputs.vertex_buffer, "3f 36x", "in_position")],
                           index_buffer=inputs.index_buffer, index_element_size=4)
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
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = False
    return EffectSetup(
        uniforms={"light_clip": m.T, "shadow_texel": 1.0 / res,
                  "shadow_normal_offset": 1.5 * texel_m,
                  "shadow_bias_const": 0.5 * texel_m / depth_range,
                  "shadow_bias_slope": 1.0 * texel_m / depth_range},
        textures={"shadow_map": tex},
        gl_objects=[prog, vao, fbo, tex],
        facts={"texel_m": texel_m, "resolution": float(res)},
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
    },
    uniforms=("shadow_map", "light_clip", "shadow_texel", "shadow_normal_offset", "shadow_bias_const",
              "shadow_bias_slope"),
    pass_name="shadow_map",
    prepare=_prepare,
    glsl_declarations='#include "capture/shadow_lookup.glsl"\n',
)
