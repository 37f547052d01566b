"""Draw a lit crowd with moderngl: the street mesh with a simple shading, then every walker in one
instanced draw of ``shaders/crowd/`` (GPU skinning, the runtime lookup, the dynamic terms, the sun).

:class:`CrowdRenderer` holds the GL objects of one run (context, probe and sky textures, the
street and avatar buffers, the programs); :meth:`CrowdRenderer.render` draws one pose of the crowd
and returns the linear HDR frame (and, with ``targets=True``, the float targets the tests compare
with the numpy twin).  The sky map is drawn behind everything; the street is shaded ``albedo * (sky_mean + E_sun
max(n.l, 0) / pi) + emission`` (no shadows: the street is the backdrop; the avatars are what the
runtime lights).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import moderngl
import numpy as np
from numpy.typing import NDArray

from envcap.core.inverse_distance import inverse_distance
from envcap.core.resources import expand_includes, shader_source
from envcap.core.street_frame import plan_rotation
from envcap.crowd.camera import Camera
from envcap.crowd.inputs import ALBEDO, CrowdAvatar, crowd_function
from envcap.crowd.instances import TEXELS_PER_JOINT, CrowdPose, instance_texture
from envcap.crowd.sphere_buffer import MAX_SPHERES, NEIGHBOURS, SELF_CLAMP, neighbour_texture, nearest_neighbours
from envcap.dynamic.crowd_lod import NEAR_FACTOR
from envcap.evaluate.shading import Material
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.uniforms import set_uniforms
from envcap.probeset.probe_set import ProbeSet
from envcap.runtime.methods import ParallaxMethod
from envcap.runtime.shader_targets import prologue
from envcap.runtime.street import RuntimeStreet, StreetUniforms
from envcap.scene.model import SceneMesh

TERMS = {"probes": 0, "self": 1, "neighbours": 2}
"""``--terms``: Eq. 3 from the probes only, + the avatar's own blocker bones, + its neighbours."""
TARGETS = ("color", "position", "normal", "self0", "self1", "eq3", "self_term", "all_term")
"""The float targets of a ``targets=True`` render (``shaders/crowd/crowd_frag.glsl``, CROWD_TARGETS)."""
MAX_LOBES = 3


DISTANCE_UNIT = 7
"""Texture unit of the probes' 1/distance cube array (``crowd_distance``) for ``depth_refine``."""


def crowd_sources(method_glsl: str, target: str = "gl450", targets: bool = False) -> tuple[str, str]:
    """``(vertex, fragment)`` GLSL of the crowd for a shader ``target`` (includes expanded).
    ``crowd_sample_depth_refine`` (:func:`envcap.crowd.inputs.crowd_function`) also defines
    ``CROWD_DISTANCE`` (the distance texture and the wrapper)."""
    head = prologue(target)
    if method_glsl == "crowd_sample_depth_refine":
        method_glsl += "\n#define CROWD_DISTANCE"
    defs = f"#define CROWD_SAMPLE {method_glsl}\n#define CROWD_NEIGHBOURS {NEIGHBOURS}\n" \
           f"#define ENVCAP_MAX_SPHERES {MAX_SPHERES}\n#define CROWD_SELF_CLAMP {SELF_CLAMP!r}\n" + ("#define CROWD_TARGETS\n" if targets else "")
    vert = head + "#include \"crowd/crowd_vert.glsl\"\n"
    frag = head + defs + "#include \"crowd/crowd_frag.glsl\"\n"
    return expand_includes(vert), expand_includes(frag)


@dataclass(frozen=True)
class Sun:
    """The analytic sun: ``direction`` (3,) unit towards it (world), ``irradiance`` (3,) on a
    surface facing it (radiance x the disk's solid angle), ``cos_radius`` of its angular radius."""

    direction: NDArray[np.float64]
    irradiance: NDArray[np.float64]
    cos_radius: float

    @staticmethod
    def of(ps: ProbeSet) -> "Sun":
        """The probe set's sun when its sky map leaves it out (else none: it is in the probes)."""
        sun = ps.manifest.sky.sun
        if sun is None or ps.manifest.sky.sun_baked_in_map:
            return Sun(np.array([0.0, 1.0, 0.0]), np.zeros(3), 1.0)
        r = float(sun.angular_radius)
        omega = 2 * np.pi * (1 - np.cos(r))
        return Sun(np.asarray(sun.direction, np.float64), np.asarray(sun.radiance, np.float64) * omega, float(np.cos(r)))


