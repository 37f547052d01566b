"""What the viewer page reads besides the probe set's own files: ``/api/config.json`` (streets with
their runtime uniforms, methods, sun, lobe powers, report plots) and ``/api/runtime.glsl`` (the
runtime library for WebGL2: :func:`envcap.runtime.shader_targets.prologue` ``("webgl2")`` plus
``runtime/envcap_street_uniforms.glsl`` with every ``#include`` resolved, since a browser has no
include path).

Street uniforms are :meth:`envcap.runtime.street.RuntimeStreet.uniforms` of each manifest street
(nominal and fitted plane sets: ``frame`` and the slopes in ``planes[i].w`` included), so the page
uploads exactly what the numpy twin and the desktop GLSL use; a street of more than ``MAX_PROBES``
probes is cut to the ``MAX_PROBES`` probes nearest its middle
(:meth:`envcap.runtime.street.StreetProbes.local`).  Positions in the config are world meters;
each street carries its frame (:mod:`envcap.core.street_frame`: ``yaw_deg``, ``origin_xz`` and the
rotation's ``cos_sin`` in float64) and the page turns shading points into it as
``float32(R (x - (ox, 0, oz)) - origin)`` in float64 (JavaScript numbers), as
:meth:`StreetUniforms.to_local` does; directions stay world (the GLSL turns them).

A rung-ladder set (``manifest.ladder``, ``envcap capture --ladder``) is shown through its layer
``r = 0`` of each level, the chain the manifest's lobe table describes (``probes_atlas.ktx2`` holds
exactly those layers; the page takes layer 0 of the ``R``-layer ``sky.ktx2``): the paper-chain
methods on the ladder's levels, not the rung blend (``envcap_rung_street.glsl``), which WebGL2
cannot run without cube-map arrays for the sky.  ``config["ladder"]`` says so.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from envcap.core.resources import expand_includes
from envcap.core.street_frame import frame_to_world, from_frame, plan_rotation
from envcap.probeset.manifest import Manifest, read_manifest
from envcap.runtime import methods as runtime_methods
from envcap.runtime.limits import MAX_PROBES
from envcap.runtime.shader_targets import prologue
from envcap.runtime.street import StreetProbes, StreetUniforms

WEB_DIR = Path(__file__).resolve().parent / "web"
"""The page's static files (``index.html`` and its ES modules), shipped with the package."""

VIEWER_METHODS: dict[str, str] = {"nearest": "viewer_nearest", "planes": "viewer_planes"}
"""Methods without a runtime GLSL function that the page still offers, by the page's own GLSL
(``web/runtime.js``): ``nearest`` (the probe along ``d`` at ``z(w)``, the plain lookup over the
sky) and ``planes`` (three-plane parallax at the unshifted level)."""


def runtime_glsl_webgl2() -> str:
    """The WebGL2 (GLSL ES 3.00) runtime library: ``#version 300 es``, precisions, the target's
    macros, the face-atlas lookup, ``EnvcapStreet`` and the ``envcap_street`` uniform; no ``main``."""
    return expand_includes(prologue("webgl2") + '#include "runtime/envcap_street_uniforms.glsl"\n')


def _uniform_json(u: StreetUniforms) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for f in StreetUniforms.glsl_fields():
        v = getattr(u, f.name)
        out[f.name] = np.asarray(v).reshape(-1).tolist() if isinstance(v, np.ndarray) else int(v)
    return out


def _ktx2_layer_count(path: Path) -> int:
    """``layerCount`` of a KTX2 file's header (bytes 32..35, little-endian; 0 read as 1)."""
    with open(path, "rb") as f:
        head = f.read(36)
    if len(head) < 36 or head[:12] != b"\xabKTX 20\xbb\r\n\x1a\n":
        raise ValueError(f"{path}: not a KTX2 file")
    return max(1, int.from_bytes(head[32:36], "little"))


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def find_report(probe_dir: Path) -> Path | None:
    """An evaluation report beside a probe set: ``probe_dir`` itself or one of its direct
    subdirectories holding ``report.json`` (first by name), else ``None``."""
    if (probe_dir / "report.json").is_file():
        return probe_dir
    for sub in sorted(p for p in probe_dir.iterdir() if p.is_dir()):
        if (sub / "report.json").is_file():
            return sub
    return None


