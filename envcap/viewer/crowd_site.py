"""The crowd in the viewer's street view: what the page reads to draw ``envcap crowd``'s walkers
with the same GLSL (``shaders/crowd/``, WebGL2 target), placed and animated by the same numpy.

The server computes the crowd and the page only draws it: the walkers are placed by
:func:`envcap.crowd.walkers.place_walkers` and posed per frame by
:func:`envcap.crowd.instances.pose_crowd`, and each frame's instance and neighbour textures
(:func:`envcap.crowd.instances.instance_texture`, :func:`envcap.crowd.sphere_buffer.neighbour_texture`)
are sent as they are; so the page's crowd is ``envcap crowd``'s crowd texel for texel, with one
implementation of placement, gait, bone spheres and the neighbour search (a JavaScript copy
would be a second one to keep equal).  The cost is a short clip (:data:`FRAMES` frames at
:data:`FPS`, looped) and a few MB per walker count.

Routes (all fixed paths: nothing of a request is joined to anything; every byte is made from the
set's manifest and the avatar, which is the bundled walker or the file ``envcap view --avatar``
names on the command line):

* ``/api/crowd.json``: the crowd's description (:meth:`CrowdSite.description`): the street (index
  in ``config.streets``), the render origin (world m: the street uniforms' origin; every position
  in the textures is relative to it), ``to_local`` (the street rotation, column-major), the
  material, the sun, the counts offered with their URLs, the texture layouts;
* ``/api/crowd_vert.glsl``, ``/api/crowd_frag.glsl``: the crowd's GLSL for WebGL2 (:func:`crowd_glsl`);
* ``/api/crowd/avatar.bin``: the avatar mesh, little-endian float32 ``(V, 22)`` (position,
  normal, JOINTS_0, WEIGHTS_0, blocker joints, blocker scores: the vertex layout of
  :class:`envcap.crowd.renderer.CrowdRenderer`) then uint32 ``(T, 3)`` triangles;
* ``/api/crowd/walkers_N.bin`` for each N of :data:`COUNTS`: float32 ``FRAMES`` blocks, each the
  instance texture ``(N, 6 J, 4)`` then the neighbour texture ``(N, 2 K, 4)`` of frame ``f``
  (time ``f / FPS`` s).

The walkers walk on the set's first street with probes, on its manifest ground (the viewer has
no scene mesh to stand them on).  A city (:mod:`envcap.viewer.city_site`) has no crowd.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core.street_frame import plan_rotation
from envcap.crowd.inputs import ALBEDO, CROWD_METHODS, DEFAULT_METHOD, CrowdAvatar, default_avatar, material, \
    read_avatar
from envcap.crowd.instances import TEXELS_PER_JOINT, AvatarCycle, CrowdPose, instance_texture, pose_crowd
from envcap.crowd.renderer import MAX_LOBES, TERMS, Sun, crowd_sources
from envcap.crowd.sphere_buffer import MAX_SPHERES, NEIGHBOURS, nearest_neighbours, neighbour_texture
from envcap.crowd.walkers import Walkers, place_walkers
from envcap.dynamic.crowd_lod import NEAR_FACTOR
from envcap.probeset.manifest import Manifest
from envcap.runtime import methods
from envcap.runtime.street import StreetProbes

COUNTS = (8, 16, 32, 64)
"""Walker counts the page offers."""
DEFAULT_COUNT = 16
"""The count shown first."""
FPS = 10.0
"""Frames per second of the clip."""
FRAMES = 40
"""Frames in the clip (4 s at :data:`FPS`; the page loops it)."""
SEED = 0
"""The walkers' seed (``envcap crowd --seed``)."""
VERTEX_FLOATS = 22
"""Floats per avatar vertex in ``avatar.bin``."""


@dataclass(frozen=True)
class _SkyOf:
    """What :meth:`envcap.crowd.renderer.Sun.of` reads of a probe set: its manifest."""

    manifest: Manifest


def material_uniforms() -> dict[str, Any]:
    """The crowd material's uniforms as the renderer sets them (``crowd_rho_d``, ``crowd_C``
    rows ``(c_x, c_y, c_z, power)``, ``crowd_rho_s``, ``crowd_nlobes``, ``crowd_albedo``)."""
    m = material()
    C, rho_s = np.zeros((MAX_LOBES, 4)), np.zeros((MAX_LOBES, 3))
    for i, (c, w, rs) in enumerate(zip(m.C, m.w, m.rho_s)):
        C[i] = [*c, w]
        rho_s[i] = rs
    return {"crowd_rho_d": list(map(float, m.rho_d)), "crowd_C": C.reshape(-1).tolist(),
            "crowd_rho_s": rho_s.reshape(-1).tolist(), "crowd_nlobes": len(m.C), "crowd_albedo": ALBEDO}


PAGE_METHODS = tuple(n for n in CROWD_METHODS if not methods.get(n).needs_distance)
"""The lookups the page's crowd runs: the crowd's, less ``depth_refine`` (the page binds no
1/distance texture for the crowd: its WebGL2 shader has the probes and the sky only)."""

def crowd_glsl() -> tuple[str, str]:
    """``(vertex, fragment)``: :func:`envcap.crowd.renderer.crowd_sources` for the WebGL2 target
    with the lookup left to the macro ``CROWD_METHOD`` (the page defines it after ``#version``:
    one source for every method)."""
    return crowd_sources("CROWD_METHOD", "webgl2")


def crowd_config() -> dict[str, Any]:
    """``config["crowd"]`` of a set with a crowd: its description's URL, the counts offered and
    the one shown first."""
    return {"url": "api/crowd.json", "counts": list(COUNTS), "default_count": DEFAULT_COUNT}


