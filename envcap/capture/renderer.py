"""HDR cube capture of a scene mesh with moderngl: one pass per effect the scene calls for.

A :class:`CubeCapture` uploads a :class:`~envcap.scene.model.SceneMesh` once, applies the listed
effects (:mod:`envcap.capture.effects`: their GLSL compiled into the capture shader, their
per-set passes run once, e.g. the sky SH projection of ``sky_light`` and the shadow map of
``sun_shadows``), and then captures probes: per probe, six draws (one per cube face, 90 degree
frustum, GL face orientation of :mod:`envcap.core.cube`, :mod:`envcap.capture.projection`) into
one reused RGBA32F render target laid out as a 3 x 2 grid of faces with a reversed float32
depth buffer (:mod:`envcap.gpu.float_depth`), and one readback.  Each face draws only the
triangle chunks that can reach its frustum (:mod:`envcap.capture.culling`;
``cull_chunks=False`` draws everything, same output).

Precision: everything on the GPU is relative to the mesh's origin (``SceneMesh.origin``,
float64, near the geometry): the vertices are stored relative to it, and per probe the probe's
offset from it is computed in float64 and rounded to float32 once; the vertex shader subtracts
it, so the positions relative to the probe, the distances and the shadow-map lookups keep the
float32 steps of the scene's own size wherever it lies (``docs/capture.md``, "Precision").

Outputs: :mod:`envcap.capture.outputs`.  Shading model and its assumptions: ``docs/capture.md``.
"""

from __future__ import annotations

import math
import time
from typing import Any, Callable, Iterable, Mapping, Sequence

import moderngl
import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from envcap.capture.culling import TriangleChunks, chunk_triangles, face_draw_commands
from envcap.capture.effects import check_effects, get_effect, registered_effects
from envcap.capture.effects.base import CaptureEffect, EffectInputs, SkyLike, capture_fragment_source
from envcap.capture.outputs import CaptureSet, ProbeCapture
from envcap.capture.projection import face_clip_matrix_reversed
from envcap.core.checks import positive_int
from envcap.core.color import srgb_to_linear
from envcap.core.resources import shader_source
from envcap.core.street_frame import plan_rotation
from envcap.gpu.context import create_context
from envcap.gpu.float_depth import FloatDepthGL
from envcap.gpu.uniforms import set_uniforms
from envcap.scene.model import Scene, SceneMesh

_ATTRIBUTES = ("in_position", "in_normal", "in_albedo", "in_emission")  # 3 float32 each, interleaved


