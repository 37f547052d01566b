"""Parallax error evaluation against fresh captures (``envcap evaluate``).

At sampled positions in the street volume (a crowd: lateral offsets, anywhere along the street,
heights 0.3-3 m) a fresh HDR cube is captured (the *truth*), composited with the sky the way the
runtime does, and filtered at exactly each evaluated lobe power ``w``.  The same environment is
predicted from a probe set by each runtime method, for every texel direction of the truth cube,
and the two are compared with the solid-angle weighted relative RMSE of luminance
(:func:`envcap.evaluate.metrics.relative_rmse`) and with Eq. 3 shading of a few Lafortune materials.
Definitions, assumptions and measured figures: ``docs/evaluation.md``.

Conventions: world meters, +Y up (``envcap/core/cube.py``); cubes ``(6, M, M, C)``; colors linear HDR.
``w = inf`` is the mirror (level 0, unfiltered).  Methods (:data:`METHODS`):

* ``nearest``: nearest probe along the street, no parallax: chain at ``d``, level ``z(w)``;
* ``planes``: nearest probe, three nominal planes, no mip shift;
* ``planes_mip``: three nominal planes + mip shift ``w' = w (d_probe/d_shade)^2`` (the paper;
  :func:`envcap.runtime.parallax.sample_street`);
* ``blend``: the two bracketing probes, each with planes + mip shift, blended along the street
  (``sample_street(blend=True)``);
* ``fitted_planes_mip``: as ``planes_mip`` with each probe's planes fitted from its own depth
  (manifest ``fitted_planes``, nominal where a plane was not fitted);
* ``depth_reproject``: the ray from ``x`` is marched against the nearest probe's stored distance
  channel (first sample behind the surface the probe sees, within a thickness; bisection), the
  probe is sampled towards the hit, with the mip shift of the hit distances; rays that pass
  behind occluders fall back to the fitted planes; rays that never go behind anything see the sky.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.core import cube as cubemod
from envcap.runtime import parallax as px

METHODS: tuple[str, ...] = ("nearest", "planes", "planes_mip", "blend", "fitted_planes_mip", "depth_reproject")
"""Prediction methods, simplest first (see the module docstring)."""

DEFAULT_LOBE_POWERS: tuple[float, ...] = (math.inf, 1024.0, 256.0, 64.0, 16.0, 4.0, 1.0)
"""Evaluated lobe powers: the mirror (``inf``, level 0) and normalized cos^w lobes."""

LOCAL_PROBES = 4
"""Probes of a street handed to the runtime twin per position (the nearest ones along it)."""


@dataclass(frozen=True)
class Sweep:
    """Where to evaluate: ``per_street`` positions on every street of the probe set.

    Along the street: jittered strata over the probes' span (half a spacing beyond the end
    probes), at least ``end_margin`` m from the street's ends.  Lateral: uniform within the
    facades minus ``margin`` m.  Height: uniform in ``heights`` m above the ground.  ``seed``
    fixes everything (street ``i`` uses ``seed + i``).
    """

    per_street: int = 16
    margin: float = 1.0
    end_margin: float = 2.0
    heights: tuple[float, float] = (0.3, 3.0)
    seed: int = 5

    def __post_init__(self) -> None:
        if not (isinstance(self.per_street, int) and self.per_street >= 1):
            raise ValueError(f"sweep: per_street must be a positive integer, got {self.per_street!r}")
        vals = (self.margin, self.end_margin, *self.heights)
        if not all(math.isfinite(v) for v in vals) or self.margin < 0 or self.end_margin < 0:
            raise ValueError(f"sweep: margins must be finite and >= 0, got {self.margin}, {self.end_margin}")
        if not 0 < self.heights[0] <= self.heights[1]:
            raise ValueError(f"sweep: heights must satisfy 0 < low <= high, got {self.heights}")


DEFAULT_SWEEP = Sweep()
QUICK_SWEEP = Sweep(per_street=6)


@dataclass(frozen=True)
class EvalPosition:
    """One evaluation position: ``position`` (3,) m on street ``street``; ``lateral`` signed
    offset (m) from the street's probe line on its cross axis; ``along`` (m) distance along the
    street to the nearest probe; ``height`` (m) above the ground; ``near_crossing``: inside
    another street's roadway (the three planes of this street are wrong there)."""

    street: str
    index: int
    position: tuple[float, float, float]
    lateral: float
    along: float
    height: float
    near_crossing: bool


@dataclass(frozen=True)
class Material:
    """A Lafortune material for the shading metric (see :class:`envcap.runtime.lafortune.Lafortune`)."""

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


@dataclass
class EvaluationResult:
    """Outcome of :func:`evaluate_scene`.

    ``rows``: one dict per (position, method, lobe power): ``scene, street, position_index,
    method, lobe_power`` (``None`` = mirror), ``rel_rmse``, offsets.  ``summary``: one dict per
    (scene, method, lobe power): ``rel_rmse`` (mean over positions), ``median``, ``p90``,
    ``max``, ``n_positions``.  ``shading``: one dict per (position, method, material):
    ``rel_err`` of Eq. 3 luminance.  ``timings``: seconds (captures, filtering, predictions,
    shading, total).  ``floor``: the same metrics at the probes' own positions (evaluator and
    filter floor).  ``meta``: resolution, sweep, probe set facts.
    """

    scene: str
    positions: list[EvalPosition]
    rows: list[dict[str, Any]]
    summary: list[dict[str, Any]]
    shading: list[dict[str, Any]]
    timings: dict[str, float]
    meta: dict[str, Any]
    floor: list[dict[str, Any]] = field(default_factory=list)
    strips: dict[str, Any] = field(default_factory=dict)

    def error(self, method: str, lobe_power: float | None, stat: str = "rel_rmse", sun: bool = True) -> float:
        """Summary statistic of ``method`` at ``lobe_power`` (``None``/``inf`` = mirror) with or
        without the sun in the sky; NaN if absent."""
        lp = _lp_key(lobe_power)
        for r in self.summary:
            if r["method"] == method and r["lobe_power"] == lp and r.get("sun", True) == sun:
                return float(r[stat])
        return float("nan")


