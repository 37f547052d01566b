"""Which site a directory the user names is: ``envcap view DIR`` and ``envcap export web DIR`` take

* a probe set (``manifest.json``): :class:`~envcap.viewer.site.ViewerSite`;
* a city probe set (``city.json``): :class:`~envcap.viewer.city_site.CitySite`;
* a directory holding exactly one of those as a direct subdirectory, e.g. ``envcap demo``'s
  output (``probes/`` and ``evaluation/``) or an ``envcap export web`` site (``set/`` and
  ``report/``): that one, with the evaluation report found beside it (a subdirectory of ``DIR``
  holding ``report.json``) unless ``--report`` names one.

A probe set without the WebGL2 face atlas is refused with one line that gives the command making
it (:func:`atlas_command`).
"""

from __future__ import annotations

import shlex
from pathlib import Path

from envcap.probeset.city_index import INDEX_FILE
from envcap.viewer.city_site import CitySite
from envcap.viewer.site import MissingAtlas, ViewerSite, find_report

MANIFEST = "manifest.json"


def _is_set(d: Path) -> bool:
    return (d / MANIFEST).is_file() or (d / INDEX_FILE).is_file()


def export_dir_for(given: str | Path) -> Path:
    """Where :func:`atlas_command` puts the web export of ``given``: ``given`` + ``-web`` beside it."""
    p = Path(given)
    if p.name in ("", ".", ".."):
        p = p.resolve()
    return p.with_name(p.name + "-web")


def atlas_command(given: str | Path) -> str:
    """The command that makes the face atlas of the probe set the user named ``given`` (as typed):
    ``envcap export web DIR --out DIR-web`` (the export writes the atlas into its copy of the set)."""
    return f"envcap export web {shlex.quote(str(given))} --out {shlex.quote(str(export_dir_for(given)))}"


def find_probe_dir(given: str | Path) -> tuple[Path, Path]:
    """``(probe_dir, top)``: the probe set or city that ``given`` names (itself, or its one direct
    subdirectory holding ``manifest.json`` / ``city.json``) and the directory reports are looked
    for in.  ``FileNotFoundError`` / ``ValueError`` with one line naming what is there."""
    root = Path(given)
    if not root.is_dir():
        raise FileNotFoundError(f"probe-set directory not found: {root.resolve()}")
    if _is_set(root):
        return root, root
    subs = sorted(d for d in root.iterdir() if d.is_dir() and _is_set(d))
    if not subs:
        raise FileNotFoundError(f"{root.resolve()}: no probe set here ({MANIFEST} or {INDEX_FILE}), "
                                f"nor in a subdirectory")
    if len(subs) > 1:
        raise ValueError(f"{root.resolve()}: holds {len(subs)} probe sets ({', '.join(d.name for d in subs)}); "
                         f"name one of them")
    return subs[0], root


def open_site(given: str | Path, report: str | Path | None = None, *,
              require_atlas: bool = True, avatar: str | Path | None = None) -> ViewerSite | CitySite:
    """The site of the directory ``given`` (module docstring); ``report``: the evaluation report
    (default: beside the probe set, :func:`envcap.viewer.site.find_report`); ``avatar``: the
    crowd's (a probe set's view only).  Without a face atlas and ``require_atlas``:
    ``ValueError`` with the command that makes it."""
    probe_dir, top = find_probe_dir(given)
    if report is None:
        found = find_report(probe_dir) or (find_report(top) if top != probe_dir else None)
        report = found
    try:
        if (probe_dir / INDEX_FILE).is_file() and not (probe_dir / MANIFEST).is_file():
            if avatar is not None:
                raise ValueError(f"--avatar: {probe_dir} is a city; the crowd walks in a probe set's view only")
            return CitySite.open(probe_dir, report, require_atlas=require_atlas)
        return ViewerSite.open(probe_dir, report, require_atlas=require_atlas, avatar=avatar)
    except MissingAtlas as e:
        raise ValueError(f"{e}; make it with: {atlas_command(given)}  (then: envcap view "
                         f"{shlex.quote(str(export_dir_for(given)))})") from None
