"""Checks of a bake's streets against the scene: before the capture, and of the planes fitted after it.

Before the capture (:func:`street_setup_warnings`): a street whose facade corridor (its length,
its two facade planes widened by :data:`NEAR_WALL_M`; in its own frame for a street at an angle)
holds no wall of the scene (a triangle with |n_y| < 0.5), or whose world plan box lies outside
the walls' plan bounds altogether, is reported: that is what
a wrong ``up_axis``, rotation or offset of an imported mesh looks like, and such a street's probes
can only use the nominal planes.

After the fit (:func:`plane_fit_warnings`): planes that were seen but not fitted
(:func:`envcap.probeset.planes.unfitted_but_seen`: the nominal plane is used there), and fitted
planes farther than :func:`far_plane_limit` from the nominal ones, one line per street and kind,
naming the probes.  :func:`inside_geometry_warning` says which probe stands inside geometry and why.

Every message is one line without the ``envcap: warning:`` prefix (the caller prints it).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from envcap.core import cube
from envcap.probeset.planes import PLANE_NAMES, FittedPlanes, Planes, unfitted_but_seen
from envcap.scene.model import Scene, Street

NEAR_WALL_M = 20.0
"""A street's corridor reaches this far (m) beyond each nominal facade plane."""
FAR_PLANE_MIN_M = 5.0
"""Fitted planes farther from the nominal ones than ``max(FAR_PLANE_MIN_M, width / 2)`` are reported."""
ENCLOSED_BACKFACE_SHARE = 0.98
"""A probe that sees back faces over this share of its sphere stands in a closed volume."""


def far_plane_limit(width: float) -> float:
    """Distance (m) past which a fitted plane of a street ``width`` m wide is reported."""
    return max(FAR_PLANE_MIN_M, 0.5 * width)


def _span(lo: float, hi: float) -> str:
    return f"{lo:.1f}..{hi:.1f}"


def _corridor(street: Street, margin: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(lo, hi)`` (3,) box of the street's facade corridor widened by ``margin`` across, in the
    street's own coordinates (its frame for a framed street; y left open)."""
    lo, hi = np.full(3, -np.inf), np.full(3, np.inf)
    lo[street.along_index], hi[street.along_index] = min(street.start, street.end), max(street.start, street.end)
    lo[street.cross_index], hi[street.cross_index] = street.facade_min - margin, street.facade_max + margin
    return lo, hi


def _plan(street: Street, margin: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(lo, hi)`` (2,) world plan box (x, z) of the street's facade corridor widened by
    ``margin`` (the box around the turned corridor for a framed street)."""
    lo, hi = _corridor(street, margin)
    a, c = street.along_index, street.cross_index
    corners = np.zeros((4, 3))
    corners[:, a], corners[:, c] = (lo[a], hi[a], hi[a], lo[a]), (lo[c], lo[c], hi[c], hi[c])
    xz = street.to_world(corners)[:, [0, 2]]
    return xz.min(axis=0), xz.max(axis=0)


def street_setup_warnings(scene: Scene) -> list[str]:
    """One line per street of ``scene`` with no wall near it (see the module docstring); none
    when the scene has no walls at all (a street over bare ground is allowed)."""
    mesh = scene.mesh
    if not mesh.indices.size:
        return []
    wall = np.abs(mesh.normals[mesh.indices[:, 0], 1]) < 0.5
    if not np.any(wall):
        return []
    centers = mesh.origin[[0, 2]] + mesh.positions[mesh.indices[wall]].astype(np.float64).mean(axis=1)[:, [0, 2]]
    w_lo, w_hi = centers.min(axis=0), centers.max(axis=0)
    walls = f"the scene's walls span x {_span(w_lo[0], w_hi[0])}, z {_span(w_lo[1], w_hi[1])}"
    fix = "check the mesh's up_axis, rotation_deg and offset (or the street's coordinates)"
    out = []
    for st in scene.streets:
        lo, hi = _plan(st, NEAR_WALL_M)
        where = f"street '{st.name}' (x {_span(lo[0], hi[0])}, z {_span(lo[1], hi[1])} with {NEAR_WALL_M:g} m margins)"
        c_lo, c_hi = _corridor(st, NEAR_WALL_M)
        local = st.to_frame(np.stack([centers[:, 0], np.zeros(len(centers)), centers[:, 1]], axis=1))
        if np.any(hi < w_lo) or np.any(lo > w_hi):
            out.append(f"{where} lies outside the scene's walls: {walls}; {fix}; its probes will use the nominal planes")
        elif not np.any(np.all((local >= c_lo) & (local <= c_hi), axis=1)):
            out.append(f"{where} has no wall near its facade planes: {walls}; {fix}; "
                       "its probes will use the nominal planes")
    return out


def _probes(indices: Sequence[int], total: int) -> str:
    shown = ", ".join(str(i) for i in indices[:8]) + (f" and {len(indices) - 8} more" if len(indices) > 8 else "")
    return f"probe{'s' if len(indices) > 1 else ''} {shown} (of {total})"


def plane_fit_warnings(street: str, width: float,
                       fits: Sequence[tuple[int, Planes, FittedPlanes]]) -> list[str]:
    """Lines about one street's fitted planes: ``fits`` holds (probe index, nominal planes,
    fitted planes) per probe; ``width`` (m) sets :func:`far_plane_limit`."""
    out = []
    for name in PLANE_NAMES:
        missed = [i for i, _, f in fits if name in unfitted_but_seen(f)]
        if missed:
            out.append(f"street '{street}': no clear {name} plane at {_probes(missed, len(fits))}: geometry was "
                       "seen but no plane stands out (a sparse mesh, or the street away from its buildings); "
                       "the nominal plane is used there")
    limit = far_plane_limit(width)
    worst, far = (0.0, -1, ""), []
    for i, nominal, f in fits:
        gaps = [(abs(getattr(f, n) - getattr(nominal, n)), n) for n in PLANE_NAMES if getattr(f, n) is not None]
        d, n = max(gaps, default=(0.0, ""))
        if d > limit:
            far.append(i)
        if d > worst[0]:
            worst = (d, i, n)
    if far:
        out.append(f"street '{street}': fitted planes lie up to {worst[0]:.2f} m from the nominal ones (probe "
                   f"{worst[1]}, {worst[2]}), more than {limit:g} m at {_probes(far, len(fits))}: check the "
                   "street's coordinates and the mesh's transform")
    return out


def inside_geometry_warning(street: str, index: int, position: Sequence[float],
                            backfacing: NDArray[np.bool_]) -> str:
    """The line for a probe flagged inside geometry: where (rounded to cm) and why, from its
    ``backfacing`` (6, N, N) capture flags (the solid-angle share of back faces seen)."""
    b = np.asarray(backfacing, dtype=bool)
    share = float(np.sum(cube.texel_solid_angles(b.shape[1]) * b) / (4.0 * math.pi))
    why = ("inside a closed volume" if share >= ENCLOSED_BACKFACE_SHARE
           else "an open or inward-wound mesh around it? (set winding on the mesh table)")
    pos = ", ".join(f"{float(v):.2f}" for v in position)
    return (f"probe {index} of street '{street}' at ({pos}) stands inside geometry: it sees back faces over "
            f"{100 * share:.0f} % of its sphere: {why}")
