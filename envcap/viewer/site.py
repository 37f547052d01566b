"""What the viewer page reads besides the probe set's own files: ``/api/config.json`` (streets with
their runtime uniforms, methods, sun, lobe powers, report plots) and ``/api/runtime.glsl`` (the
runtime library for WebGL2: :func:`envcap.runtime.shader_targets.prologue` ``("webgl2")`` plus
``runtime/envcap_street_uniforms.glsl`` with every ``#include`` resolved, since a browser has no
include path); and :meth:`ViewerSite.routes`, every URL path of the site and what it serves, the
one list that ``envcap view`` serves and ``envcap export web`` writes as static files.  The page's
URLs are relative (``set/manifest.json``, ``report/NAME``, ``api/config.json``), so the site works
from any directory of any static server.

A probe set is untrusted input: a route's file is always a path resolved inside the set
(:meth:`ViewerSite.set_file`, :func:`envcap.core.contained_path.resolve_inside`), and a set whose
manifest names a file outside it (an absolute path, ``..``, a symbolic link leading out) is
refused when opened; a report's plot that links outside it is left out (:func:`report_files`).

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
from typing import Any, Callable, Union

import numpy as np

from envcap.core.contained_path import OutsideFolder, resolve_inside
from envcap.core.resources import expand_includes
from envcap.core.street_frame import OptionalFrame, frame_to_world, from_frame, plan_rotation
from envcap.formats.webgl2_writer import ATLAS_FILE
from envcap.probeset.json_codec import read_json_file
from envcap.probeset.manifest import Manifest, read_manifest
from envcap.runtime import methods as runtime_methods
from envcap.runtime.limits import MAX_PROBES
from envcap.runtime.shader_targets import prologue
from envcap.runtime.street import StreetProbes, StreetUniforms
from envcap.viewer.babylon_build import find_babylon
from envcap.viewer.crowd_site import CrowdSite, crowd_config

WEB_DIR = Path(__file__).resolve().parent / "web"
"""The page's static files (``index.html``, ``three.html``, ``babylon.html`` and their ES modules;
``three/``: the three.js r187 build, MIT), shipped with the package (Babylon.js is not:
:mod:`envcap.viewer.babylon_build`)."""

Body = Union[Path, bytes, Callable[[], bytes]]
"""What a route serves: a file, bytes, or a function making the bytes when asked."""

Routes = dict[str, Body]
"""URL path (leading ``/``; ``/`` is ``index.html``) -> what it serves."""


class MissingAtlas(ValueError):
    """A probe set (or a city shard) without ``probes_atlas.ktx2``, the WebGL2 face atlas."""

    def __init__(self, probe_dir: Path) -> None:
        super().__init__(f"{probe_dir}: no {ATLAS_FILE}, the WebGL2 face atlas (WebGL2 has no cube-map arrays)")
        self.probe_dir = probe_dir

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
    subdirectories holding ``report.json`` (first by name; a link to a folder outside
    ``probe_dir`` is not one), else ``None``."""
    if (probe_dir / "report.json").is_file():
        return probe_dir
    base = probe_dir.resolve()
    for sub in sorted(p for p in probe_dir.iterdir() if p.is_dir()):
        if (sub / "report.json").is_file() and sub.resolve().is_relative_to(base):
            return sub
    return None


def report_files(report_dir: Path | None) -> dict[str, Path]:
    """An evaluation report's ``report.json`` and PNG plots by name, each resolved inside
    ``report_dir`` (:func:`envcap.core.contained_path.resolve_inside`): a plot that is a link
    leading outside is left out; a ``report.json`` that does raises
    :class:`~envcap.core.contained_path.OutsideFolder`.  Empty without a report."""
    if report_dir is None:
        return {}
    out = {"report.json": resolve_inside(report_dir, "report.json", str(report_dir), "the report")}
    for p in sorted(report_dir.glob("*.png")):
        try:
            path = resolve_inside(report_dir, p.name, str(report_dir), "the report")
        except OutsideFolder:
            continue
        if path.is_file():
            out[p.name] = path
    return out