def _check_position(p: Any) -> NDArray[np.float64]:
    a = np.asarray(p, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"probe position must have shape (3,), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"probe position must be finite, got {a.tolist()}")
    return a


class CubeCapture:
    """Captures HDR cube probes of one scene mesh at many positions (see the module docstring).

    Parameters
    ----------
    mesh:
        The scene geometry (uploaded once, float32 relative to ``mesh.origin``).
    size:
        Face resolution ``N`` (integer >= 1).
    sky:
        An :class:`envcap.sky.base.Sky` (or anything with ``sun`` and ``radiance(dirs)``), for the
        effects that need the sky or its sun.  ``None`` means no sky: those effects are then
        not applied.
    effects:
        Names of registered effects (:func:`envcap.capture.effects.effect_names`); each runs
        only when listed, and only when the scene has what it needs (:attr:`applied`).
    ctx:
        A moderngl context (OpenGL >= 4.3); default: a new headless one (released by
        :meth:`release`).
    near, far:
        Clip distances along each face's axis in meters; ``far = inf`` is an infinite
        projection.  Distances are written from the fragment shader in float32 (not rebuilt
        from depth), so ``far`` does not limit their accuracy.
    effect_parameters:
        Per effect name, its keyword parameters (each effect module documents them), e.g.
        ``{"sun_shadows": {"resolution": 1024}, "sky_light": {"sh_resolution": 32}}``.
    cull_chunks:
        Draw, for each face, only the triangle chunks whose box reaches that face's frustum,
        near chunks first (:mod:`envcap.capture.culling`).  The output is the same as with
        ``False`` (every triangle drawn for every face, one draw call), only faster; ``False``
        is the simple reference path.
    chunk_size:
        Cell size in meters of the chunk grid (x-z), used when ``cull_chunks``.
    """

    def __init__(self, mesh: SceneMesh, size: int, *, sky: SkyLike | None = None,
                 effects: Iterable[str] = (), ctx: moderngl.Context | None = None, near: float = 0.05,
                 far: float = math.inf, effect_parameters: Mapping[str, Mapping[str, Any]] | None = None,
                 cull_chunks: bool = True, chunk_size: float = 8.0) -> None:
        self.size = positive_int(size, "capture resolution")
        self.effects: frozenset[str] = check_effects(effects)
        if not (math.isfinite(near) and 0 < near < far):
            raise ValueError(f"need 0 < near < far, got near={near}, far={far}")
        given = dict(effect_parameters or {})
        params = {name: get_effect(name).resolve_parameters(given.get(name)) for name in self.effects | set(given)}
        if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(chunk_size) and chunk_size > 0):
            raise ValueError(f"chunk cell size must be a finite number of meters > 0, got {chunk_size!r}")
        self.mesh = mesh
        self.origin: NDArray[np.float64] = mesh.origin
        self.cull_chunks = bool(cull_chunks)
        self.near, self.far = float(near), float(far)
        self.sky = sky
        self._own_ctx = ctx is None
        self.ctx = create_context() if ctx is None else ctx
        ctx = self.ctx
        max_size = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
        if 3 * self.size > max_size:
            raise ValueError(f"capture resolution {self.size} too large: 3 x {self.size} exceeds GL_MAX_TEXTURE_SIZE {max_size}")

        sun = getattr(sky, "sun", None) if sky is not None else None
        sun_ok = sun is not None and np.all(np.isfinite(sun.direction)) and np.linalg.norm(sun.direction) > 0 \
            and np.all(np.isfinite(sun.illuminance))
        if sun is not None and not sun_ok:
            raise ValueError("sky.sun has a zero or non-finite direction or illuminance")
        has_tris = mesh.triangle_count > 0
        self.applied_effects: tuple[CaptureEffect, ...] = _applied(
            self.effects, {"sky": sky is not None, "sun": bool(sun_ok), "triangles": has_tris})
        self.applied: frozenset[str] = frozenset(e.name for e in self.applied_effects)
        self.passes_run: list[str] = []
        self.pass_times_s: dict[str, float] = {}
        self.effect_facts: dict[str, float] = {}
        """Numbers the applied effects report, ``"EFFECT.NAME" -> value`` (e.g.
        ``"sun_shadows.texel_m"``: the shadow map's texel size in meters)."""

        textured = {"ENVCAP_TEXTURED": 1} if mesh.textured and has_tris else None
        defines = dict(textured or {})
        for effect in self.applied_effects:
            if effect.glsl_defines is not None:
                defines.update(effect.glsl_defines(params[effect.name]))
        self._fragment_source = capture_fragment_source(self.applied_effects, defines or None)
        self._prog = ctx.program(vertex_shader=shader_source("capture/capture_vert.glsl", textured),
                                 fragment_shader=self._fragment_source)
        self._textures: list[Any] = []   # bound to units 0, 1, ... for every probe
        self._effect_objs: list[Any] = []
        self._per_probe: list[tuple[str, Callable[[NDArray[np.float64]], Mapping[str, Any]]]] = []
        self._vao = None
        self._vbo = self._ibo = self._indirect = None
        self.chunks: TriangleChunks | None = None
        if has_tris:
            data = np.concatenate([mesh.positions, mesh.normals, mesh.albedo, mesh.emission], axis=1)
            self._vbo = ctx.buffer(np.ascontiguousarray(data, dtype=np.float32).tobytes())
            # Triangles reordered into spatial chunks (contiguous index ranges); both paths draw
            # this buffer, so the culled path draws a subset of the same triangles.
            self.chunks = chunk_triangles(mesh.positions, mesh.indices, chunk_size)
            idx = mesh.indices[self.chunks.order]
            self._ibo = ctx.buffer(np.ascontiguousarray(idx, dtype=np.uint32).tobytes())
            # Indirect draw commands, 20 bytes each, at most one per chunk and face.
            self._indirect = ctx.buffer(reserve=20 * 6 * max(int(self.chunks.first.size), 1))
            # Attributes that a shader variant does not use are optimized away: skip their bytes.
            used = [a for a in _ATTRIBUTES if self._prog.get(a, None) is not None]
            fmt = " ".join("3f" if a in used else "12x" for a in _ATTRIBUTES)
            content = [(self._vbo, fmt, *used)]
            if textured:
                content.append(self._surface_textures(mesh))
            self._vao = ctx.vertex_array(self._prog, content, index_buffer=self._ibo, index_element_size=4)
        n = self.size
        self._color = ctx.texture((3 * n, 2 * n), 4, dtype="f4")
        self._depth = ctx.depth_renderbuffer((3 * n, 2 * n))
        self._fbo = ctx.framebuffer([self._color], self._depth)
        # Reversed depth in a float32 buffer (face_clip_matrix_reversed): the 24-bit buffer that
        # moderngl makes cannot separate a window from its wall (1.5 cm) beyond ~110 m.
        self._gl = FloatDepthGL()
        self._depth32 = self._gl.attach_float_depth(self._fbo.glo, 3 * n, 2 * n)
        self._face_clip = [face_clip_matrix_reversed(f, self.near, self.far).T for f in range(6)]  # column-major

        inputs = EffectInputs(ctx=ctx, sky=sky, positions=mesh.positions, origin=mesh.origin, vertex_buffer=self._vbo,
                              index_buffer=self._ibo, max_texture_size=max_size)
        try:
            for effect in self.applied_effects:
                t0 = time.perf_counter()
                setup = effect.setup(inputs, params[effect.name])
                self._effect_objs += setup.gl_objects
                units = {}
                for name, tex in setup.textures.items():
                    units[name] = len(self._textures)
                    self._textures.append(tex)
                set_uniforms(self._prog, {**setup.uniforms, **units}, sources=(self._fragment_source,))
                self.effect_facts.update({f"{effect.name}.{k}": float(v) for k, v in setup.facts.items()})
                if effect.pass_name is not None:
                    self._record(effect.pass_name, time.perf_counter() - t0)
                if setup.per_probe is not None:   # e.g. shadow cascades that follow the probe
                    self._per_probe.append((effect.pass_name or effect.name, setup.per_probe))
        except BaseException:
            self.release()  # a failed effect leaves no GL objects behind
            raise

    def _surface_textures(self, mesh: SceneMesh) -> tuple[Any, str, str]:
        """Upload a textured mesh's images (decoded to linear, float16, mipmapped, repeating) as
        a 2D texture array on the next texture unit, and its (u, v, layer) per vertex; returns
        the vertex-array entry of the latter."""
        assert mesh.textures is not None and mesh.uv_layer is not None
        ctx = self.ctx
        k, s = mesh.textures.shape[0], mesh.textures.shape[1]
        most = int(ctx.info.get("GL_MAX_ARRAY_TEXTURE_LAYERS", 256))
        if k > most:
            raise ValueError(f"the scene has {k} distinct surface textures, more than this GPU's "
                             f"GL_MAX_ARRAY_TEXTURE_LAYERS ({most}): share or atlas them")
        linear = srgb_to_linear(mesh.textures[..., :3] / 255.0).astype(np.float16)
        tex = ctx.texture_array((s, s, k), 3, np.ascontiguousarray(linear).tobytes(), dtype="f2")
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        tex.anisotropy = 16.0
        uvl = ctx.buffer(np.ascontiguousarray(mesh.uv_layer, dtype=np.float32).tobytes())
        set_uniforms(self._prog, {"surface_textures": len(self._textures)})
        self._textures.append(tex)
        self._effect_objs += [tex, uvl]
        return (uvl, "3f", "in_uv_layer")

    def _record(self, name: str, seconds: float) -> None:
        if name not in self.passes_run:
            self.passes_run.append(name)
        self.pass_times_s[name] = self.pass_times_s.get(name, 0.0) + seconds

    # -- per-probe passes -------------------------------------------------------------------------
    def capture(self, position: Sequence[float], yaw_deg: float = 0.0) -> ProbeCapture:
        """Capture the probe at ``position`` (3,) meters, its cube turned with a street at
        ``yaw_deg`` (:mod:`envcap.core.street_frame`; 0: the world axes); outputs per
        :mod:`envcap.capture.outputs`."""
        p = _check_position(position)
        n = self.size
        rgba = np.empty((6, n, n, 4), dtype=np.float32)
        distance = np.empty((6, n, n), dtype=np.float32)
        backfacing = np.empty((6, n, n), dtype=bool)
        times, stats = self._capture_into(p, rgba, distance, backfacing, yaw_deg)
        return ProbeCapture(position=p, rgba=rgba, distance=distance, backfacing=backfacing,
                            passes_run=self.passes_run + ["render", "readback"],
                            pass_times_s={**self.pass_times_s, **times}, draw_stats=stats)

    def _capture_into(self, p: NDArray[np.float64], rgba: NDArray[np.float32], distance: NDArray[np.float32],
                      backfacing: NDArray[np.bool_], yaw_deg: float = 0.0) -> tuple[dict[str, float], dict[str, float]]:
        """Render the probe at ``p`` (world meters) and write its outputs into the given
        (C-contiguous) arrays.

        Writing straight into the caller's arrays matters for :meth:`capture_many`: a copy into
        fresh output memory costs its page faults a second time (measured 3-10 ms per 6 x 256^2
        probe here).  Returns (pass seconds, draw stats).
        """
        n = self.size
        ctx = self.ctx
        stats = {"cull_s": 0.0, "triangles": 0.0, "draw_calls": 0.0}
        local = p - self.origin  # float64; rounded to float32 once, for the shader
        rotation = None if yaw_deg == 0.0 else plan_rotation(yaw_deg)
        face_clip = self._face_clip if rotation is None else self._turned_face_clips(rotation)
        draws = self._face_draws(local, stats, rotation)  # CPU time in stats["cull_s"], not in "render"
        times: dict[str, float] = {}
        for name, hook in self._per_probe:
            t0 = time.perf_counter()
            set_uniforms(self._prog, hook(local))
            times[name] = times.get(name, 0.0) + time.perf_counter() - t0
        t0 = time.perf_counter()
        self._fbo.use()
        self._fbo.viewport = (0, 0, 3 * n, 2 * n)
        self._fbo.clear(0.0, 0.0, 0.0, 0.0, depth=0.0)  # reversed depth: 0 is infinitely far
        if self._vao is not None:
            with self._gl.reversed_depth():
                ctx.enable(ctx.DEPTH_TEST)
                ctx.disable(ctx.CULL_FACE)  # both sides: back faces are seen (and marked) from inside buildings
                ctx.disable(ctx.BLEND)
                set_uniforms(self._prog, {"probe": local.astype(np.float32)})
                for unit, tex in enumerate(self._textures):
                    tex.use(unit)
                for f in range(6):
                    if draws is not None and draws[f][1] == 0:
                        continue
                    self._fbo.viewport = ((f % 3) * n, (f // 3) * n, n, n)
                    set_uniforms(self._prog, {"face_clip": face_clip[f]})
                    if draws is None:
                        self._vao.render()
                    else:  # one multi-draw per face (glMultiDrawElementsIndirect)
                        self._vao.render_indirect(self._indirect, count=draws[f][1], first=draws[f][0])
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
        return {**times, "render": t1 - t0, "readback": t2 - t1}, stats

    def _turned_face_clips(self, rotation: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Column-major face clip matrices of a cube turned by ``rotation`` (world -> cube frame):
        ``clip = F_f [R 0; 0 1] (x - probe, 1)``.  Lighting stays in the world frame."""
        turn = np.eye(4)
        turn[:3, :3] = rotation
        return [(face_clip_matrix_reversed(f, self.near, self.far) @ turn).T for f in range(6)]

    def _face_draws(self, p: NDArray[np.float64], stats: dict[str, float],
                    rotation: NDArray[np.float64] | None = None) -> list[tuple[int, int]] | None:
        """Cull and order chunks for the probe at ``p`` (meters, relative to the mesh origin) and
        write the indirect draw commands into ``self._indirect``.  Returns per face (first
        command, number of commands); ``None``: draw everything."""
        ch = self.chunks
        if ch is None:
            return [(0, 0)] * 6
        if not self.cull_chunks:
            stats["triangles"], stats["draw_calls"] = 6.0 * int(ch.count.sum()), 6.0
            return None
        t0 = time.perf_counter()
        draws = face_draw_commands(ch, p, self.near, self.far, rotation)
        stats["triangles"] = float(draws.triangles)
        stats["draw_calls"] = float(draws.commands.shape[0])
        if draws.commands.shape[0]:
            self._indirect.write(draws.commands.tobytes())
        stats["cull_s"] = time.perf_counter() - t0
        return draws.faces

    def capture_many(self, positions: NDArray[np.floating], progress: bool = True,
                     on_probe: Callable[[int, CaptureSet], None] | None = None, yaw_deg: float = 0.0) -> CaptureSet:
        """Capture probes at ``positions`` (P, 3) meters, cubes turned with a street at ``yaw_deg``
        (:meth:`capture`), with a tqdm bar when on a TTY.
        ``on_probe(i, out)``: called once probe ``i`` of ``out`` (the set being filled) is captured."""
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
            times, _ = self._capture_into(pos[i], out.rgba[i], out.distance[i], out.backfacing[i], yaw_deg)
            for k, v in times.items():
                out.pass_times_s[k] = out.pass_times_s.get(k, 0.0) + v
            if on_probe is not None:
                on_probe(i, out)
        return out

    @classmethod
    def from_scene(cls, scene: Scene, size: int, *, sky: SkyLike | None = None, ctx: moderngl.Context | None = None,
                   **kwargs: Any) -> "CubeCapture":
        """A capture of ``scene`` with its effects; ``sky`` defaults to the scene's sky
        (``scene.sky.build()``) when one of its effects needs the sky or the sun."""
        if sky is None and any(get_effect(e).needs & {"sky", "sun"} for e in scene.effects):
            sky = scene.sky.build()
        return cls(scene.mesh, size, sky=sky, effects=scene.effects, ctx=ctx, **kwargs)

    def release(self) -> None:
        """Free the GL objects (and the context if this capture created it)."""
        for o in [self._vao, self._vbo, self._ibo, self._indirect, self._fbo, self._color, self._depth, self._prog,
                  *self._effect_objs]:
            if o is not None:
                o.release()
        if self._depth32:
            self._gl.delete_renderbuffer(self._depth32)
            self._depth32 = 0
        self._vao = None
        self._effect_objs = []
        self._textures = []
        if self._own_ctx:
            self.ctx.release()

    def __enter__(self) -> "CubeCapture":
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _applied(listed: frozenset[str], available: Mapping[str, bool]) -> tuple[CaptureEffect, ...]:
    """The listed effects whose needs are ``available`` and whose required effects are applied,
    in registry order."""
    chosen = [e for e in registered_effects() if e.name in listed and all(available[k] for k in e.needs)]
    while True:
        names = {e.name for e in chosen}
        kept = [e for e in chosen if all(r in names for r in e.requires)]
        if len(kept) == len(chosen):
            return tuple(kept)
        chosen = kept
