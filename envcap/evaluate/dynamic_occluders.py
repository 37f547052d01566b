"""Street evaluation of the dynamic terms: a ring of spheres around a point, fresh captures with
the spheres in the scene as truth, Eq. 3 shading from the probes without and with the dynamic terms.

Per position ``x`` and ring (:class:`Ring`): the spheres are added to the scene
(:func:`envcap.scene.occluder_spheres.with_spheres`) and a cube is captured at ``x`` (the truth,
composited with the sky).  For the Eq. 3 materials of the shading metric
(:data:`envcap.evaluate.shading.MATERIALS`) in the frames of
:func:`envcap.evaluate.shading.shading_frames`, luminance is computed from

* ``truth``: the exact float64 lobe integral of the capture with the spheres;
* ``static``: the probe set looked up by a runtime method (no spheres: what the runtime does now);
* ``static+MODEL``: ``static`` minus the blocked and plus the bounced light of the runtime's
  dynamic terms (:func:`envcap.dynamic.terms.dynamic_terms`) in a model of
  :data:`envcap.evaluate.dynamic_terms.MODELS`;
* ``oracle`` and ``oracle+MODEL``: the same with a fresh capture at ``x`` *without* the spheres as
  the static environment (no parallax error: what remains is the dynamic terms' own error).

The error is the evaluator's shading metric: relative RMS of luminance over the frames.  Coverage:
``sky_hidden``, the fraction of the visible sky's solid angle that the spheres hide
(:func:`visible_sky_hidden`), and ``coverage``, the fraction of the upper hemisphere they cover
(:func:`sky_coverage`).  Definitions and results: ``docs/dynamic.md``, "Street evaluation".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from envcap.capture.renderer import CubeCapture
from envcap.core import cube as cubemod
from envcap.core.checks import positive_int
from envcap.core.color import luminance
from envcap.evaluate.dynamic_terms import DEFAULT_MODELS, MODELS, lafortune, model_terms, shade_model, sphere_buffer
from envcap.evaluate.predict import Predictor
from envcap.evaluate.shading import MATERIALS, Material, exact_environment, shade, shading_frames
from envcap.evaluate.truth import with_alpha
from envcap.runtime.sampling import composite
from envcap.runtime.shading import EnvironmentFn
from envcap.scene.occluder_spheres import OccluderSphere, ring_of_spheres, with_spheres

COVERAGE_BINS: tuple[float, ...] = (0.0, 0.05, 0.10, 0.20, 0.30, 0.45)
"""Edges of the coverage bins of the summary (fractions: of the visible sky hidden, or of the upper hemisphere)."""
ALBEDOS: tuple[tuple[float, float, float], ...] = ((0.55, 0.45, 0.35), (0.2, 0.25, 0.3))
"""Sphere albedos, alternating around a ring (clothes: a light warm one and a dark cool one)."""


@dataclass(frozen=True)
class Ring:
    """``count`` spheres of ``radius`` m, centers ``distance`` m from the point at ``elevation_deg``
    above its horizontal plane (:func:`envcap.scene.occluder_spheres.ring_of_spheres`)."""

    count: int
    distance: float
    radius: float
    elevation_deg: float = 0.0

    def spheres(self, point: ArrayLike, azimuth_deg: float = 22.5) -> list[OccluderSphere]:
        base = ring_of_spheres(point, self.count, self.distance, self.radius, self.elevation_deg, azimuth_deg)
        return [OccluderSphere(s.center, s.radius, ALBEDOS[i % len(ALBEDOS)]) for i, s in enumerate(base)]

    @property
    def label(self) -> str:
        return f"{self.count}x r{self.radius:g} at {self.distance:g} m, {self.elevation_deg:g}°"


DEFAULT_RINGS: tuple[Ring, ...] = (
    Ring(8, 4.0, 0.25), Ring(8, 2.0, 0.4), Ring(8, 1.5, 0.5), Ring(8, 2.0, 0.4, 45.0), Ring(8, 1.5, 0.5, 20.0),
    Ring(8, 2.0, 0.5, 35.0), Ring(6, 2.5, 0.6, 50.0), Ring(6, 1.5, 0.45, 45.0), Ring(6, 1.2, 0.4, 40.0),
    Ring(6, 1.5, 0.35, 60.0), Ring(8, 1.0, 0.3, 45.0), Ring(6, 1.0, 0.45, 35.0),
)
"""Rings of people-sized spheres 1-4 m from the point, at its height and above (heads around a
child): in the canyon they hide 0-43 % of the visible sky and cover 1-62 % of the upper hemisphere."""


def sky_coverage(point: ArrayLike, spheres: Sequence[OccluderSphere], samples: int = 200_000) -> float:
    """Fraction of the upper hemisphere (directions with y > 0) seen from ``point`` (3,) m that is
    covered by at least one sphere: a Fibonacci lattice of ``samples`` directions uniform in solid
    angle, each tested against every sphere's cap (independent of the capture and of Eq. 4-7)."""
    p = np.asarray(point, np.float64)
    i = np.arange(samples) + 0.5
    y = 1.0 - i / samples                   # uniform in y on (0, 1): uniform in solid angle
    phi = math.pi * (3.0 - math.sqrt(5.0)) * i
    r = np.sqrt(1 - y * y)
    u = np.stack([r * np.cos(phi), y, r * np.sin(phi)], axis=-1)
    hit = np.zeros(samples, bool)
    for s in spheres:
        v = np.asarray(s.center) - p
        ell = float(np.linalg.norm(v))
        if ell <= s.radius:
            return 1.0
        cos_theta = math.sqrt(max(0.0, 1 - (s.radius / ell) ** 2))
        hit |= u @ (v / ell) >= cos_theta
    return float(hit.mean())