def page_routes() -> Routes:
    """The page's own files: ``/`` (the viewer, ``index.html``), ``/three.html`` and
    ``/babylon.html`` (the probe set in three.js and in Babylon.js), ``/three_webgpu.html`` (the
    probe set in three.js on WebGPU, WGSL), ``/web/NAME`` (their modules and CSS), ``/three/NAME``
    (the three.js build) and ``/babylon/NAME`` (the Babylon.js build and its license, where one is
    installed: :func:`envcap.viewer.babylon_build.find_babylon`)."""
    out: Routes = {"/": WEB_DIR / "index.html", "/three.html": WEB_DIR / "three.html",
                   "/three_webgpu.html": WEB_DIR / "three_webgpu.html",
                   "/babylon.html": WEB_DIR / "babylon.html"}
    out.update({f"/web/{p.name}": p for p in sorted(WEB_DIR.iterdir()) if p.is_file() and p.suffix != ".html"})
    out.update({f"/three/{p.name}": p for p in sorted((WEB_DIR / "three").iterdir()) if p.is_file()})
    babylon = find_babylon()
    if babylon is not None:
        out.update({f"/babylon/{name}": path for name, path in babylon.files.items()})
    return out


def report_routes(report_dir: Path | None) -> Routes:
    """``/report/NAME``: a report's ``report.json`` and PNG plots (:func:`report_files`; none
    without a report)."""
    return {f"/report/{name}": path for name, path in report_files(report_dir).items()}


def street_plan(st: OptionalFrame, axis: str, start: float, end: float, facades: tuple[float, float]) -> dict[str, Any]:
    """A street's plan for the page (the map, which street the camera is in): ``along`` (axis index
    in its frame), ``frame`` (``yaw_deg``, ``origin_xz``, ``cos_sin``: float64), ``direction`` (world
    plan unit vector along it) and ``corners`` (world plan points (x, z) of its rectangle
    ``start..end`` x ``facades``, in order around it)."""
    yaw, oxz = st.frame_yaw_deg, st.frame_origin_xz
    along = 0 if axis == "x" else 2
    r = plan_rotation(yaw)
    unit = np.zeros(3)
    unit[along] = 1.0
    rect = np.zeros((4, 3))
    rect[:, along] = (start, end, end, start)
    rect[:, 2 - along] = (facades[0], facades[0], facades[1], facades[1])
    return {"along": along, "frame": {"yaw_deg": yaw, "origin_xz": list(oxz), "cos_sin": [float(r[0, 0]), float(r[0, 2])]},
            "direction": from_frame(unit, yaw)[[0, 2]].tolist(),
            "corners": frame_to_world(rect, yaw, oxz)[:, [0, 2]].tolist()}


def report_plots(report_dir: Path | None) -> list[str]:
    """URLs of the report's PNG plots (``report/NAME``), plots first, then worst positions."""
    names = sorted(n for n in report_files(report_dir) if n.endswith(".png"))
    return ["report/" + n for n in sorted(names, key=lambda n: (n.startswith("worst_"), n))]