def viewer_methods() -> list[dict[str, Any]]:
    """The parallax methods the page can run: the registered ones with a GLSL function, plus
    :data:`VIEWER_METHODS`; each with its plane set, summary and (``planes_mip_aniso``) taps."""
    out = []
    for name in runtime_methods.registered():
        m = runtime_methods.get(name)
        glsl = m.glsl or VIEWER_METHODS.get(name)
        if glsl is not None:
            out.append({"name": name, "glsl": glsl, "planes": m.planes, "summary": m.summary,
                        "taps": int(m.parameters.get("taps", 2))})
    return out


@dataclass(frozen=True)
class ViewerSite:
    """A probe set as the viewer serves it: ``probe_dir`` (with ``manifest.json`` and, for WebGL2,
    ``probes_atlas.ktx2``), its checked :class:`Manifest`, and an optional evaluation ``report_dir``."""

    probe_dir: Path
    manifest: Manifest
    report_dir: Path | None = None

    @staticmethod
    def open(probe_dir: str | Path, report_dir: str | Path | None = None) -> "ViewerSite":
        """Check and open ``probe_dir`` (``FileNotFoundError`` / ``ValueError`` naming the problem);
        ``report_dir`` default: :func:`find_report`."""
        root = Path(probe_dir).resolve()
        if not root.is_dir():
            raise FileNotFoundError(f"probe-set directory not found: {root}")
        m = read_manifest(root / "manifest.json")
        atlas = m.files.extra.get("probes_atlas")
        if not atlas or not (root / atlas).is_file():
            raise ValueError(f"{root}: no probes_atlas.ktx2 (WebGL2 has no cube-map arrays); "
                             "bake with 'envcap capture ... --webgl2'")
        if m.files.sky is None or not (root / m.files.sky).is_file():
            raise FileNotFoundError(f"{root}: sky file missing")
        layers = _ktx2_layer_count(root / atlas)
        if layers != 6 * m.layer_count:
            why = (f" (a rung ladder of {m.ladder.per_level} rungs per level: the page reads one chain per probe, "
                   "layer r = 0)" if m.ladder is not None else "")
            raise ValueError(f"{root / atlas}: {layers} layers, the viewer needs 6 per probe = {6 * m.layer_count}{why}")
        rep = Path(report_dir).resolve() if report_dir is not None else find_report(root)
        if rep is not None and not (rep / "report.json").is_file():
            raise FileNotFoundError(f"{rep}: not an evaluation report (no report.json)")
        return ViewerSite(root, m, rep)

    def streets(self) -> list[dict[str, Any]]:
        """Per street: name, axis, ``along`` (axis index in its frame), extent and nominal planes
        (frame coordinates), its frame (``yaw_deg``, ``origin_xz``, ``cos_sin`` = (cos, sin) of the
        yaw, float64; yaw 0 / origin (0, 0) for a world-frame street), ``direction`` (world plan
        unit vector (x, z) along it), ``corners`` (world plan points (x, z) of its rectangle
        ``start..end`` x ``facade_min..facade_max``, in order around it), probes (world positions,
        layers, nominal ground and ``ground_slope``) and the runtime uniforms of both plane sets
        (``uniforms.nominal`` / ``uniforms.fitted``) with their ``origin`` (frame m)."""
        out = []
        for st in self.manifest.streets:
            if not st.probes:
                continue
            sp = StreetProbes.from_manifest(st)
            yaw, oxz = st.frame_yaw_deg, st.frame_origin_xz
            mid = np.zeros(3)
            mid[sp.along] = 0.5 * (st.start + st.end)
            mid = frame_to_world(mid, yaw, oxz)          # StreetProbes.local takes a world point
            rs = {ps: (sp.local(mid, MAX_PROBES, ps) if sp.layers.size > MAX_PROBES else sp.runtime_street(ps))
                  for ps in ("nominal", "fitted")}
            uni = {ps: r.uniforms(self.manifest.lobes.powers) for ps, r in rs.items()}
            r = plan_rotation(yaw)
            axis = np.zeros(3)
            axis[sp.along] = 1.0
            pl = st.planes.as_array()
            rect = np.zeros((4, 3))
            rect[:, sp.along] = (st.start, st.end, st.end, st.start)
            rect[:, 2 - sp.along] = (pl[0], pl[0], pl[1], pl[1])
            out.append({
                "name": st.name, "axis": st.axis, "along": sp.along, "start": st.start, "end": st.end,
                "center": st.center, "planes": pl.tolist(),
                "frame": {"yaw_deg": yaw, "origin_xz": list(oxz), "cos_sin": [float(r[0, 0]), float(r[0, 2])]},
                "direction": from_frame(axis, yaw)[[0, 2]].tolist(),
                "corners": frame_to_world(rect, yaw, oxz)[:, [0, 2]].tolist(),
                "probes": [{"layer": int(q.layer), "position": list(map(float, q.position)),
                            "ground": float(q.planes.ground), "ground_slope": q.planes.slope} for q in st.probes_along()],
                "origin": uni["nominal"].origin.tolist(),
                "uniforms": {ps: _uniform_json(u) for ps, u in uni.items()},
            })
        return out

    def methods(self) -> list[dict[str, Any]]:
        """The parallax methods the page can run (:func:`viewer_methods`)."""
        return viewer_methods()

    def report_plots(self) -> list[str]:
        """URLs of the report's PNG plots (``/report/NAME``), plots first, then worst positions."""
        if self.report_dir is None:
            return []
        names = sorted(p.name for p in self.report_dir.glob("*.png"))
        return ["/report/" + n for n in sorted(names, key=lambda n: (n.startswith("worst_"), n))]

    def report_positions(self) -> list[dict[str, Any]]:
        """The report's evaluation positions (``report.json`` ``positions`` rows grouped by world
        position): ``{"position": [x, y, z], "street": name, "error": {method: mean rel. RMSE
        over its lobe powers and sun variants}}``; rows without a finite position or error are skipped."""
        if self.report_dir is None:
            return []
        doc = json.loads((self.report_dir / "report.json").read_text())
        groups: dict[tuple[float, ...], dict[str, Any]] = {}
        for r in doc.get("positions", []) if isinstance(doc, dict) else []:
            pos, err, meth = r.get("position"), r.get("rel_rmse"), r.get("method")
            if not (isinstance(pos, list) and len(pos) == 3 and isinstance(meth, str) and isinstance(err, (int, float))):
                continue
            if not (all(isinstance(v, (int, float)) and math.isfinite(v) for v in pos) and math.isfinite(err)):
                continue
            g = groups.setdefault(tuple(pos), {"position": list(map(float, pos)), "street": r.get("street"), "sums": {}})
            total, n = g["sums"].get(meth, (0.0, 0))
            g["sums"][meth] = (total + float(err), n + 1)
        return [{"position": g["position"], "street": g["street"],
                 "error": {m: t / n for m, (t, n) in sorted(g["sums"].items())}} for g in groups.values()]

    def config(self) -> dict[str, Any]:
        """The page's ``/api/config.json``."""
        m = self.manifest
        sun = m.sky.sun
        doc = json.loads((self.probe_dir / "manifest.json").read_text())
        return {
            "files": {"manifest": "/set/manifest.json", "atlas": "/set/" + m.files.extra["probes_atlas"],
                      "sky": "/set/" + m.files.sky,
                      **({"scene": "/set/" + m.files.extra["scene_gltf"]}   # the bake's scene.glb, if written
                         if isinstance(m.files.extra.get("scene_gltf"), str)
                         and (self.probe_dir / m.files.extra["scene_gltf"]).is_file() else {})},
            "resolution": m.resolution, "powers": [_finite(p) for p in m.lobes.powers],
            "sun": None if sun is None else list(map(float, sun.direction)),
            "sun_in_sky": bool(m.sky.sun_baked_in_map),
            "scene": doc.get("scene", {}).get("name"),
            "ladder": None if m.ladder is None else {   # a rung-ladder set: shown through layer r = 0 of each level
                "mode": m.ladder.mode, "per_level": int(m.ladder.per_level),
                "shown": "layer r = 0 of each level (the manifest's lobe table), not the rung blend"},
            "streets": self.streets(), "methods": self.methods(), "plots": self.report_plots(),
            "evaluation": self.report_positions(),
        }