def visible_sky_hidden(plain_rgba: NDArray, with_rgba: NDArray) -> float:
    """Fraction of the visible sky's solid angle (texels with alpha 0 in ``plain_rgba``, the capture
    without spheres, ``(6, N, N, 4)``) that is covered (alpha > 0) in ``with_rgba``, the capture with them."""
    omega = cubemod.texel_solid_angles(plain_rgba.shape[1])
    sky = plain_rgba[..., 3] <= 0
    total = float(np.sum(omega[sky]))
    return float(np.sum(omega[sky & (with_rgba[..., 3] > 0)])) / total if total > 0 else 0.0


def sphere_mask(plain: Any, withs: Any) -> NDArray[np.bool_]:
    """Texels ``(6, N, N)`` where the capture with spheres (``withs``) sees a sphere: covered now, and
    sky or farther before (``plain``; captures with ``rgba`` and ``distance``)."""
    now = withs.rgba[..., 3] > 0
    return now & ((plain.rgba[..., 3] <= 0) | (withs.distance < plain.distance * (1 - 1e-4)))


def true_terms(plain: Any, withs: Any, sky_rgba: NDArray, dirs: NDArray, w: float) -> tuple[NDArray, NDArray]:
    """The exact blocked and bounced light ``(M, 3)`` of the normalized ``cos^w`` lobes at ``dirs``
    ``(M, 3)``: sums over the sphere texels (:func:`sphere_mask`) of the lobe weight times the
    radiance without (blocked) and with (bounced) the spheres, over the whole lobe's weight (the
    same texel quadrature as the truth: truth - oracle = bounced - blocked)."""
    n = plain.rgba.shape[1]
    u = cubemod.texel_directions(n).reshape(-1, 3)
    om = cubemod.texel_solid_angles(n).reshape(-1)
    mask = sphere_mask(plain, withs).reshape(-1)
    lob = np.maximum(np.asarray(dirs, np.float64) @ u.T, 0.0) ** w * om
    lob /= lob.sum(axis=1, keepdims=True)
    rad = [composite(c.rgba.astype(np.float64), sky_rgba).reshape(-1, 3) for c in (plain, withs)]
    return lob[:, mask] @ rad[0][mask], lob[:, mask] @ rad[1][mask]