@dataclass
class CrowdSite:
    """The crowd of a probe set in the viewer (module docstring).  ``manifest``: the set's;
    ``street_index``: the street in ``config.streets`` (the first with probes); ``origin_local``:
    that street's uniforms origin (frame m, ``config.streets[i].origin``); ``avatar_path``: an
    ``envcap avatar`` file, or ``None`` for the bundled walker.  The avatar and the clips are
    made when first asked for."""

    manifest: Manifest
    street_index: int
    origin_local: NDArray[np.float64]
    avatar_path: Path | None = None
    _avatar: CrowdAvatar | None = field(default=None, repr=False)
    _cycle: AvatarCycle | None = field(default=None, repr=False)

    @staticmethod
    def of(manifest: Manifest, streets: list[dict[str, Any]], avatar_path: Path | None = None) -> "CrowdSite | None":
        """The crowd of a set whose page config lists ``streets`` (:meth:`ViewerSite.streets`);
        ``None`` when it has no street with probes."""
        named = [i for i, st in enumerate(manifest.streets) if st.probes]
        if not named or not streets:
            return None
        return CrowdSite(manifest, 0, np.asarray(streets[0]["origin"], np.float64), avatar_path)

    @property
    def street(self) -> StreetProbes:
        """The street the walkers walk on."""
        return StreetProbes.from_manifest([st for st in self.manifest.streets if st.probes][self.street_index])

    @property
    def origin(self) -> NDArray[np.float64]:
        """The render origin (3,) world m: the street uniforms' origin turned back to the world
        (as :class:`envcap.crowd.renderer.CrowdRenderer` computes it)."""
        st = self.street
        return self.origin_local @ plan_rotation(st.yaw_deg) + np.array([st.origin_xz[0], 0.0, st.origin_xz[1]])

    @property
    def avatar(self) -> CrowdAvatar:
        """The avatar (read or annotated on first use)."""
        if self._avatar is None:
            self._avatar = default_avatar() if self.avatar_path is None else read_avatar(self.avatar_path)
        return self._avatar

    @property
    def cycle(self) -> AvatarCycle:
        """The avatar's sampled gait."""
        if self._cycle is None:
            self._cycle = AvatarCycle.of(self.avatar.avatar, self.avatar.spheres)
        return self._cycle

    def walkers(self, count: int) -> Walkers:
        """``count`` walkers on the street (seed :data:`SEED`, manifest ground)."""
        return place_walkers(self.street, count, SEED)

    def pose(self, count: int, frame: int) -> CrowdPose:
        """The crowd of ``count`` at frame ``frame`` of the clip (time ``frame / FPS`` s)."""
        return pose_crowd(self.walkers(count), self.cycle, frame / FPS, self.origin)

    def clip(self, count: int) -> bytes:
        """``walkers_N.bin`` (module docstring)."""
        wk = self.walkers(count)
        out = []
        for f in range(FRAMES):
            pose = pose_crowd(wk, self.cycle, f / FPS, self.origin)
            out += [instance_texture(pose).tobytes(), neighbour_texture(pose, nearest_neighbours(pose.one)).tobytes()]
        return b"".join(out)

    def avatar_bytes(self) -> bytes:
        """``avatar.bin`` (module docstring)."""
        av = self.avatar
        a = av.avatar
        cols = np.concatenate([a.positions, a.normals, a.joints, a.weights, av.blockers, av.scores], axis=1)
        return cols.astype("<f4").tobytes() + a.triangles.astype("<u4").tobytes()

    def description(self) -> dict[str, Any]:
        """``crowd.json`` (module docstring)."""
        a = self.avatar.avatar
        sun = Sun.of(_SkyOf(self.manifest))   # type: ignore[arg-type]  (Sun.of reads .manifest only)
        rot = plan_rotation(self.street.yaw_deg)
        return {
            "street": self.street_index, "origin": self.origin.tolist(),
            "to_local": rot.T.reshape(-1).tolist(),
            "avatar": {"url": "api/crowd/avatar.bin", "name": "walker.glb" if self.avatar_path is None else self.avatar_path.name,
                       "vertices": len(a.positions), "triangles": len(a.triangles), "vertex_floats": VERTEX_FLOATS},
            "joints": a.joint_count, "texels_per_joint": TEXELS_PER_JOINT, "neighbours": NEIGHBOURS,
            "max_spheres": MAX_SPHERES, "near_factor": NEAR_FACTOR, "fps": FPS, "frames": FRAMES, "seed": SEED,
            "counts": {str(n): f"api/crowd/walkers_{n}.bin" for n in COUNTS}, "default_count": DEFAULT_COUNT,
            "terms": TERMS, "methods": list(PAGE_METHODS), "default_method": DEFAULT_METHOD,
            "material": material_uniforms(),
            "sun": {"direction": sun.direction.tolist(), "irradiance": sun.irradiance.tolist(), "cos_radius": sun.cos_radius},
        }

    def routes(self) -> dict[str, Any]:
        """``/api/crowd.json``, ``/api/crowd/avatar.bin``, ``/api/crowd/walkers_N.bin`` and the
        shaders ``/api/crowd_vert.glsl``, ``/api/crowd_frag.glsl`` (made on request)."""
        out: dict[str, Any] = {"/api/crowd.json": lambda: json.dumps(self.description(), allow_nan=False).encode(),
                               "/api/crowd/avatar.bin": self.avatar_bytes,
                               "/api/crowd_vert.glsl": lambda: crowd_glsl()[0].encode(),
                               "/api/crowd_frag.glsl": lambda: crowd_glsl()[1].encode()}
        for n in COUNTS:
            out[f"/api/crowd/walkers_{n}.bin"] = (lambda n=n: self.clip(n))
        return out