def _lp_key(w: float | None) -> float | None:
    return None if w is None or (isinstance(w, float) and math.isinf(w)) else float(w)


def _lp_label(w: float | None) -> str:
    return "mirror" if _lp_key(w) is None else f"w={w:g}"


# --- positions ---------------------------------------------------------------------------

def _street_info(st: Mapping[str, Any]) -> dict[str, Any]:
    along = 0 if st["axis"] == "x" else 2
    s = sorted(float(p["position"][along]) for p in st["probes"])
    pl = st["planes"]
    return {"along": along, "cross": 2 - along, "s": np.array(s), "fmin": float(pl["facade_min"]),
            "fmax": float(pl["facade_max"]), "ground": float(pl["ground"]), "start": float(st["start"]),
            "end": float(st["end"]), "center": float(st["center"])}


def _near_crossing(x: NDArray[np.float64], name: str, streets: Sequence[Mapping[str, Any]]) -> bool:
    for st in streets:
        if st["name"] == name:
            continue
        info = _street_info(st)
        if info["fmin"] <= x[info["cross"]] <= info["fmax"] and info["start"] <= x[info["along"]] <= info["end"]:
            return True
    return False


def sample_positions(manifest: Mapping[str, Any], sweep: Sweep = DEFAULT_SWEEP) -> list[EvalPosition]:
    """Evaluation positions for every street of a probe-set ``manifest`` (see :class:`Sweep`).

    A street narrower than ``2 * margin`` is sampled on its probe line; one whose usable span is
    empty at the middle of its probes.  Deterministic for a given ``sweep.seed``.
    """
    streets = manifest.get("streets") or []
    if not streets:
        raise ValueError("probe set has no streets: nothing to evaluate")
    out: list[EvalPosition] = []
    for k, st in enumerate(streets):
        if not st.get("probes"):
            raise ValueError(f"street {st.get('name')!r} has no probes")
        info = _street_info(st)
        rng = np.random.default_rng(sweep.seed + k)
        s = info["s"]
        half = 0.5 * (s[1] - s[0]) if s.size > 1 else 0.5 * float(manifest.get("probe_spacing", 0.0))
        lo = max(info["start"] + sweep.end_margin, s[0] - half)
        hi = min(info["end"] - sweep.end_margin, s[-1] + half)
        if not hi > lo:
            lo = hi = 0.5 * (s[0] + s[-1])
        clo, chi = info["fmin"] + sweep.margin, info["fmax"] - sweep.margin
        if not chi > clo:
            clo = chi = info["center"]
        n = sweep.per_street
        alongs = lo + (hi - lo) * (np.arange(n) + rng.uniform(0, 1, n)) / n
        crosses = rng.uniform(clo, chi, n)
        heights = rng.uniform(sweep.heights[0], sweep.heights[1], n)
        for i in range(n):
            x = np.zeros(3)
            x[info["along"]] = alongs[i]
            x[info["cross"]] = crosses[i]
            x[1] = info["ground"] + heights[i]
            out.append(EvalPosition(st["name"], len(out), (float(x[0]), float(x[1]), float(x[2])),
                                    float(crosses[i] - info["center"]), float(np.min(np.abs(s - alongs[i]))),
                                    float(heights[i]), _near_crossing(x, st["name"], streets)))
    return out