def coverage_bin(c: float, edges: Sequence[float] = COVERAGE_BINS) -> tuple[str, float]:
    """The label ``"lo-hi %"`` and lower edge of the bin holding coverage ``c``."""
    for lo, hi in zip(edges[:-1], edges[1:]):
        if lo <= c < hi:
            return f"{100 * lo:g}-{100 * hi:g} %", lo
    return f">= {100 * edges[-1]:g} %", edges[-1]


def rel_err(pred: NDArray, truth: NDArray) -> float:
    """Relative RMS of luminance over frames (the evaluator's shading metric)."""
    lt, lp = luminance(truth), luminance(pred)
    den = float(np.sqrt(np.mean(lt ** 2)))
    num = float(np.sqrt(np.mean((lp - lt) ** 2)))
    return num / den if den > 0 else float(num > 0)


def upper_sky(sky_rgba: NDArray) -> EnvironmentFn:
    """``E_w`` of the sky cube ``(6, N, N, 4)`` with directions below the horizon set to 0 (the
    light the capture's ``sky_light`` puts on surfaces), exact float64 lobe integral."""
    rgb = sky_rgba[..., :3].astype(np.float64).copy()
    rgb[cubemod.texel_directions(rgb.shape[1])[..., 1] < 0] = 0.0
    return exact_environment(rgb)


def evaluate_rings(scene: Any, predictor: Predictor, street: str, positions: Sequence[Sequence[float]], *,
                   rings: Sequence[Ring] = DEFAULT_RINGS, ctx: Any, resolution: int = 64, method: str = "planes_mip",
                   materials: Sequence[Material] = MATERIALS, suns: Sequence[bool] = (False,),
                   models: Sequence[str] = DEFAULT_MODELS, oracle: bool = True) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """``(rows, terms)``.  ``rows``: ``{position, xyz, ring, coverage, sky_hidden, sun, material,
    variant, rel_err}``, one per position x ring x sun x material x variant (module docstring).
    ``terms``: per position x ring x sun x model, the blocked and bounced luminance of the diffuse
    lobes about the frames' normals, true (:func:`true_terms`) and modelled on the oracle
    (``true_blocked``, ``model_blocked``, ``true_bounced``, ``model_bounced``, summed over the
    normals).  ``predictor`` holds the probe set of ``scene`` (with both sky variants when ``False``
    is in ``suns``); ``street``: the street the positions are on; ``resolution``: face size of the
    fresh captures; ``models``: names in :data:`MODELS`."""
    bad = [m for m in models if m not in MODELS]
    if bad:
        raise ValueError(f"unknown dynamic model(s) {bad}; known: {', '.join(MODELS)}")
    if positive_int(resolution, "capture resolution") < 4:
        raise ValueError(f"capture resolution must be >= 4 texels per face, got {resolution}")
    sky = scene.sky.build()
    sky_rgba = {s: with_alpha(sky.cube(resolution, include_sun=s)) for s in suns}
    sky_light = {s: upper_sky(sky_rgba[s]) for s in suns}
    frames, views = shading_frames(predictor.streets[street].along)
    normals = frames[:, 2, :]
    un = slice(None, None, 2)   # each normal appears in two frames
    diffuse = lafortune(Material("unit diffuse", (1.0, 1.0, 1.0)))
    rows: list[dict[str, Any]] = []
    terms: list[dict[str, Any]] = []

    def capture(sc: Any, x: NDArray) -> Any:
        with CubeCapture.from_scene(sc, resolution, sky=sky, ctx=ctx) as cap:
            return cap.capture(x)

    for pi, pos in enumerate(positions):
        x = np.asarray(pos, np.float64)
        plain = capture(scene, x)
        for ring in rings:
            spheres = ring.spheres(x)
            buf = sphere_buffer(spheres)
            withs = capture(with_spheres(scene, spheres), x)
            base0 = {"position": pi, "xyz": [float(v) for v in x], "ring": ring.label, "coverage": sky_coverage(x, spheres),
                     "sky_hidden": visible_sky_hidden(plain.rgba, withs.rgba)}
            for sun in suns:
                t_env = exact_environment(composite(withs.rgba.astype(np.float64), sky_rgba[sun]))
                o_env = exact_environment(composite(plain.rgba.astype(np.float64), sky_rgba[sun]))
                tb, tc = (float(luminance(v).sum()) for v in true_terms(plain, withs, sky_rgba[sun], normals[un], 1.0))
                for name in models:
                    mb, mc = (float(luminance(v).sum()) for v in model_terms(
                        name, o_env, sky_light[sun], x, frames[un], views[un], diffuse, buf))
                    terms.append({**base0, "sun": sun, "model": name, "true_blocked": tb, "true_bounced": tc,
                                  "model_blocked": mb, "model_bounced": mc})

                def probes(d: NDArray, w: NDArray, x: NDArray = x, sun: bool = sun) -> NDArray:
                    return predictor.predict(method, street, x, d.reshape(-1, 3), np.ravel(w), sun).reshape(d.shape[:-1] + (3,))
                statics: dict[str, EnvironmentFn] = {"static": probes}
                if oracle:
                    statics["oracle"] = o_env
                for mat in materials:
                    truth = shade(t_env, mat, frames, views)
                    base = {**base0, "sun": sun, "material": mat.name}
                    for sname, senv in statics.items():
                        rows.append({**base, "variant": sname, "rel_err": rel_err(shade(senv, mat, frames, views), truth)})
                        for name in models:
                            pred = shade_model(name, senv, sky_light[sun], x, frames, views, mat, buf)
                            rows.append({**base, "variant": f"{sname}+{name}", "rel_err": rel_err(pred, truth)})
    return rows, terms


