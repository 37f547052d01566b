"""The numpy twin of the crowd fragment's terms (``shaders/crowd/crowd_frag.glsl``): at a shading
point with its normal, the camera and the self spheres its vertex passed, Eq. 3 of the material
through the runtime lookup (:func:`envcap.runtime.sampling.sample_street` with the crowd's method),
and ``bounced - blocked`` (:func:`envcap.dynamic.terms.dynamic_terms`) of the spheres the fragment
gathers (:func:`envcap.crowd.sphere_buffer.fragment_spheres`), own bones only and with the
neighbours.  The tests compare it with the shader's float targets."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from envcap.crowd.instances import CrowdPose
from envcap.crowd.sphere_buffer import fragment_spheres
from envcap.dynamic.terms import dynamic_terms
from envcap.evaluate.shading import Material
from envcap.probeset.probe_set import ProbeSet
from envcap.runtime.chains import ProbeChains, SkyChain
from envcap.runtime.lafortune import Lafortune
from envcap.runtime.methods import ParallaxMethod
from envcap.runtime.sampling import sample_street
from envcap.runtime.shading import shade_lafortune
from envcap.runtime.street import RuntimeStreet


@dataclass(frozen=True)
class PointTerms:
    """At one shading point: ``eq3``, ``self_term``, ``all_term`` ``(3,)`` radiance."""

    eq3: NDArray[np.float64]
    self_term: NDArray[np.float64]
    all_term: NDArray[np.float64]


def shading_frame(normal: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows T, B, N of the crowd shader's frame for unit ``normal`` (3,)."""
    n = np.asarray(normal, np.float64)
    ref = np.array([0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    t = np.cross(ref, n)
    t /= np.linalg.norm(t)
    return np.stack([t, np.cross(n, t), n])


class CrowdTwin:
    """The twin of one renderer's shading (its probe set, runtime street, method, material,
    render ``origin`` and sphere albedo)."""

    def __init__(self, ps: ProbeSet, street: RuntimeStreet, method: ParallaxMethod, material: Material,
                 origin: NDArray[np.float64], albedo: float) -> None:
        self.chains = ProbeChains.from_probe_set(ps)
        self.sky = SkyChain(ps.sky_levels)
        self.street, self.method, self.origin, self.albedo = street, method, np.asarray(origin, np.float64), albedo
        m = material
        self.lafortune = Lafortune(m.rho_d, m.C, m.w, m.rho_s)
        self.material = m

    def terms(self, x: NDArray[np.float64], normal: NDArray[np.float64], camera: NDArray[np.float64], walker: int,
              self_spheres: NDArray[np.float64], pose: CrowdPose, neighbours: NDArray[np.int64]) -> PointTerms:
        """:class:`PointTerms` at ``x`` (render frame, m) of ``walker`` (module docstring)."""
        x = np.asarray(x, np.float64)
        world = x + self.origin

        def env(d: NDArray, w: NDArray) -> NDArray:
            return sample_street(self.chains, self.sky, self.street, world, d, w, self.method)

        F = shading_frame(normal)
        v = np.asarray(camera, np.float64) - x
        v /= np.linalg.norm(v)
        vl = F @ v
        m = self.material
        eq3 = shade_lafortune(env, vl, F, m.rho_d, np.reshape(m.C, (-1, 3)), np.asarray(m.w, np.float64),
                              np.reshape(m.rho_s, (-1, 3)))
        out = []
        for use_neighbours in (False, True):
            sph = fragment_spheres(x, walker, self_spheres, pose, neighbours, use_self=True,
                                   use_neighbours=use_neighbours, albedo=self.albedo)
            dyn = dynamic_terms(x, F, vl, self.lafortune, sph, env)
            out.append(dyn.bounced - dyn.blocked)
        return PointTerms(np.asarray(eq3, np.float64), out[0], out[1])