def report_positions(report_dir: Path | None) -> list[dict[str, Any]]:
    """The report's evaluation positions (``report.json`` ``positions`` rows grouped by world
    position): ``{"position": [x, y, z], "street": name, "error": {method: mean rel. RMSE
    over its lobe powers and sun variants}}``; rows without a finite position or error are skipped."""
    if report_dir is None:
        return []
    doc = read_json_file(report_files(report_dir)["report.json"], "evaluation report")
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
    ``probes_atlas.ktx2``), its checked :class:`Manifest`, an optional evaluation ``report_dir``,
    and ``prefix``, the site folder its files are served under (``set/``; a city's shard:
    ``set/<shard path>/``), ``avatar``: the crowd's avatar (an ``envcap avatar`` file; ``None``:
    the bundled walker)."""

    probe_dir: Path
    manifest: Manifest
    report_dir: Path | None = None
    prefix: str = "set/"
    avatar: Path | None = None

    @staticmethod
    def open(probe_dir: str | Path, report_dir: str | Path | None = None, *, require_atlas: bool = True,
             prefix: str = "set/", find_report_dir: bool = True, avatar: str | Path | None = None) -> "ViewerSite":
        """Check and open ``probe_dir`` (``FileNotFoundError`` / ``ValueError`` naming the problem;
        :class:`MissingAtlas` without the face atlas when ``require_atlas``: ``envcap export web``
        opens with ``False`` and makes it).  ``report_dir`` default: :func:`find_report` (when
        ``find_report_dir``)."""
        root = Path(probe_dir).resolve()
        if not root.is_dir():
            raise FileNotFoundError(f"probe-set directory not found: {root}")
        m = read_manifest(resolve_inside(root, "manifest.json", str(root)))
        site = ViewerSite(root, m, None, prefix)
        on_disk = site.manifest_files()   # every name resolved inside the set: OutsideFolder otherwise
        if m.files.sky is None or m.files.sky not in on_disk:
            raise FileNotFoundError(f"{root}: sky file missing")
        if site.has_atlas:
            layers = _ktx2_layer_count(site.set_file(site.atlas_name, "probes_atlas"))
            if layers != 6 * m.layer_count:
                why = (f" (a rung ladder of {m.ladder.per_level} rungs per level: the page reads one chain per probe, "
                       "layer r = 0)" if m.ladder is not None else "")
                raise ValueError(f"{root / site.atlas_name}: {layers} layers, the viewer needs 6 per probe = "
                                 f"{6 * m.layer_count}{why}")
        elif require_atlas:
            raise MissingAtlas(root)
        rep = Path(report_dir).resolve() if report_dir is not None else (find_report(root) if find_report_dir else None)
        if rep is not None and not (rep / "report.json").is_file():
            raise FileNotFoundError(f"{rep}: not an evaluation report (no report.json)")
        report_files(rep)   # its report.json inside it: OutsideFolder otherwise
        return ViewerSite(root, m, rep, prefix, None if avatar is None else Path(avatar).resolve())

    @property
    def atlas_name(self) -> str:
        """The face atlas's file name: the manifest's ``files.probes_atlas``, else ``probes_atlas.ktx2``."""
        name = self.manifest.files.extra.get("probes_atlas")
        return name if isinstance(name, str) else ATLAS_FILE

    @property
    def has_atlas(self) -> bool:
        """Whether the probe set has its face atlas on disk."""
        return self.set_file(self.atlas_name).is_file()

    def set_file(self, name: str, key: str = "") -> Path:
        """The file of the set that the manifest calls ``name`` (in its entry ``files.key``):
        resolved, links included, and checked to lie inside :attr:`probe_dir`
        (:func:`envcap.core.contained_path.resolve_inside`; ``OutsideFolder`` naming the entry
        otherwise).  Read this path, never ``probe_dir / name``."""
        return resolve_inside(self.probe_dir, name, f"{self.probe_dir / 'manifest.json'}: files{'.' + key if key else ''}")

    def manifest_files(self) -> dict[str, Path]:
        """The files the manifest names that exist (``manifest.json`` included), by relative name,
        each resolved inside the set (:meth:`set_file`: a name or a link that leads outside it
        raises ``OutsideFolder`` naming the entry, whether or not the file exists)."""
        f = self.manifest.files
        entries: list[tuple[str, Any]] = [(k, getattr(f, k)) for k in ("probes", "sky", "exr", "previews", "sky_preview",
                                                                       "contact_sheet")]
        entries += list(f.extra.items())
        out = {"manifest.json": resolve_inside(self.probe_dir, "manifest.json", str(self.probe_dir))}
        for key, value in entries:
            for name in ([value] if isinstance(value, str) else value or ()):
                out[name] = self.set_file(name, key)
        return {n: out[n] for n in sorted(out) if out[n].is_file()}

    def set_routes(self) -> Routes:
        """``/<prefix>NAME`` for each file the manifest names (:meth:`manifest_files`: resolved
        inside the set), and nothing else."""
        return {f"/{self.prefix}{n}": path for n, path in self.manifest_files().items()}

    def routes(self) -> Routes:
        """Everything the site serves: the page (:func:`page_routes`), the probe set's files, the
        report's (:func:`report_routes`), ``/api/config.json``, ``/api/runtime.glsl`` and the crowd's
        (:meth:`envcap.viewer.crowd_site.CrowdSite.routes`: the walkers of ``envcap crowd`` on the
        first street, with :attr:`avatar` or the bundled walker)."""
        out = page_routes()
        out.update(self.set_routes())
        out.update(report_routes(self.report_dir))
        out["/api/config.json"] = lambda: json.dumps(self.config(), allow_nan=False).encode()
        out["/api/runtime.glsl"] = lambda: runtime_glsl_webgl2().encode()
        crowd = CrowdSite.of(self.manifest, self.streets(), self.avatar)
        if crowd is not None:
            out.update(crowd.routes())
        return out

    def files(self) -> dict[str, str]:
        """The page's URLs of the face atlas (WebGL2), the cube-map array (``probes``: WebGPU), the
        sky and (when on disk) ``scene.glb``."""
        m = self.manifest
        gltf = m.files.extra.get("scene_gltf")   # the bake's scene.glb, if written
        return {"manifest": self.prefix + "manifest.json", "atlas": self.prefix + self.atlas_name,
                "probes": self.prefix + str(m.files.probes), "sky": self.prefix + str(m.files.sky),
                **({"scene": self.prefix + gltf} if isinstance(gltf, str) and self.set_file(gltf).is_file() else {})}

    def streets(self) -> list[dict[str, Any]]:
        """Per street: name, axis, extent and nominal planes (frame coordinates), its plan
        (:func:`street_plan`: ``along``, ``frame``, ``direction``, ``corners``), probes (world
        positions, layers, nominal ground and ``ground_slope``) and the runtime uniforms of both
        plane sets (``uniforms.nominal`` / ``uniforms.fitted``) with their ``origin`` (frame m)."""
        out = []
        for st in self.manifest.streets:
            if not st.probes:
                continue
            sp = StreetProbes.from_manifest(st)
            mid = np.zeros(3)
            mid[sp.along] = 0.5 * (st.start + st.end)
            mid = frame_to_world(mid, st.frame_yaw_deg, st.frame_origin_xz)   # StreetProbes.local takes a world point
            rs = {ps: (sp.local(mid, MAX_PROBES, ps) if sp.layers.size > MAX_PROBES else sp.runtime_street(ps))
                  for ps in ("nominal", "fitted")}
            uni = {ps: r.uniforms(self.manifest.lobes.powers) for ps, r in rs.items()}
            pl = st.planes.as_array()
            out.append({
                "name": st.name, "axis": st.axis, "start": st.start, "end": st.end,
                "center": st.center, "planes": pl.tolist(),
                **street_plan(st, st.axis, st.start, st.end, (float(pl[0]), float(pl[1]))),
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
        """URLs of the report's PNG plots (:func:`report_plots`)."""
        return report_plots(self.report_dir)

    def report_positions(self) -> list[dict[str, Any]]:
        """The report's evaluation positions (:func:`report_positions`)."""
        return report_positions(self.report_dir)

    def config(self) -> dict[str, Any]:
        """The page's ``api/config.json`` (URLs relative to the page)."""
        m = self.manifest
        sun = m.sky.sun
        return {
            "files": self.files(),
            "resolution": m.resolution, "powers": [_finite(p) for p in m.lobes.powers],
            "sun": None if sun is None else list(map(float, sun.direction)),
            "sun_in_sky": bool(m.sky.sun_baked_in_map),
            "scene": None if m.scene is None else m.scene.name,
            "ladder": None if m.ladder is None else {   # a rung-ladder set: shown through layer r = 0 of each level
                "mode": m.ladder.mode, "per_level": int(m.ladder.per_level),
                "shown": "layer r = 0 of each level (the manifest's lobe table), not the rung blend"},
            "streets": self.streets(), "methods": self.methods(), "plots": self.report_plots(),
            "evaluation": self.report_positions(),
            "crowd": crowd_config() if any(st.probes for st in m.streets) else None,
        }
