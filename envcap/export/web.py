"""Export target ``web``: a probe set as a static site for WebGL2, WebGPU, three.js and Babylon.js, served by any static
file server (``python3 -m http.server``), no envcap process (``docs/engines.md``, section 7).

The site is exactly what ``envcap view`` serves (:meth:`envcap.viewer.site.ViewerSite.routes`),
written as files; the page's URLs are relative, so it works from any folder of any server::

    index.html            the viewer page (map, street view, method switch)
    three.html            the probe set in three.js (web/three_example.js through web/three_probes.js)
    three_webgpu.html     the same on three.js's WebGPURenderer: probes.ktx2 as a cube-map array,
                          shaded by the WGSL runtime (web/three_webgpu_example.js, web/three_webgpu.wgsl)
    babylon.html          the probe set in Babylon.js (web/babylon_example.js through web/babylon_probes.js)
    web/                  the pages' ES modules (ktx2.js, runtime.js, three_probes.js, ...)
    three/                three.js r187 (three.module.js, three.core.js, three.webgpu.js, three.tsl.js;
                          MIT, three.LICENSE)
    babylon/              Babylon.js (babylon.js; Apache-2.0, its license and notice), copied from
                          an npm install (:mod:`envcap.viewer.babylon_build`; envcap does not ship it)
    api/config.json       streets with their runtime uniforms (EnvcapStreet), methods, sun, lobe powers
    api/runtime.glsl      the runtime GLSL, WebGL2 target (GLSL ES 3.00, includes resolved)
    api/crowd*            the viewer's crowd: its config, avatar mesh, per-frame walker textures and
                          the crowd GLSL for WebGL2 (envcap.viewer.crowd_site)
    set/                  the probe set: manifest.json, probes.ktx2, sky.ktx2, probes_atlas.ktx2
                          (+ scene.glb); a city: city.json, street_map.ktx2, set/shards/NAME/...
    report/               the evaluation report's report.json and plots, if there is one
    README.md             this list and how to serve it

A probe set is untrusted input: every file copied is one the set's manifest (or ``city.json``)
names, resolved inside the set (:meth:`envcap.viewer.site.ViewerSite.set_file`, the resolver the
viewer's server uses); a set naming a file outside it, by an absolute path, ``..`` or a symbolic
link, is refused before anything is written.

``set/`` keeps a complete probe set (``envcap view SITE`` reads it) but only the files the web
reads: the manifest is rewritten to list just them (per-probe EXRs, previews and lat-long maps
stay behind).  A set baked without ``--webgl2`` gets its face atlas made here from
``probes.ktx2`` (:func:`envcap.formats.webgl2_writer.write_probe_atlas`, the bake's own writer).
"""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

from envcap.formats.webgl2_writer import write_probe_atlas
from envcap.probeset.manifest import Files, write_manifest
from envcap.probeset.store import read_probe_set
from envcap.viewer.babylon_build import INSTALL_COMMAND, find_babylon, missing_note
from envcap.viewer.city_site import CitySite
from envcap.viewer.site import ViewerSite
from envcap.viewer.site_dir import open_site

SUMMARY = "a static site for WebGL2 / WebGPU / three.js / Babylon.js: probe files, street uniforms (JSON), runtime GLSL, example pages"
KIND = "web-export"
WEB_FILES = ("probes", "sky", "probes_atlas", "scene_gltf")
"""The manifest ``files`` entries a web export keeps."""

README = """# envcap web export

A probe set as a static site: serve this folder with any static file server, e.g. from inside it

    python3 -m http.server 8000

and open http://localhost:8000/ (the viewer), http://localhost:8000/three.html (three.js),
http://localhost:8000/three_webgpu.html (three.js on WebGPU) or http://localhost:8000/babylon.html
(Babylon.js).
Browsers do not run ES modules from file:// URLs, so a server is needed, but no envcap process.

* `index.html`, `three.html`, `three_webgpu.html`, `babylon.html`, `web/`: the pages
  (`web/three_probes.js` and `web/babylon_probes.js` load the probe set into three.js and
  Babylon.js; `web/three_example.js`, `web/three_webgpu_example.js` and `web/babylon_example.js`
  are the examples using them; `web/three_webgpu.wgsl` is the WebGPU example's shader, WGSL);
* `three/`: three.js r187 with its WebGPU build (MIT, `three/three.LICENSE`);
* `babylon/`: {babylon};
* `api/config.json`: the streets and their runtime uniforms (`streets[i].uniforms.nominal`, the
  `EnvcapStreet` struct), the methods, the sun, the lobe powers;
* `api/runtime.glsl`: the runtime GLSL for WebGL2 (GLSL ES 3.00); `api/crowd*`: the viewer's crowd;
* `set/`: the probe set ({what}){report}.

Made by `envcap export web` (envcap docs/engines.md, section 7).
"""


def _write_set(site: ViewerSite, dest: Path) -> None:
    """The web files of one probe set into ``dest``: copied, the face atlas made if missing, the
    manifest listing just them."""
    dest.mkdir(parents=True, exist_ok=True)
    files = site.manifest.files
    entries: dict[str, str] = {}
    for key in WEB_FILES:
        name = getattr(files, key, None) if key in ("probes", "sky") else files.extra.get(key)
        if not isinstance(name, str):
            continue
        src = site.set_file(name, key)   # resolved inside the set (the manifest is untrusted), else OutsideFolder
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, dest / name)
            entries[key] = name
    if "probes_atlas" not in entries:
        entries.update(write_probe_atlas(dest, read_probe_set(site.probe_dir, distance=False)))
    write_manifest(dest / "manifest.json", replace(site.manifest, files=Files.from_json(entries)))


def write_web_site(source: Path, out: Path, report: Path | None) -> str:
    """Write the web export of the probe set (or city, or directory holding one) ``source`` into
    ``out`` (module docstring); returns how to serve it (``{out}``: the output's final path)."""
    site = open_site(source, report, require_atlas=False)
    sets: tuple[ViewerSite, ...] = site.shards if isinstance(site, CitySite) else (site,)
    for s in sets:
        _write_set(s, out / s.prefix)
    if isinstance(site, CitySite):
        for name, path in site.city_files().items():   # city.json and the street map, resolved inside the city
            (out / "set" / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, out / "set" / name)
    for route, body in site.routes().items():
        if route.startswith("/set/"):
            continue   # written above
        path = out / (route.lstrip("/") or "index.html")
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(body, Path):
            shutil.copyfile(body, path)
        else:
            path.write_bytes(body if isinstance(body, bytes) else body())
    what = (f"a city of {len(site.index.streets)} streets in {len(sets)} shards" if isinstance(site, CitySite)
            else f"{site.manifest.layer_count} probes, {site.manifest.resolution}^2 faces")
    babylon = find_babylon()
    (out / "README.md").write_text(README.format(
        what=what, report="; `report/`: its evaluation report" if site.report_dir else "",
        babylon=(f"Babylon.js {babylon.version} (Apache-2.0, `babylon/babylon.LICENSE.md`)" if babylon else
                 f"missing: envcap does not ship Babylon.js; run  {INSTALL_COMMAND}  (or set ENVCAP_BABYLON to a "
                 "folder holding babylon.js) and export again")))
    return ("serve it with any static server, e.g.  python3 -m http.server 8000 --directory {out}\n"
            "and open http://localhost:8000/ (the viewer), http://localhost:8000/three.html (three.js),\n"
            "http://localhost:8000/three_webgpu.html (three.js on WebGPU) or http://localhost:8000/babylon.html (Babylon.js)" + ("" if babylon else "\nnote: " + missing_note()))
