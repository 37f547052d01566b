"""Where the Babylon.js build for ``babylon.html`` comes from (``docs/engines.md``, section 7).

envcap does not ship Babylon.js: its UMD build (npm ``babylonjs``, ``babylon.js``) is 8.9 MB
minified (1.9 MB gzipped), four times the three.js build envcap ships, and the ES-module package
(``@babylonjs/core``) is thousands of files meant for a bundler.  The page takes the UMD build
from an npm install instead, found in this order:

1. ``$ENVCAP_BABYLON``: a folder holding ``babylon.js`` (the npm package's folder), or the file;
   when set, only there (a wrong path finds nothing rather than another build);
2. else ``$XDG_CACHE_HOME/envcap/npm/node_modules/babylonjs`` (``~/.cache`` without XDG_CACHE_HOME),
   where :data:`INSTALL_COMMAND` puts it (``.ci/run`` runs it).

The version the page was written and tested against is :data:`VERSION`; another 9.x build is
used as found (its version is in the page's caption)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

VERSION = "9.35.0"
"""The ``babylonjs`` npm version ``babylon.html`` is tested with."""
INSTALL_COMMAND = (f'npm install --prefix "${{XDG_CACHE_HOME:-$HOME/.cache}}/envcap/npm" --no-save --no-audit '
                   f"--no-fund --ignore-scripts --no-package-lock babylonjs@{VERSION}")
"""The command that puts Babylon.js where :func:`find_babylon` looks (shell syntax)."""
FILES = {"babylon.js": "babylon.js", "license.md": "babylon.LICENSE.md", "NOTICE.md": "babylon.NOTICE.md"}
"""Files of the npm package the site carries, and their names under ``babylon/`` (Apache-2.0:
the license and the notice go with the code)."""


@dataclass(frozen=True)
class BabylonBuild:
    """A Babylon.js UMD build on disk: ``files`` maps the site name (under ``babylon/``) to the
    file; ``version`` is the npm package's (``"unknown"`` without a ``package.json``)."""

    files: dict[str, Path]
    version: str


def cache_dir() -> Path:
    """The npm prefix :data:`INSTALL_COMMAND` installs into."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "envcap" / "npm"


def _build_in(folder: Path) -> BabylonBuild | None:
    if not (folder / "babylon.js").is_file():
        return None
    files = {site: folder / name for name, site in FILES.items() if (folder / name).is_file()}
    try:
        version = str(json.loads((folder / "package.json").read_text())["version"])
    except (OSError, ValueError, KeyError, TypeError):
        version = "unknown"
    return BabylonBuild(files, version)


def find_babylon() -> BabylonBuild | None:
    """The Babylon.js build the pages use (module docstring for where it is looked for), or None."""
    env = os.environ.get("ENVCAP_BABYLON")
    if env:
        p = Path(env).expanduser()
        return _build_in(p.parent if p.is_file() else p)
    return _build_in(cache_dir() / "node_modules" / "babylonjs")


def missing_note() -> str:
    """One line for a user whose site has ``babylon.html`` but no Babylon.js build."""
    return ("babylon.html needs Babylon.js, which envcap does not ship: run  " + INSTALL_COMMAND +
            "  (or set ENVCAP_BABYLON to a folder holding babylon.js) and export again")
