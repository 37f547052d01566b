"""The evaluator's predictions: a probe set looked up through the runtime's numpy twin.

Nothing here samples or blends on its own: each lookup is a registered runtime method
(:mod:`envcap.runtime.methods`) on a runtime street, composited over the sky with
:func:`envcap.runtime.sampling.composite`.  What the evaluator adds: the runtime street of each
position is made of the :data:`LOCAL_PROBES` probes nearest to it (the runtime holds at most
``MAX_PROBES`` per street; a long street has more), inside a crossing of a set that records them
(``Manifest.crossings``) as the crossing lookup mode says (:data:`CROSSING_MODES`; the default: each
direction on the meeting street it looks down, with the crossing probe among its probes,
:mod:`envcap.runtime.crossing_lookup`, docs/crossings.md), and a second sky chain (with the sun if
the bake left it out, or without) so that both sky variants can be predicted.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core.lobes import LobeLadder
from envcap.evaluate.truth import with_alpha
from envcap.prefilter import prefilter_chain
from envcap.prefilter.rungs import prefilter_rungs
from envcap.probeset.crossings import corridor, crossing_of, meetings_of
from envcap.probeset.probe_set import ProbeSet
from envcap.runtime import methods
from envcap.runtime.chains import ProbeChains, SkyChain
from envcap.runtime.crossing_lookup import crossing_street, probe_street, street_per_direction
from envcap.runtime.methods import ParallaxMethod
from envcap.runtime.sampling import composite, sample_sky
from envcap.runtime.street import RuntimeStreet, StreetProbes

LOCAL_PROBES = 4
"""Probes of a street handed to the runtime twin per position (the nearest ones along it)."""

CROSSING_MODES = ("direction", "shared", "probe", "plan", "off")
"""How a position inside a crossing is looked up: ``probe`` the crossing probe alone, ``shared``
the street's own :data:`LOCAL_PROBES` with the crossing probe among them, ``direction`` each
direction ``shared`` on the meeting street it looks down
(:func:`envcap.runtime.crossing_lookup.street_per_direction`), ``off`` per street."""

CROSSING_MODE = "direction"
"""The default (measured: docs/evaluation.md, "Crossings")."""


class Predictor:
    """Lookups of one probe set by any registered parallax method.

    :meth:`street_rgba` returns the premultiplied street RGBA a method fetches, :meth:`sky_rgb`
    the sky at the unshifted level, :meth:`predict` their composite (what
    :func:`envcap.runtime.sampling.sample_street` returns).  ``x`` (3,) m, ``d`` (M, 3) unit,
    ``w`` (M,) lobe powers (``inf`` = mirror).  With ``sky`` (an :class:`envcap.sky.Sky`) and
    ``ctx``, the sky variant the bake did not store (with or without the sun) is filtered with the
    probe set's ladder, so that both ``sun=True`` and ``sun=False`` lookups work.  ``manifest``: the
    probe set's (its streets' grounds, e.g. :class:`envcap.evaluate.sweep.StreetExtent`).
    ``crossings``: resolve positions inside a crossing to the crossing probe (``False``: per street,
    as for a set without crossings).
    """

    def __init__(self, probe_set: ProbeSet, sky: Any = None, ctx: Any = None, quality: str = "default",
                 crossings: bool | str = True) -> None:
        manifest = self.manifest = probe_set.manifest
        self.chains = ProbeChains.from_probe_set(probe_set)
        # The baked sky map holds the sun only when the manifest says so (bake default: no sun,
        # the sun is an analytic light); the other variant is filtered here when a sky is given.
        self.baked_sun = manifest.sky.sun_baked_in_map
        rungs = self.chains.ladder   # a rung-ladder set: the sky is an R-layer rung array too
        self.sky_levels = {self.baked_sun: SkyChain(probe_set.sky_levels) if rungs is None
                           else SkyChain(probe_set.sky_rungs or [], rungs)}
        if sky is not None and rungs is not None:
            ns = self.sky_levels[self.baked_sun].levels[0].shape[-2]
            self.sky_levels[not self.baked_sun] = SkyChain(prefilter_rungs(
                with_alpha(sky.cube(ns, include_sun=not self.baked_sun)), rungs, quality=quality, ctx=ctx), rungs)
        elif sky is not None:
            ns = self.sky_levels[self.baked_sun].levels[0].shape[1]
            powers = tuple(float(p) for p in self.chains.powers)
            lad = LobeLadder(tuple(max(ns >> k, 1) for k in range(len(powers))), powers)
            self.sky_levels[not self.baked_sun] = SkyChain(prefilter_chain(
                with_alpha(sky.cube(ns, include_sun=not self.baked_sun)), lad, quality=quality, ctx=ctx, progress=False))
        self.streets = {st.name: StreetProbes.from_manifest(st) for st in manifest.streets}
        self.crossing_mode = CROSSING_MODE if crossings is True else (crossings or "off")
        if self.crossing_mode not in CROSSING_MODES:
            raise ValueError(f"crossing lookup must be one of {CROSSING_MODES}, got {crossings!r}")
        table = manifest.crossings if self.crossing_mode != "off" and manifest.crossings else ()
        self.corridors = [corridor(st) for st in manifest.streets]
        self.meetings = meetings_of(manifest.streets, table)
        self.crossing_centres = [np.array(c.centre, np.float64) for c in table]   # world, m
        self.crossing_probes: list[tuple[str, int]] = []   # per crossing: (owner street, index of its probe in StreetProbes)
        for c in table:
            sp = self.streets[c.streets[0]]
            self.crossing_probes.append((c.streets[0], int(np.flatnonzero(sp.layers == c.probe_layer)[0])))

    def crossing_at(self, x: ArrayLike) -> int:
        """The index of the crossing (``Manifest.crossings``) whose region holds the world point ``x``
        (3,) m; -1: none, or crossings off."""
        if not self.meetings:
            return -1
        x = np.asarray(x, np.float64).reshape(3)
        return int(crossing_of(self.corridors, self.meetings, x[[0, 2]]))

    def local_street(self, name: str, x: ArrayLike, planes: str = "nominal") -> RuntimeStreet:
        """The runtime street of the :data:`LOCAL_PROBES` probes nearest ``x`` along street ``name``
        with the plane set ``planes``; inside a crossing (:meth:`crossing_at`) as the crossing mode
        says (:data:`CROSSING_MODES`): ``shared`` (and ``direction``, whose per-direction choice is
        :meth:`street_rgba`'s) those probes with the crossing probe among them,
        ``probe`` the crossing probe alone (its owner's frame and planes), ``plan`` the meeting street
        whose probe is nearest to ``x`` in plan, as ``shared``."""
        if name not in self.streets:
            raise ValueError(f"probe set has no street named {name!r}")
        k = self.crossing_at(x)
        if k >= 0 and self.crossing_mode == "probe":
            owner, i = self.crossing_probes[k]
            return self.streets[owner].runtime_street(planes, [i])
        if k >= 0 and self.crossing_mode in ("shared", "direction"):
            return self._shared_street(name, k, x, planes)
        if k >= 0 and self.crossing_mode == "plan":
            cands = [self._shared_street(self.corridors[i].name, k, x, planes) for i in self.meetings[k].streets]
            dist = [float(np.min(np.hypot(*(c.positions[:, [0, 2]] - c.to_frame(x)[[0, 2]]).T))) for c in cands]
            return cands[int(np.argmin(dist))]
        return self.streets[name].local(x, LOCAL_PROBES, planes)

    def _shared_street(self, name: str, k: int, x: NDArray[np.float64], planes: str) -> RuntimeStreet:
        """Street ``name``'s local probes with crossing ``k``'s probe among them
        (:func:`envcap.runtime.crossing_lookup.crossing_street`, GLSL ``envcap_crossing_street``); a
        street turned differently from the owner: the crossing probe alone in the owner's frame."""
        owner, i = self.crossing_probes[k]
        sp = self.streets[name]
        if sp.yaw_deg != self.streets[owner].yaw_deg:
            return probe_street(self.streets[owner].runtime_street(planes, [i]), int(self.streets[owner].layers[i]))
        local = sp.local(x, LOCAL_PROBES, planes)
        return crossing_street(local, local.to_frame(self.crossing_centres[k]), int(self.streets[owner].layers[i]))

    def _direction_street(self, name: str, k: int, x: NDArray[np.float64], planes: str) -> RuntimeStreet:
        """Mode ``direction``: meeting street ``name`` as ``shared`` hands it when it runs in the owner's
        frame; a street turned differently keeps its own probes (the crossing probe's cube is in the
        owner's frame, and that street's planes are the right ones for the rays looking down it)."""
        owner = self.crossing_probes[k][0]
        if self.streets[name].yaw_deg != self.streets[owner].yaw_deg:
            return self.streets[name].local(x, LOCAL_PROBES, planes)
        return self._shared_street(name, k, x, planes)

    def sky_rgb(self, d: ArrayLike, w: ArrayLike, sun: bool | None = None) -> NDArray[np.float64]:
        """Sky ``(M, 4)`` at the original directions and the unshifted level ``z(w)``.

        ``sun``: with the sun splatted into the sky map or not; ``None``: the sky as baked."""
        if sun is None:
            sun = self.baked_sun
        if sun not in self.sky_levels:
            raise ValueError("no sky chain of that sun variant: construct the Predictor with sky= and ctx=")
        d = np.asarray(d, np.float64).reshape(-1, 3)
        w = np.broadcast_to(np.asarray(w, np.float64), d.shape[:1])
        return sample_sky(self.sky_levels[sun], d, w, self.chains.xk)

    def street_rgba(self, method: str | ParallaxMethod, street: str, x: ArrayLike, d: ArrayLike,
                    w: ArrayLike) -> NDArray[np.float64]:
        """Premultiplied street RGBA ``(M, 4)`` that ``method`` fetches from the probes."""
        m = methods.get(method)
        x = np.asarray(x, np.float64).reshape(3)
        d = np.asarray(d, np.float64).reshape(-1, 3)
        w = np.broadcast_to(np.asarray(w, np.float64), d.shape[:1])
        k = self.crossing_at(x) if self.crossing_mode == "direction" else -1
        if k < 0:
            return m(self.chains, self.local_street(street, x, m.planes), x, d, w)
        streets = [self._direction_street(self.corridors[i].name, k, x, m.planes) for i in self.meetings[k].streets]
        pick = street_per_direction(streets, x, d)
        out = np.zeros((d.shape[0], 4))
        for j, st in enumerate(streets):
            sel = pick == j
            if np.any(sel):
                out[sel] = m(self.chains, st, x, d[sel], w[sel])
        return out

    def predict(self, method: str | ParallaxMethod, street: str, x: ArrayLike, d: ArrayLike, w: ArrayLike,
                sun: bool | None = None) -> NDArray[np.float64]:
        """Radiance ``(M, 3)``: street RGBA of ``method`` composited over the sky."""
        return composite(self.street_rgba(method, street, x, d, w), self.sky_rgb(d, w, sun))
