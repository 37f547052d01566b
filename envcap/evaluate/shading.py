"""The shading metric: Eq. 3 luminance of a few Lafortune materials lit by the predicted
environment against the same materials lit by the truth.

At each position, for shading frames facing up, across and along the street (two views each),
the prediction shades with :func:`envcap.runtime.shading.shade_lafortune` and a method's lookups
as ``E_w``; the truth with the same Eq. 3 and ``E_w`` the exact float64 lobe integral of the
fresh capture composited with the sky.  The error is the relative RMS of luminance over the
frames.  Definitions: ``docs/evaluation.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from numpy.typing import NDArray

from envcap.core.color import luminance
from envcap.core.street_frame import from_frame
from envcap.evaluate.predict import Predictor
from envcap.evaluate.sweep import EvalPosition
from envcap.prefilter import convolve_exact_dirs
from envcap.runtime.sampling import composite
from envcap.runtime.shading import EnvironmentFn, shade_lafortune


@dataclass(frozen=True)
class Material:
    """A Lafortune material for the shading metric (see :class:`envcap.runtime.lafortune.Lafortune`):
    ``rho_d`` (3,), lobes ``C`` (K, 3), powers ``w`` (K,), ``rho_s`` (K, 3)."""

    name: str
    rho_d: tuple[float, float, float]
    C: tuple[tuple[float, float, float], ...] = ()
    w: tuple[float, ...] = ()
    rho_s: tuple[tuple[float, float, float], ...] = ()


MATERIALS: tuple[Material, ...] = (
    Material("diffuse", (0.6, 0.6, 0.6)),
    Material("plastic", (0.4, 0.4, 0.4), ((-1.0, -1.0, 1.0),), (20.0,), ((0.3, 0.3, 0.3),)),
    Material("glossy", (0.05, 0.05, 0.05), ((-1.0, -1.0, 1.0),), (300.0,), ((0.9, 0.9, 0.9),)),
)
"""Materials of the shading metric: Lambert, a plastic (w = 20) and a glossy metal (w = 300)."""


def shading_frames(along: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Shading frames (F, 3, 3) rows T, B, N (world) and local views (F, 3) for the shading metric:
    normals up, +-cross, +-along of a street along world axis ``along``; views at 30 and 70
    degrees from the normal."""
    c = 2 - along
    normals = []
    for axis, sgn in ((1, 1), (c, 1), (c, -1), (along, 1), (along, -1)):
        nrm = np.zeros(3)
        nrm[axis] = sgn
        normals.append(nrm)
    frames, views = [], []
    for nrm in normals:
        helper = np.array([0.0, 1.0, 0.0]) if abs(nrm[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
        T = np.cross(helper, nrm)
        T /= np.linalg.norm(T)
        B = np.cross(nrm, T)
        for th, ph in ((30.0, 20.0), (70.0, 200.0)):
            t, f = math.radians(th), math.radians(ph)
            frames.append(np.stack([T, B, nrm]))
            views.append([math.sin(t) * math.cos(f), math.sin(t) * math.sin(f), math.cos(t)])
    return np.array(frames), np.array(views)


def shade(env: EnvironmentFn, mat: Material, frames: NDArray, views: NDArray) -> NDArray[np.float64]:
    """Eq. 3 radiance ``(F, 3)`` of ``mat`` in each frame, lit by ``env``."""
    C = np.array(mat.C, np.float64).reshape(-1, 3)
    return shade_lafortune(env, views, frames, mat.rho_d, C, np.array(mat.w, np.float64),
                           np.array(mat.rho_s, np.float64).reshape(-1, 3))


def exact_environment(cube3: NDArray) -> EnvironmentFn:
    """``E_w`` of a cube ``(6, N, N, 3)`` by the exact float64 lobe integral (the truth's lighting)."""
    def env(dirs: NDArray, w: NDArray) -> NDArray:
        dirs = np.asarray(dirs, np.float64)
        w = np.broadcast_to(np.asarray(w, np.float64), dirs.shape[:-1])
        out = np.empty(dirs.shape[:-1] + (3,))
        for wv in np.unique(w):
            m = w == wv
            out[m] = convolve_exact_dirs(cube3, float(wv), dirs[m])
        return out
    return env


def shading_errors(predictor: Predictor, ep: EvalPosition, capture_rgba: NDArray, sky_rgba: dict[bool, NDArray],
                   methods: Sequence[str], materials: Sequence[Material], suns: Sequence[bool]) -> list[dict[str, Any]]:
    """Rows ``{street, position_index, method, sun, material, rel_err, lateral_m, near_crossing}`` at
    position ``ep``: the relative RMS error of Eq. 3 luminance over :func:`shading_frames`.

    ``capture_rgba``: the fresh capture ``(6, N, N, 4)``; ``sky_rgba[sun]``: the sky ``(6, N, N, 4)``
    with (``True``) and without the sun, both with their axes along the street's frame
    (``ep.yaw_deg``; the shading frames are in those axes).
    """
    x = np.array(ep.position)
    frames, views = shading_frames(predictor.streets[ep.street].along)   # in the capture's axes (the street's frame)
    rows = []
    for sun in suns:
        truth_env = exact_environment(composite(capture_rgba.astype(np.float64), sky_rgba[sun]))
        for mat in materials:
            lt = luminance(shade(truth_env, mat, frames, views))
            den = float(np.sqrt(np.mean(lt ** 2)))
            for meth in methods:
                def env(dd: NDArray, ww: NDArray, meth: str = meth, sun: bool = sun) -> NDArray:
                    dw = dd.reshape(-1, 3)
                    dw = from_frame(dw, ep.yaw_deg) if ep.yaw_deg else dw      # the runtime takes world directions
                    pred = predictor.predict(meth, ep.street, x, dw, np.ravel(ww), sun)
                    return pred.reshape(dd.shape[:-1] + (3,))
                lp = luminance(shade(env, mat, frames, views))
                num = float(np.sqrt(np.mean((lp - lt) ** 2)))
                rows.append({"street": ep.street, "position_index": ep.index, "method": meth, "sun": sun,
                             "material": mat.name, "rel_err": num / den if den > 0 else float(num > 0),
                             "lateral_m": ep.lateral, "near_crossing": ep.near_crossing})
    return rows
