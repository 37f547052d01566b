"""A city probe set in the viewer: ``envcap view CITY`` on a directory with ``city.json``
(``docs/scale.md``), each shard a probe set of its own with its WebGL2 face atlas.

The page gets every street of the city for its map (``config.city.streets``: name, extent,
planes and plan from ``city.json``, with its shard; no uniforms) and the full config of one shard
at a time: ``config.streets`` and ``config.files`` are shard 0's, ``api/shards/S.json`` is shard
``S``'s (``files`` and ``streets`` with their runtime uniforms, as :meth:`ViewerSite.config`).
When the camera goes to a street of another shard the page loads that shard's config and face
atlas (``web/viewer.js``); the sky is the city's (every shard has the same sky map,
:func:`envcap.probeset.city_index.merge_shards` checks it), loaded once.  A shard's files are
served under ``set/<shard path>/``, ``city.json`` and the street map under ``set/``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from envcap.core.contained_path import resolve_inside
from envcap.probeset.city_index import INDEX_FILE, CityIndex, read_city_index
from envcap.viewer.site import MissingAtlas, Routes, ViewerSite, find_report, page_routes, report_plots, \
    report_files, report_positions, report_routes, runtime_glsl_webgl2, street_plan


@dataclass(frozen=True)
class CitySite:
    """A city directory as the viewer serves it: ``probe_dir`` (with ``city.json``), its checked
    :class:`CityIndex`, one :class:`ViewerSite` per shard (in index order) and an optional
    evaluation ``report_dir``."""

    probe_dir: Path
    index: CityIndex
    shards: tuple[ViewerSite, ...]
    report_dir: Path | None = None

    @staticmethod
    def open(city_dir: str | Path, report_dir: str | Path | None = None, *, require_atlas: bool = True) -> "CitySite":
        """Check and open the city at ``city_dir`` and each of its shards (:class:`MissingAtlas`
        naming the city when a shard has no face atlas and ``require_atlas``)."""
        root = Path(city_dir).resolve()
        index = read_city_index(resolve_inside(root, INDEX_FILE, str(root), "the city"))
        shards = []
        for i, sh in enumerate(index.shards):
            shard_dir = resolve_inside(root, sh.path, f"{root / INDEX_FILE}: shards[{i}].path", "the city")
            try:
                shards.append(ViewerSite.open(shard_dir, require_atlas=require_atlas, prefix=f"set/{sh.path}/",
                                              find_report_dir=False))
            except MissingAtlas:
                raise MissingAtlas(root) from None
            names = tuple(st.name for st in shards[-1].manifest.streets)
            if names != sh.streets:
                raise ValueError(f"{root / sh.path}: holds streets {list(names)}, {INDEX_FILE} says {list(sh.streets)}")
        rep = Path(report_dir).resolve() if report_dir is not None else find_report(root)
        if rep is not None and not (rep / "report.json").is_file():
            raise FileNotFoundError(f"{rep}: not an evaluation report (no report.json)")
        site = CitySite(root, index, tuple(shards), rep)
        site.city_files()   # each inside the city: OutsideFolder otherwise
        report_files(rep)
        return site

    def city_files(self) -> dict[str, Path]:
        """The city's own files by name, resolved inside :attr:`probe_dir`
        (:func:`envcap.core.contained_path.resolve_inside`: ``OutsideFolder`` for a name or a link
        leading outside it): ``city.json`` and, when on disk, the street map."""
        where = str(self.probe_dir / INDEX_FILE)
        out = {INDEX_FILE: resolve_inside(self.probe_dir, INDEX_FILE, str(self.probe_dir), "the city")}
        sm = self.index.street_map
        if sm is not None:
            path = resolve_inside(self.probe_dir, sm.file, f"{where}: street_map.file", "the city")
            if path.is_file():
                out[sm.file] = path
        return out

    def map_streets(self) -> list[dict[str, Any]]:
        """Every street of the city for the map: name, axis, extent and nominal planes (frame
        coordinates), its plan (:func:`envcap.viewer.site.street_plan`) and its ``shard``."""
        out = []
        for st in self.index.streets:
            pl = st.planes.as_array()
            out.append({"name": st.name, "axis": st.axis, "start": st.start, "end": st.end, "center": st.center,
                        "planes": pl.tolist(), **street_plan(st, st.axis, st.start, st.end, (float(pl[0]), float(pl[1]))),
                        "shard": st.shard})
        return out

    def shard_config(self, s: int) -> dict[str, Any]:
        """``api/shards/S.json``: shard ``s``'s ``files`` and ``streets`` (with uniforms)."""
        sh = self.shards[s]
        return {"shard": s, "files": sh.files(), "streets": sh.streets()}

    def config(self) -> dict[str, Any]:
        """The page's ``api/config.json``: shard 0's config, the city's streets and shards, the report."""
        cfg = self.shards[0].config()
        cfg.update(scene=self.index.scene.name or cfg.get("scene"), plots=report_plots(self.report_dir),
                   evaluation=report_positions(self.report_dir), crowd=None)   # the crowd walks in a probe set's view only
        cfg["city"] = {"shard": 0, "streets": self.map_streets(),
                       "shards": [{"path": sh.path, "streets": list(sh.streets), "config": f"api/shards/{i}.json"}
                                  for i, sh in enumerate(self.index.shards)]}
        return cfg

    def routes(self) -> Routes:
        """Everything the site serves: the page, ``set/city.json`` (and the street map), each
        shard's files under ``set/<shard path>/``, the report, ``api/config.json``,
        ``api/shards/S.json`` and ``api/runtime.glsl``."""
        out = page_routes()
        out.update({"/set/" + name: path for name, path in self.city_files().items()})
        for s, sh in enumerate(self.shards):
            out.update(sh.set_routes())
            out[f"/api/shards/{s}.json"] = lambda s=s: json.dumps(self.shard_config(s), allow_nan=False).encode()
        out.update(report_routes(self.report_dir))
        out["/api/config.json"] = lambda: json.dumps(self.config(), allow_nan=False).encode()
        out["/api/runtime.glsl"] = lambda: runtime_glsl_webgl2().encode()
        return out