class CrowdRenderer:
    """GL state of one crowd run (module docstring).  ``origin``: the render origin (world m, the
    street's local origin: the runtime's street-local frame is ``plan_rotation(yaw) @ (x - origin)``)."""

    def __init__(self, ctx: moderngl.Context, ps: ProbeSet, street: RuntimeStreet, method: ParallaxMethod,
                 avatar: CrowdAvatar, material: Material, mesh: SceneMesh | None, size: tuple[int, int],
                 walkers: int, targets: bool = False) -> None:
        self.ctx, self.size, self.targets = ctx, size, targets
        powers = ps.manifest.lobe_powers
        self.uniforms: StreetUniforms = street.uniforms(powers)
        rot = plan_rotation(street.yaw_deg)
        self.origin = self.uniforms.origin @ rot + np.array([street.origin_xz[0], 0.0, street.origin_xz[1]])
        self.to_local = rot
        self.sun = Sun.of(ps)
        self.sky_mean = np.mean(ps.sky_levels[-1][..., :3], axis=(0, 1, 2)).astype(np.float64)
        self.joint_count = avatar.avatar.joint_count
        self.resources: list[Any] = []
        self.probes = CubeArrayTexture(ps.levels)
        self.distance: CubeArrayTexture | None = None
        if method.needs_distance:
            if ps.distance is None:
                raise ValueError(f"method {method.name} needs the probe set's distance texture (inverse_distance.ktx2)")
            inv = inverse_distance(ps.distance)
            self.distance = CubeArrayTexture([np.concatenate([inv[..., None], np.zeros(inv.shape + (3,), np.float32)],
                                                             axis=-1)], filter="nearest")
        self.texture_bytes = sum(int(np.prod(lv.shape)) * 4 for lv in [*ps.levels, *ps.sky_levels])
        self.sky = cube_texture(ctx, ps.sky_levels)
        vert, frag = crowd_sources(crowd_function(method) or "envcap_sample_nearest", targets=targets)
        self.prog = self._keep(ctx.program(vertex_shader=vert, fragment_shader=frag))
        self.sources = (vert, frag)
        a = avatar.avatar
        cols = np.concatenate([a.positions, a.normals, a.joints, a.weights, avatar.blockers, avatar.scores], axis=1)
        self.avatar_vbo = self._keep(ctx.buffer(cols.astype(np.float32).tobytes()))
        self.avatar_ibo = self._keep(ctx.buffer(a.triangles.astype(np.uint32).tobytes()))
        self.avatar_vao = self._keep(ctx.vertex_array(self.prog, [(self.avatar_vbo, "3f 3f 4f 4f 4f 4f", "in_position",
                                     "in_normal", "in_joints", "in_weights", "in_blockers", "in_blocker_weights")],
                                     self.avatar_ibo))
        self.triangles = len(a.triangles)
        n = max(walkers, 1)
        self.instances = self._keep(ctx.texture((TEXELS_PER_JOINT * self.joint_count, n), 4, dtype="f4"))
        self.neighbours = self._keep(ctx.texture((2 * NEIGHBOURS, n), 4, dtype="f4"))
        for t in (self.instances, self.neighbours):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.street_vao = None
        self.street_triangles = 0
        if mesh is not None and len(mesh.indices):
            self.street_prog = self._keep(ctx.program(vertex_shader=prologue("gl450") + shader_source("crowd/street_vert.glsl"),
                                                      fragment_shader=prologue("gl450") + shader_source("crowd/street_frag.glsl")))
            pos = (mesh.positions.astype(np.float64) + mesh.origin - self.origin).astype(np.float32)
            sv = np.concatenate([pos, mesh.normals, mesh.albedo, mesh.emission], axis=1).astype(np.float32)
            self.street_vbo = self._keep(ctx.buffer(sv.tobytes()))
            self.street_ibo = self._keep(ctx.buffer(mesh.indices.astype(np.uint32).tobytes()))
            self.street_vao = self._keep(ctx.vertex_array(self.street_prog, [(self.street_vbo, "3f 3f 3f 3f", "in_position",
                                         "in_normal", "in_albedo", "in_emission")], self.street_ibo))
            self.street_triangles = len(mesh.indices)
        self.sky_prog = self._keep(ctx.program(vertex_shader=prologue("gl450") + shader_source("crowd/sky_vert.glsl"),
                                               fragment_shader=prologue("gl450") + shader_source("crowd/sky_frag.glsl")))
        self.sky_vao = self._keep(ctx.vertex_array(self.sky_prog, []))
        w, h = size
        count = len(TARGETS) if targets else 1
        self.colors = [self._keep(ctx.renderbuffer((w, h), 4, dtype="f4")) for _ in range(count)]
        self.depth = self._keep(ctx.depth_renderbuffer((w, h)))
        self.fbo = self._keep(ctx.framebuffer(self.colors, self.depth))
        m = material
        C = np.zeros((MAX_LOBES, 4))
        rho_s = np.zeros((MAX_LOBES, 3))
        for i, (c, wi, rs) in enumerate(zip(m.C, m.w, m.rho_s)):
            C[i] = [*c, wi]
            rho_s[i] = rs
        self.material_values = {"crowd_rho_d": np.asarray(m.rho_d), "crowd_C": C, "crowd_rho_s": rho_s,
                                "crowd_nlobes": len(m.C), "crowd_albedo": ALBEDO}

    def _keep(self, obj: Any) -> Any:
        self.resources.append(obj)
        return obj

    def gpu_bytes(self) -> int:
        """Bytes of the GPU buffers and textures this renderer made (probes and sky included)."""
        total = self.texture_bytes
        for r in self.resources:
            if isinstance(r, moderngl.Buffer):
                total += r.size
            elif isinstance(r, (moderngl.Texture, moderngl.Renderbuffer)):
                total += r.width * r.height * r.components * (4 if r.dtype == "f4" else 1)
        return int(total)

    def render(self, pose: CrowdPose, camera: Camera, terms: str = "neighbours", constant: bool = False,
               ) -> dict[str, NDArray[np.float32]]:
        """Draw ``pose`` from ``camera``; ``{"color": (H, W, 3) linear HDR, row 0 at the top}``,
        plus the other :data:`TARGETS` ``(H, W, 4)`` with ``targets``.  ``constant``: the unlit
        crowd (same geometry and skinning, a constant colour; the bench's reference)."""
        self.draw(pose, camera, terms, constant)
        w, h = self.size
        out = {}
        for name, rb in zip(TARGETS, self.colors):
            img = np.frombuffer(self.fbo.read(components=4, dtype="f4", attachment=TARGETS.index(name)),
                                np.float32).reshape(h, w, 4)[::-1]
            out[name] = img[..., :3].copy() if name == "color" else img.copy()
        return out

    def draw(self, pose: CrowdPose, camera: Camera, terms: str = "neighbours", constant: bool = False) -> None:
        """Upload ``pose``'s textures and draw the frame (no read-back; :meth:`render`)."""
        ctx, n = self.ctx, len(pose.roots)
        self.fbo.use()
        ctx.enable(moderngl.DEPTH_TEST)
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        vp = camera.view_proj().astype(np.float32)
        if not self.targets:
            ctx.disable(moderngl.DEPTH_TEST)
            self.sky.use(4)
            set_uniforms(self.sky_prog, {"crowd_inverse_view_proj": np.linalg.inv(camera.view_proj()).T, "sky": 4})
            self.sky_vao.render(vertices=3)
            ctx.enable(moderngl.DEPTH_TEST)
        if self.street_vao is not None and not self.targets:
            set_uniforms(self.street_prog, {"crowd_view_proj": vp.T, "crowd_sky_mean": self.sky_mean,
                                            "crowd_sun_dir": self.sun.direction, "crowd_sun_e": self.sun.irradiance})
            self.street_vao.render()
        if n:
            if n > self.instances.height:
                raise ValueError(f"{n} walkers, but the renderer was made for {self.instances.height}")
            self.instances.write(instance_texture(pose).tobytes(), viewport=(0, 0, self.instances.width, n))
            self.neighbours.write(neighbour_texture(pose, nearest_neighbours(pose.one)).tobytes(),
                                  viewport=(0, 0, self.neighbours.width, n))
            self.probes.use(3)
            self.sky.use(4)
            self.instances.use(5)
            self.neighbours.use(6)
            dist = {}
            if self.distance is not None:
                self.distance.use(DISTANCE_UNIT)
                dist = {"crowd_distance": DISTANCE_UNIT}
            values = {**dist, **self.uniforms.values(), **self.material_values,
                      "crowd_view_proj": vp.T, "crowd_joint_count": self.joint_count,
                      "crowd_to_local": self.to_local.T, "crowd_camera": camera.eye,
                      "crowd_terms": -1 if constant else TERMS[terms], "crowd_sun_dir": self.sun.direction,
                      "crowd_sun_e": self.sun.irradiance, "crowd_sun_cos": self.sun.cos_radius,
                      "crowd_near_factor": NEAR_FACTOR, "crowd_instances": 5, "crowd_neighbours": 6,
                      "probes": 3, "sky": 4}
            set_uniforms(self.prog, values, sources=self.sources)
            self.avatar_vao.render(instances=n)

    def release(self) -> None:
        """Free every GL object (the context is the caller's)."""
        for r in reversed(self.resources):
            r.release()
        self.resources.clear()
        self.probes.release()
        self.sky.release()
        if self.distance is not None:
            self.distance.release()