def positions_from_array(manifest: Mapping[str, Any], positions: ArrayLike) -> list[EvalPosition]:
    """:class:`EvalPosition` for explicit world positions ``(P, 3)`` (m): each is assigned to the
    street whose volume holds it, else the street with the nearest probe line."""
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 1:
        raise ValueError(f"positions must have shape (P, 3) with P >= 1, got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("positions contain NaN or Inf")
    streets = manifest.get("streets") or []
    if not streets:
        raise ValueError("probe set has no streets: nothing to evaluate")
    infos = [_street_info(st) for st in streets]
    out = []
    for i, x in enumerate(p):
        def cost(inf: dict[str, Any]) -> float:
            inside = inf["fmin"] <= x[inf["cross"]] <= inf["fmax"] and inf["start"] <= x[inf["along"]] <= inf["end"]
            return -1.0 if inside else abs(x[inf["cross"]] - inf["center"]) + max(0.0, inf["start"] - x[inf["along"]],
                                                                                  x[inf["along"]] - inf["end"])
        k = int(np.argmin([cost(inf) for inf in infos]))
        inf = infos[k]
        out.append(EvalPosition(streets[k]["name"], i, (float(x[0]), float(x[1]), float(x[2])),
                                float(x[inf["cross"]] - inf["center"]), float(np.min(np.abs(inf["s"] - x[inf["along"]]))),
                                float(x[1] - inf["ground"]), _near_crossing(x, streets[k]["name"], streets)))
    return out


# --- truth -------------------------------------------------------------------------------

def truth_grid_size(w: float, n: int, min_grid: int = 8) -> int:
    """Face size of the grid a lobe of power ``w`` is compared on, for an ``n``-texel capture.

    ``n >> k`` for the largest ``k >= 1`` with ``n >> k >= max(0.9 sqrt(w + 2), min_grid)``: the
    lobe ladder's density (a face-center texel, ``2/M`` rad, spans about two lobe RMS angles
    ``1/sqrt(w + 2)``), so a ladder power ``w_k`` gets its own level's grid ``N_k``; at most
    ``n // 2``; ``n`` for the mirror.
    """
    if math.isinf(w):
        return n
    target = max(0.9 * math.sqrt(w + 2.0), float(min_grid))
    k = 1
    while (n >> (k + 1)) >= target:
        k += 1
    return max(n >> k, 1)


def filter_truth(cube: NDArray, w: float, quality: str = "default", ctx: Any = None,
                 min_grid: int = 8) -> NDArray[np.float32]:
    """``cube`` ``(6, N, N, C)`` filtered with the normalized ``cos^w`` lobe onto the grid of
    :func:`truth_grid_size` (``(6, M, M, C)``), at exactly ``w``.

    * Wide lobes (a solid-angle box reduction of ``cube`` of size ``S < N`` with at least
      :data:`TRUTH_TEXELS_PER_SIGMA` texels per lobe RMS angle exists): the float64 reference
      :func:`envcap.prefilter.filters.convolve_exact_dirs` over that reduction (no footprint truncation;
      the box adds at most ``1 / (12 * 3^2 / 4)`` ~ 1 % to the lobe's angular variance).
    * Otherwise the GLSL chain filter from the full-resolution cube, with a ladder whose last
      level is ``w`` (its other levels are made needle-sharp, i.e. cheap; the last level only
      depends on the input, so a ladder power of the bake is reproduced bit for bit).
    * ``w`` at or above the texel power of ``N``: the float64 reference at full resolution.
    """
    from envcap.core.lobes import LobeLadder, texel_power
    from envcap.prefilter.filters import convolve_exact, convolve_exact_dirs, omega_box_pyramid, prefilter_chain

    n = cube.shape[1]
    m = truth_grid_size(w, n, min_grid)
    k = 0
    while max(n >> k, 1) != m:
        k += 1
    need = TRUTH_TEXELS_PER_SIGMA * 2.0 * math.sqrt(w + 2.0)   # S >= texels * (2 / S) per sigma
    pyr = omega_box_pyramid(cube, k + 1)
    coarse = [p for p in pyr[1:] if p.shape[1] >= need and p.shape[1] >= m]
    if coarse:
        src = coarse[-1]
        return convolve_exact_dirs(src, w, cubemod.texel_directions(m)).astype(np.float32)
    tp = texel_power(n)
    if k < 1 or not w < tp - k:
        return convolve_exact(cube, w, m).astype(np.float32)
    powers = [tp - i for i in range(k)] + [float(w)]
    sizes = tuple(max(n >> i, 1) for i in range(k + 1))
    return prefilter_chain(cube, LobeLadder(sizes, tuple(powers)), quality=quality, ctx=ctx, progress=False)[-1]


TRUTH_TEXELS_PER_SIGMA = 3.0
"""Minimum source texels (face-center angle 2/S) per lobe RMS angle for the box-reduced truth."""


class TruthRenderer:
    """Fresh captures at evaluation positions, composited with the sky like the runtime.

    :meth:`filtered` returns ``{w: {"street": (6, M, M, 4), "sky": (6, M, M, 4),
    "sky_nosun": ...}}`` filtered separately at exactly ``w``; the truth is
    ``px.composite(street, sky)`` (``street.rgb + (1 - clamp(alpha)) * sky``, what the runtime
    computes from a chain).  :meth:`physical` filters the composite itself (the radiance that
    really arrives), to measure what compositing after filtering costs.
    """

    def __init__(self, scene: Any, resolution: int, ctx: Any, quality: str = "default") -> None:
        from envcap.capture.renderer import CubeCapture
        from envcap.sky.sky import sky_from_spec

        self.n = int(resolution)
        self.ctx = ctx
        self.quality = quality
        self.sky = sky_from_spec(scene.sky, scene.base_dir)
        self.sky_rgba = {True: _with_alpha(self.sky.cube(self.n)), False: _with_alpha(self.sky.cube(self.n, include_sun=False))}
        self._sky_cache: dict[tuple[float, bool], NDArray] = {}
        self.cap = CubeCapture.from_scene(scene, self.n, sky=self.sky, ctx=ctx)
        self.times = {"capture_s": 0.0, "filter_s": 0.0}

    def release(self) -> None:
        self.cap.release()

    def capture(self, position: Sequence[float]) -> Any:
        t0 = time.perf_counter()
        c = self.cap.capture(position)
        self.times["capture_s"] += time.perf_counter() - t0
        return c

    def sky_at(self, w: float, sun: bool) -> NDArray[np.float64]:
        if math.isinf(w):
            return self.sky_rgba[sun].astype(np.float64)
        if (w, sun) not in self._sky_cache:
            self._sky_cache[(w, sun)] = filter_truth(self.sky_rgba[sun], w, self.quality, self.ctx).astype(np.float64)
        return self._sky_cache[(w, sun)]

    def filtered(self, rgba: NDArray, powers: Sequence[float]) -> dict[float, dict[str, NDArray[np.float64]]]:
        t0 = time.perf_counter()
        out: dict[float, dict[str, NDArray[np.float64]]] = {}
        for w in powers:
            st = rgba.astype(np.float64) if math.isinf(w) else filter_truth(rgba, w, self.quality, self.ctx).astype(np.float64)
            out[w] = {"street": st, "sky": self.sky_at(w, True), "sky_nosun": self.sky_at(w, False)}
        self.times["filter_s"] += time.perf_counter() - t0
        return out

    def physical(self, rgba: NDArray, w: float, sun: bool = True) -> NDArray[np.float64]:
        """The composite radiance ``rgb + (1 - alpha) sky`` filtered at ``w`` (``(6, M, M, 3)``)."""
        comp = px.composite(rgba.astype(np.float64), self.sky_rgba[sun])
        return comp if math.isinf(w) else filter_truth(comp, w, self.quality, self.ctx).astype(np.float64)


def _with_alpha(rgb: NDArray) -> NDArray[np.float32]:
    return np.concatenate([rgb, np.ones(rgb.shape[:-1] + (1,), rgb.dtype)], axis=-1).astype(np.float32)


# --- predictions -------------------------------------------------------------------------

PredictFn = Callable[[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]


class Predictor:
    """Lookups of one probe set by every method of :data:`METHODS` (numpy twin of the runtime).

    :meth:`street_rgba` returns the (blended) premultiplied street RGBA a method fetches,
    :meth:`sky_rgb` the sky at the unshifted level, :meth:`predict` their composite (what
    ``envcap.runtime.parallax.sample_street`` returns for ``planes_mip`` and ``blend``).  ``x`` (3,) m,
    ``d`` (M, 3) unit, ``w`` (M,) lobe powers (``inf`` = mirror).  With ``sky`` (an
    :class:`envcap.sky.sky.Sky`) and ``ctx``, a second sky chain without the sun is filtered with the
    probe set's ladder (``sun=False`` lookups).
    """

    def __init__(self, probe_set: Any, sky: Any = None, ctx: Any = None, quality: str = "default") -> None:
        m = probe_set.manifest
        self.levels = [np.asarray(a) for a in probe_set.levels]
        # The baked sky map holds the sun only when the manifest says so (bake default: no sun,
        # the sun is an analytic light); the other variant is filtered here when a sky is given.
        baked_sun = bool(m.get("sky", {}).get("sun_in_map", True))
        self.baked_sun = baked_sun
        self.sky_levels = {baked_sun: [np.asarray(a) for a in probe_set.sky_levels]}
        pw = (m.get("lobes") or {}).get("powers")
        if not pw:
            pw = [lv.get("lobe_power") for lv in m["levels"]]
        if any(p is None for p in pw) or len(pw) != len(self.levels):
            raise ValueError("probe set has no lobe ladder (baked without filtered levels): cannot evaluate lobes")
        self.powers = [float(p) for p in pw]
        self.xk = px.lobe_table(self.powers)
        if sky is not None:
            from envcap.core.lobes import LobeLadder
            from envcap.prefilter.filters import prefilter_chain

            ns = self.sky_levels[baked_sun][0].shape[1]
            lad = LobeLadder(tuple(max(ns >> k, 1) for k in range(len(self.powers))), tuple(self.powers))
            self.sky_levels[not baked_sun] = prefilter_chain(_with_alpha(sky.cube(ns, include_sun=not baked_sun)), lad,
                                                             quality=quality, ctx=ctx, progress=False)
        self.distance = None if probe_set.distance is None else np.asarray(probe_set.distance, np.float64)
        self.streets: dict[str, dict[str, Any]] = {}
        for st in m["streets"]:
            along = 0 if st["axis"] == "x" else 2
            probes = sorted(st["probes"], key=lambda q: q["position"][along])
            nominal = np.array([[q["planes"][k] for k in ("facade_min", "facade_max", "ground")] for q in probes], float)
            fitted = nominal.copy()
            for i, q in enumerate(probes):
                fp = q.get("fitted_planes") or {}
                for j, k in enumerate(("facade_min", "facade_max", "ground")):
                    if fp.get(k) is not None:
                        fitted[i, j] = float(fp[k])
                if not fitted[i, 1] > fitted[i, 0]:
                    fitted[i] = nominal[i]
            self.streets[st["name"]] = {
                "along": along,
                "pos": np.array([q["position"] for q in probes], float),
                "layers": np.array([int(q["layer"]) for q in probes], np.int64),
                "nominal": nominal, "fitted": fitted,
            }

    def local_street(self, name: str, x: NDArray[np.float64], fitted: bool = False) -> px.RuntimeStreet:
        """The runtime street of the ``LOCAL_PROBES`` probes nearest ``x`` along street ``name``
        (the runtime holds at most ``MAX_PROBES``; selection and blending only need neighbours)."""
        if name not in self.streets:
            raise ValueError(f"probe set has no street named {name!r}")
        st = self.streets[name]
        s = st["pos"][:, st["along"]]
        idx = np.sort(np.argsort(np.abs(s - x[st["along"]]), kind="stable")[:LOCAL_PROBES])
        planes = st["fitted"] if fitted else st["nominal"]
        return px.RuntimeStreet(st["along"], st["pos"][idx], planes[idx], st["layers"][idx])

    def _z(self, w: NDArray[np.float64]) -> NDArray[np.float64]:
        return px.clamp_level(px.z_of_w(w, self.xk), len(self.powers))

    def _fetch(self, layer: NDArray, r: NDArray, ratio: NDArray, w: NDArray, shift: bool) -> NDArray:
        from envcap.core import cube_sampling

        zs = self._z(px.shift_power(w, ratio) if shift else w)
        return cube_sampling.sample_cube_array(self.levels, r, layer, zs)

    def sky_rgb(self, d: ArrayLike, w: ArrayLike, sun: bool | None = None) -> NDArray[np.float64]:
        """Sky ``(M, 4)`` at the original directions and the unshifted level ``z(w)``.

        ``sun``: with the sun splatted into the sky map or not; ``None``: the sky as baked."""
        from envcap.core import cube_sampling

        if sun is None:
            sun = self.baked_sun
        if sun not in self.sky_levels:
            raise ValueError("no sun-free sky chain: construct the Predictor with sky= and ctx=")
        d = np.asarray(d, np.float64).reshape(-1, 3)
        w = np.broadcast_to(np.asarray(w, np.float64), d.shape[:1])
        return cube_sampling.sample_cube(self.sky_levels[sun], d, self._z(w))

    def street_rgba(self, method: str, street: str, x: ArrayLike, d: ArrayLike, w: ArrayLike) -> NDArray[np.float64]:
        """Premultiplied street RGBA ``(M, 4)`` that ``method`` fetches from the probes."""
        x = np.asarray(x, np.float64).reshape(3)
        d = np.asarray(d, np.float64).reshape(-1, 3)
        w = np.broadcast_to(np.asarray(w, np.float64), d.shape[:1])
        if method not in METHODS:
            raise ValueError(f"unknown method {method!r}; known: {', '.join(METHODS)}")
        rs = self.local_street(street, x, fitted=method in ("fitted_planes_mip", "depth_reproject"))
        if method == "blend":
            i0, i1, t = px.probe_pair(x[rs.along], rs.along_coords)
            acc = np.zeros((d.shape[0], 4))
            for i, wt in ((int(i0), 1.0 - float(t)), (int(i1), float(t))):
                r, ratio = px.parallax(x, d, rs.positions[i], rs.planes[i], rs.along)
                acc += wt * self._fetch(np.full(d.shape[0], rs.layers[i]), r, ratio, w, shift=True)
            return acc
        i = int(px.nearest_probe(x[rs.along], rs.along_coords))
        p, planes, layer = rs.positions[i], rs.planes[i], np.full(d.shape[0], rs.layers[i])
        if method == "nearest":
            return self._fetch(layer, d, np.ones(d.shape[0]), w, shift=False)
        if method == "depth_reproject":
            if self.distance is None:
                raise ValueError("depth_reproject needs the probe set's distance channel (EXR files)")
            r, ratio = depth_reproject(x, d, p, self.distance[rs.layers[i]], planes, rs.along)
        else:
            r, ratio = px.parallax(x, d, p, planes, rs.along)
        return self._fetch(layer, r, ratio, w, shift=method != "planes")

    def predict(self, method: str, street: str, x: ArrayLike, d: ArrayLike, w: ArrayLike,
                sun: bool | None = None) -> NDArray[np.float64]:
        """Radiance ``(M, 3)``: street RGBA of ``method`` composited over the sky."""
        return px.composite(self.street_rgba(method, street, x, d, w), self.sky_rgb(d, w, sun))


def depth_reproject(x: ArrayLike, d: ArrayLike, p: ArrayLike, distance: NDArray, planes: ArrayLike, along: int,
                    steps: int = 32, t_min: float = 0.05, t_max: float = 2000.0, thickness: float = 0.15,
                    refine: int = 6) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reprojection through a probe's distance channel: ``(r, ratio)`` like :func:`envcap.runtime.parallax.parallax`.

    ``x`` (3,) shading point, ``d`` (M, 3) unit directions, ``p`` (3,) probe, ``distance``
    ``(6, N, N)`` radial distance (m, 0 = sky), ``planes`` the fallback planes.  The ray
    ``x + t d`` is sampled at ``steps`` geometric ``t`` in [t_min, t_max] m; a sample is *behind*
    when its distance from ``p`` exceeds the stored distance towards it (nearest texel).  The
    first behind sample within ``thickness`` (relative) of the surface is a hit, refined by
    bisection; ``r`` points from ``p`` to it, ``ratio = |hit - p| / |hit - x|`` (clamped like the
    runtime).  Rays whose behind samples are all too deep (occluded from the probe) use the
    three-plane result; rays never behind anything see the sky (``r = d``, ratio 1).
    """
    x = np.asarray(x, np.float64).reshape(3)
    d = np.asarray(d, np.float64).reshape(-1, 3)
    p = np.asarray(p, np.float64).reshape(3)
    D = np.asarray(distance, np.float64)
    n = D.shape[1]
    Dinf = np.where(D > 0, D, np.inf)
    ts = np.geomspace(t_min, t_max, steps)

    def probe_depth(q: NDArray) -> tuple[NDArray, NDArray]:
        v = q - p
        ln = np.linalg.norm(v, axis=-1)
        v = np.where((ln > 1e-9)[..., None], v, d if v.ndim == 2 else d[:, None, :])
        f, j, i = cubemod.direction_to_texel(v, n)
        return ln, Dinf[f, j, i]

    q = x + ts[None, :, None] * d[:, None, :]                      # (M, S, 3)
    ln, depth = probe_depth(q)
    behind = ln >= depth
    near = behind & (ln - depth <= thickness * depth + 0.1)
    any_behind = behind.any(axis=1)
    hit = near.any(axis=1)
    k = np.argmax(near, axis=1)
    t_hi = ts[k]
    t_lo = np.where(k > 0, ts[np.maximum(k - 1, 0)], 0.0)
    for _ in range(refine):
        tm = 0.5 * (t_lo + t_hi)
        lm, dm = probe_depth(x + tm[:, None] * d)
        b = lm >= dm
        t_hi = np.where(b, tm, t_hi)
        t_lo = np.where(b, t_lo, tm)
    t = t_hi
    h = x + t[:, None] * d
    rv = h - p
    dp = np.linalg.norm(rv, axis=1)
    ok = hit & (dp > px.MIN_DIST)
    r = np.where(ok[:, None], rv / np.where(ok, dp, 1.0)[:, None], d)
    ratio = np.clip(dp / np.maximum(t, px.MIN_DIST), 1.0 / px.MAX_RATIO, px.MAX_RATIO)
    ratio = np.where(ok, ratio, 1.0)
    # occluded from the probe: three planes; nothing behind at all: sky (r = d, ratio 1)
    fb = ~hit & any_behind
    if np.any(fb):
        r_pl, ratio_pl = px.parallax(x, d[fb], p, planes, along)
        r[fb], ratio[fb] = r_pl, ratio_pl
    return r, ratio


# --- evaluation --------------------------------------------------------------------------

def _frames(along: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Shading frames (F, 3, 3) rows T, B, N (world) and local views (F, 3) for the shading metric:
    normals up, +-cross, +-along; views at 30 and 70 degrees from the normal."""
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


def _shade(env: Callable[[NDArray, NDArray], NDArray], mat: Material, frames: NDArray, views: NDArray) -> NDArray:
    C = np.array(mat.C, np.float64).reshape(-1, 3)
    return px.shade_lafortune(env, views, frames, mat.rho_d, C, np.array(mat.w, np.float64),
                              np.array(mat.rho_s, np.float64).reshape(-1, 3))


def _exact_env(cube3: NDArray) -> Callable[[NDArray, NDArray], NDArray]:
    from envcap.prefilter.filters import convolve_exact_dirs

    def env(dirs: NDArray, w: NDArray) -> NDArray:
        dirs = np.asarray(dirs, np.float64)
        w = np.broadcast_to(np.asarray(w, np.float64), dirs.shape[:-1])
        out = np.empty(dirs.shape[:-1] + (3,))
        for wv in np.unique(w):
            m = w == wv
            out[m] = convolve_exact_dirs(cube3, float(wv), dirs[m])
        return out
    return env


def _luminance(rgb: NDArray) -> NDArray:
    from envcap.evaluate.metrics import luminance

    return luminance(rgb)


def evaluate_scene(
    scene: Any,
    probe_set: Any,
    *,
    positions: ArrayLike | None = None,
    sweep: Sweep = DEFAULT_SWEEP,
    methods: Sequence[str] = METHODS,
    lobe_powers: Sequence[float] = DEFAULT_LOBE_POWERS,
    resolution: int | None = None,
    ctx: Any = None,
    materials: Sequence[Material] = MATERIALS,
    keep_worst: int = 3,
    floor_probes: int = 2,
    sun_variants: Sequence[bool] = (True, False),
    progress: bool | None = None,
) -> EvaluationResult:
    """Evaluate the probe set ``probe_set`` of ``scene`` against fresh captures.

    ``positions``: explicit world positions ``(P, 3)`` (m), else :func:`sample_positions` with
    ``sweep``.  ``methods``: subset of :data:`METHODS`.  ``lobe_powers``: ``inf`` (mirror) and/or
    powers ``w >= 0``.  ``resolution``: face size of the truth captures (default: the probe
    set's, at most 64).  ``sun_variants``: ``True`` evaluates with the sun splatted into the sky map
    (of truth and prediction), ``False`` with the sun taken out of the sky of both truth and prediction (an engine
    that draws the sun as an analytic light).  ``materials``: Eq. 3 shading metric (empty:
    skipped).  ``keep_worst``: keep truth and predictions of the worst positions (by
    ``planes_mip`` at w = 64 with the sun) for image strips.  ``floor_probes``: also evaluate at
    this many probe positions (the evaluator's own floor) and measure there what compositing the
    sky after filtering costs.  Returns an :class:`EvaluationResult`.
    """
    from tqdm import tqdm

    from envcap.evaluate.metrics import relative_error_map, relative_rmse

    t_all = time.perf_counter()
    manifest = probe_set.manifest
    ps_scene = (manifest.get("scene") or {}).get("name")
    if ps_scene is not None and ps_scene != scene.name:
        raise ValueError(f"probe set was baked from scene {ps_scene!r}, not {scene.name!r}")
    methods = list(dict.fromkeys(methods))
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise ValueError(f"unknown or no method(s) {bad}; known: {', '.join(METHODS)}")
    if "depth_reproject" in methods and probe_set.distance is None:
        print("envcap: warning: probe set has no distance channel: skipping depth_reproject", file=sys.stderr)
        methods.remove("depth_reproject")
    lps = []
    for w in lobe_powers:
        w = float(w)
        if math.isnan(w) or w < 0:
            raise ValueError(f"lobe powers must be >= 0 or inf, got {w}")
        lps.append(w)
    if not lps:
        raise ValueError("no lobe powers to evaluate")
    suns = list(dict.fromkeys(bool(v) for v in sun_variants))
    if not suns:
        raise ValueError("sun_variants must hold True and/or False")
    primary = False if False in suns else True   # the variant of the strips and of worst-position picks
    n = int(resolution) if resolution is not None else min(int(probe_set.resolution), 64)
    if n < 4:
        raise ValueError(f"evaluation resolution must be >= 4 texels per face, got {n}")
    pos_list = sample_positions(manifest, sweep) if positions is None else positions_from_array(manifest, positions)
    quality = str(manifest.get("quality") or "default")
    own = ctx is None
    if own:
        from envcap.gpu.gl import create_context

        ctx = create_context()
    truth_r = TruthRenderer(scene, n, ctx, quality=quality)
    t0 = time.perf_counter()
    predictor = Predictor(probe_set, sky=truth_r.sky if False in suns else None, ctx=ctx, quality=quality)
    t_setup = time.perf_counter() - t0
    times = {"captures_s": 0.0, "filtering_s": 0.0, "predictions_s": 0.0, "shading_s": 0.0, "setup_s": t_setup}
    rows: list[dict[str, Any]] = []
    shading: list[dict[str, Any]] = []
    kept: dict[int, dict[str, Any]] = {}
    floor_rows: list[dict[str, Any]] = []
    composite_rows: list[dict[str, Any]] = []
    dirs_cache: dict[int, NDArray] = {}
    sky_cache: dict[tuple[int, float, bool], NDArray] = {}

    def dirs_of(m: int) -> NDArray:
        if m not in dirs_cache:
            dirs_cache[m] = cubemod.texel_directions(m).reshape(-1, 3)
        return dirs_cache[m]

    def pred_sky(m: int, w: float, sun: bool) -> NDArray:
        if (m, w, sun) not in sky_cache:
            d = dirs_of(m)
            sky_cache[(m, w, sun)] = predictor.sky_rgb(d, np.full(d.shape[0], w), sun)
        return sky_cache[(m, w, sun)]

    def run_position(ep: EvalPosition, keep: bool, want_shading: bool, physical: bool = False) -> tuple[list, list, dict]:
        x = np.array(ep.position)
        cap = truth_r.capture(x)
        parts = truth_r.filtered(cap.rgba, lps)
        out_rows, out_shade, store = [], [], {"truth": {}, "pred": {}}
        misfit = plane_misfit(x, cap.distance, cap.rgba[..., 3], predictor.local_street(ep.street, x))
        t0 = time.perf_counter()
        for w, part in parts.items():
            m = part["street"].shape[1]
            d = dirs_of(m)
            truth = {sun: px.composite(part["street"], part["sky" if sun else "sky_nosun"]) for sun in suns}
            if physical:
                tp = truth_r.physical(cap.rgba, w)
                composite_rows.append({"position_index": ep.index, "lobe_power": _lp_key(w),
                                       "rel_rmse": relative_rmse(truth[True], tp) if True in truth else float("nan")})
            if keep:
                store["truth"][w] = truth[primary]
            for meth in methods:
                st = predictor.street_rgba(meth, ep.street, x, d, np.full(d.shape[0], w)).reshape(6, m, m, 4)
                if not np.all(np.isfinite(st)):
                    raise ValueError(f"method {meth} produced NaN/Inf at {ep.position}")
                for sun in suns:
                    pr = px.composite(st, pred_sky(m, w, sun).reshape(6, m, m, -1))
                    out_rows.append({"street": ep.street, "position_index": ep.index, "method": meth,
                                     "lobe_power": _lp_key(w), "sun": sun, "rel_rmse": relative_rmse(pr, truth[sun]),
                                     "lateral_m": ep.lateral, "along_m": ep.along, "height_m": ep.height,
                                     "near_crossing": ep.near_crossing, "plane_misfit": misfit,
                                     "position": list(ep.position)})
                    if keep and sun == primary:
                        store["pred"][(meth, w)] = pr
        times["predictions_s"] += time.perf_counter() - t0
        if want_shading and materials:
            t0 = time.perf_counter()
            frames, views = _frames(predictor.streets[ep.street]["along"])
            for sun in suns:
                truth_env = _exact_env(px.composite(cap.rgba.astype(np.float64), truth_r.sky_rgba[sun]))
                for mat in materials:
                    lt = _luminance(_shade(truth_env, mat, frames, views))
                    den = float(np.sqrt(np.mean(lt ** 2)))
                    for meth in methods:
                        def env(dd: NDArray, ww: NDArray, meth: str = meth, sun: bool = sun) -> NDArray:
                            shp = dd.shape[:-1]
                            return predictor.predict(meth, ep.street, x, dd.reshape(-1, 3), np.ravel(ww), sun).reshape(shp + (3,))
                        lp = _luminance(_shade(env, mat, frames, views))
                        num = float(np.sqrt(np.mean((lp - lt) ** 2)))
                        out_shade.append({"street": ep.street, "position_index": ep.index, "method": meth, "sun": sun,
                                          "material": mat.name, "rel_err": num / den if den > 0 else float(num > 0),
                                          "lateral_m": ep.lateral, "near_crossing": ep.near_crossing})
            times["shading_s"] += time.perf_counter() - t0
        return out_rows, out_shade, store

    try:
        for ep in tqdm(pos_list, desc=f"evaluate {scene.name}", unit="pos", disable=None if progress is None else not progress):
            r, s, _ = run_position(ep, False, True)
            rows += r
            shading += s
        # the evaluator's own floor: the probes' own positions (every method must match the truth)
        fl_pos = [q["position"] for st in manifest["streets"][:1] for q in st["probes"][: max(0, floor_probes)]]
        if fl_pos:
            for ep in positions_from_array(manifest, np.array(fl_pos)):
                r, _, _ = run_position(ep, False, False, physical=True)
                floor_rows += r
        # worst positions, re-run with their cubes kept for the image strips
        key = "planes_mip" if "planes_mip" in methods else methods[0]
        wkey = 64.0 if 64.0 in lps else lps[0]
        cand = [(r["rel_rmse"], r["position_index"]) for r in rows
                if r["method"] == key and r["lobe_power"] == _lp_key(wkey) and r["sun"] == primary]
        for _, idx in sorted(cand, reverse=True)[: max(0, keep_worst)]:
            _, _, store = run_position(pos_list[idx], True, False)
            store["maps"] = {k: relative_error_map(v, store["truth"][k[1]]) for k, v in store["pred"].items()}
            kept[idx] = store
    finally:
        truth_r.release()
        if own:
            ctx.release()
    times["captures_s"] = truth_r.times["capture_s"]
    times["filtering_s"] = truth_r.times["filter_s"]
    times["total_s"] = time.perf_counter() - t_all
    for r in rows + floor_rows + shading + composite_rows:
        r["scene"] = scene.name
    summary = summarize(scene.name, rows)
    meta = {"resolution": n, "probe_resolution": int(probe_set.resolution), "probe_spacing": manifest.get("probe_spacing"),
            "probe_count": int(probe_set.layer_count), "methods": methods, "lobe_powers": [_lp_key(w) for w in lps],
            "sun_variants": suns, "primary_sun": primary, "quality": quality,
            "sweep": {"per_street": sweep.per_street, "margin_m": sweep.margin, "end_margin_m": sweep.end_margin,
                      "heights_m": list(sweep.heights), "seed": sweep.seed} if positions is None else "explicit",
            "n_positions": len(pos_list), "grid_sizes": {_lp_label(w): truth_grid_size(w, n) for w in lps},
            "materials": [m.name for m in materials],
            "composite_error": summarize(scene.name, [{**r, "method": "composite_after_filtering", "sun": True}
                                                      for r in composite_rows])}
    return EvaluationResult(scene.name, pos_list, rows, summary, shading, times, meta,
                            floor=summarize(scene.name, floor_rows),
                            strips={"positions": kept, "key_method": key, "key_power": wkey})


def plane_misfit(x: ArrayLike, distance: NDArray, alpha: NDArray, street: px.RuntimeStreet, rel: float = 0.2,
                 abs_m: float = 0.25) -> float:
    """Share of the sphere (solid-angle weighted, 0..1) seen from ``x`` where the three nominal
    planes of the nearest probe are the wrong model: the true hit distance (``distance``
    ``(6, N, N)`` m from ``x``, geometry where ``alpha > 0.5``) and the planes' exit distance
    differ by more than ``rel`` (relative) + ``abs_m`` (m), or one of them sees the sky (no
    hit within 1 km) and the other does not.  Gaps, crossings, setbacks and open squares raise it.
    """
    x = np.asarray(x, np.float64)
    n = distance.shape[1]
    d = cubemod.texel_directions(n)
    i = int(px.nearest_probe(x[street.along], street.along_coords))
    planes = street.planes[i]
    xc = px.clamp_to_street(x, planes, street.along)
    t_model = px.exit_distance(xc, d, planes, street.along)
    geo = (np.asarray(alpha) > 0.5) & (np.asarray(distance) > 0)
    t_true = np.where(geo, np.asarray(distance, np.float64), np.inf)
    far = 1000.0
    sky_true, sky_model = ~(t_true < far), ~(t_model < far)
    with np.errstate(invalid="ignore"):
        close = np.abs(t_true - t_model) <= rel * np.minimum(t_true, t_model) + abs_m
    ok = (sky_true & sky_model) | (~sky_true & ~sky_model & close)
    om = cubemod.texel_solid_angles(n)
    return float(np.sum(om[~ok]) / (4.0 * np.pi))


def summarize(scene: str, rows: Sequence[Mapping[str, Any]], by: Sequence[str] = ("method", "lobe_power", "sun")) -> list[dict[str, Any]]:
    """Aggregate per-position rows into ``{scene, <by...>, rel_rmse (mean), median, p90, max, n_positions}``."""
    groups: dict[tuple, list[float]] = {}
    for r in rows:
        groups.setdefault(tuple(r.get(k) for k in by), []).append(float(r["rel_rmse"]))
    out = []
    for k, v in groups.items():
        a = np.array(v)
        out.append({"scene": scene, **dict(zip(by, k)), "rel_rmse": float(a.mean()), "median": float(np.median(a)),
                    "p90": float(np.percentile(a, 90)), "max": float(a.max()), "n_positions": int(a.size)})
    return out


def quick_evaluation(scene: Any, probe_set_dir: str | Path, out_dir: str | Path, ctx: Any = None) -> Path:
    """A short evaluation (6 positions per street, mirror + w in {256, 64, 16}, <~30 s) of the
    probe set in ``probe_set_dir``; writes the report into ``out_dir`` (atomically), prints
    where the report and pictures are and returns the path of ``report.md``."""
    from envcap.evaluate.report import write_report
    from envcap.probeset.store import read_probe_set

    ps = read_probe_set(probe_set_dir)
    res = evaluate_scene(scene, ps, sweep=QUICK_SWEEP, lobe_powers=(math.inf, 256.0, 64.0, 16.0),
                         resolution=min(ps.resolution, 32), ctx=ctx, keep_worst=2)
    out = write_report([res], out_dir)
    report = Path(out) / "report.md"
    print(f"evaluation: {report} (plots and worst-position strips in {Path(out)})")
    return report


def street_segment(scene: Any, length: float, center: float | None = None) -> Any:
    """A copy of ``scene`` whose streets are cut to ``length`` m around ``center`` (default: each
    street's middle), for baking a short probe set; the geometry is unchanged."""
    import dataclasses

    if not (math.isfinite(length) and length > 0):
        raise ValueError(f"segment length must be a positive number of meters, got {length!r}")
    streets = []
    for st in scene.streets:
        c = 0.5 * (st.start + st.end) if center is None else float(center)
        a, b = max(st.start, c - 0.5 * length), min(st.end, c + 0.5 * length)
        if not b > a:
            raise ValueError(f"street {st.name!r} ({st.start}..{st.end}) has no part within {length} m of {c}")
        streets.append(dataclasses.replace(st, start=a, end=b))
    return dataclasses.replace(scene, streets=streets)
