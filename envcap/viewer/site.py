"""What the viewer page reads besides the probe set's own files: ``/api/config.json`` (streets with
their runtime uniforms, methods, sun, lobe powers, report plots) and ``/api/runtime.glsl`` (the
runtime library for WebGL2: :func:`envcap.runtime.shader_targets.prologue` ``("webgl2")`` plus
``runtime/envcap_street_uniforms.glsl`` with every ``#include`` resolved, since a browser has no
include path).

Street uniforms are :meth:`envcap.runtime.street.RuntimeStreet.uniforms` of each manifest street
(nominal and fitted plane sets), so the page uploads exactly what the numpy twin and the desktop
GLSL use; a street of more than ``MAX_PROBES`` probes is cut to the ``MAX_PROBES`` probes nearest
its middle (:meth:`envcap.runtime.street.StreetProbes.local`).  Positions in the config are world
meters; the page converts shading points to a street's local frame as ``float32(x - origin)``
(JavaScript numbers are float64), as :meth:`StreetUniforms.to_local` does.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from envcap.core.resources import expand_includes
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
        rep = Path(report_dir).resolve() if report_dir is not None else find_report(root)
        if rep is not None and not (rep / "report.json").is_file():
            raise FileNotFoundError(f"{rep}: not an evaluation report (no report.json)")
        return ViewerSite(root, m, rep)

    def streets(self) -> list[dict[str, Any]]:
        """Per street: name, axis, extent, nominal planes, probes (world positions, layers) and the
        runtime uniforms of both plane sets (``uniforms.nominal`` / ``uniforms.fitted``)."""
        out = []
        for st in self.manifest.streets:
            if not st.probes:
                continue
            sp = StreetProbes.from_manifest(st)
            mid = np.zeros(3)
            mid[sp.along] = 0.5 * (st.start + st.end)
            rs = {ps: (sp.local(mid, MAX_PROBES, ps) if sp.layers.size > MAX_PROBES else sp.runtime_street(ps))
                  for ps in ("nominal", "fitted")}
            uni = {ps: r.uniforms(self.manifest.lobes.powers) for ps, r in rs.items()}
            out.append({
                "name": st.name, "axis": st.axis, "along": sp.along, "start": st.start, "end": st.end,
                "center": st.center, "planes": st.planes.as_array().tolist(),
                "probes": [{"layer": int(q.layer), "position": list(map(float, q.position))} for q in st.probes_along()],
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
            "streets": self.streets(), "methods": self.methods(), "plots": self.report_plots(),
            "evaluation": self.report_positions(),
        }
