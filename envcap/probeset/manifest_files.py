"""The ``files`` table of a probe set's manifest: which files of the directory hold what, as names
relative to it.  A manifest is untrusted input (a set may be downloaded): every entry must name a
path inside the set (:func:`envcap.core.contained_path.name_problem`); readers resolve it with
:func:`envcap.core.contained_path.resolve_inside` before opening it."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

from envcap.core.contained_path import name_problem
from envcap.probeset.json_codec import ManifestError, from_json

__all__ = ["Files", "check_files"]

_OMIT = {"json": "omit_none"}


@dataclass(frozen=True)
class Files:
    """Files of the probe-set directory, relative to it; filled by the writers
    (:mod:`envcap.formats.registry`).  ``extra``: entries of writers registered outside envcap
    (JSON: more keys of this object, a path or a list of paths each)."""

    probes: str | None = field(default=None, metadata=_OMIT)
    sky: str | None = field(default=None, metadata=_OMIT)
    exr: tuple[str, ...] | None = field(default=None, metadata=_OMIT)
    previews: tuple[str, ...] | None = field(default=None, metadata=_OMIT)
    sky_preview: str | None = field(default=None, metadata=_OMIT)
    contact_sheet: str | None = field(default=None, metadata=_OMIT)
    extra: dict[str, Any] = field(default_factory=dict, metadata={"json": "rest"})

    @staticmethod
    def from_json(obj: Any) -> "Files":
        """The entries of JSON object ``obj`` (known keys typed, others in ``extra``)."""
        files = from_json(Files, obj, "files")
        check_files(files, "files")
        return files



def check_files(files: Files, where: str) -> None:
    """Every entry a path or a list of paths, each inside the set (a manifest is untrusted input:
    :func:`envcap.core.contained_path.name_problem`, no absolute path, no ``..``)."""
    entries: dict[str, Any] = {f.name: getattr(files, f.name) for f in fields(Files) if f.name != "extra"}
    for key, value in files.extra.items():
        if not (isinstance(value, str) or (isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value))):
            raise ManifestError(f"{where}.{key}: must be a path or a list of paths, got {value!r}")
        entries[key] = value
    for key, value in entries.items():
        for name in ([value] if isinstance(value, str) else value or ()):
            if (problem := name_problem(name)) is not None:
                raise ManifestError(f"{where}.{key}: {name!r} is not a path inside the probe set: {problem}")
