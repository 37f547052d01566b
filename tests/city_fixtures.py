"""Helpers shared by tests/city (not a test module): the settings of the session's tiny city and
a directory's files as bytes."""

from pathlib import Path

SETTINGS = dict(resolution=8, spacing=100.0, writers=("ktx2", "exr", "previews"))
"""6 x 8^2 texels, a probe every 100 m, EXR files and previews written."""


def tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (relative path -> bytes), hidden ones included."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(Path(root).rglob("*")) if p.is_file()}