def summarize_by_coverage(rows: Sequence[dict[str, Any]], key: str = "coverage") -> list[dict[str, Any]]:
    """Per (bin of ``key``: ``coverage`` or ``sky_hidden``, sun, material, variant): the RMS of
    ``rel_err`` over positions and rings and the count, in bin order."""
    groups: dict[tuple, list[float]] = {}
    for r in rows:
        groups.setdefault((coverage_bin(r[key]), r["sun"], r["material"], r["variant"]), []).append(r["rel_err"])
    out = [{"bin": k[0][0], "bin_lo": k[0][1], "sun": k[1], "material": k[2], "variant": k[3], "n": len(v),
            "rms_rel_err": float(np.sqrt(np.mean(np.square(v))))} for k, v in groups.items()]
    return sorted(out, key=lambda r: (r["bin_lo"], r["sun"], r["material"], r["variant"]))


def markdown_table(summary: Sequence[dict[str, Any]], variants: Sequence[str]) -> str:
    """One row per (bin, sun, material), one column per variant (RMS relative error, %)."""
    keyed: dict[tuple, dict[str, Any]] = {}
    for r in summary:
        keyed.setdefault((r["bin"], r["sun"], r["material"]), {"n": r["n"]})[r["variant"]] = r["rms_rel_err"]
    head = "| sky coverage | sun | material | n | " + " | ".join(variants) + " |\n" + "| --- " * (4 + len(variants)) + "|\n"
    body = ""
    for (b, sun, mat), v in keyed.items():
        cells = " | ".join(f"{100 * v[k]:.1f}" if k in v else "" for k in variants)
        body += f"| {b} | {'in sky' if sun else 'analytic'} | {mat} | {v['n']} | {cells} |\n"
    return head + body
