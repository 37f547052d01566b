"""Helpers shared by tests/city (not a test module): the settings of the session's tiny city and
a directory's files as bytes."""

from pathlib import Path

SETTINGS = dict(resolution=8, spacing=100.0, writers=("ktx2", "exr", "previews"))
"""6 x 8^2 texels, a probe every 100 m, EXR files and previews written."""


def tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (relative path -> bytes), hidden ones included."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(Path(root).rglob("*")) if p.is_file()}


def framed_street(name, p0, p1, width, cross=0.0, probes=()):
    """A manifest street at any angle, as the TOML ``p0``/``p1`` form makes it: axis "x",
    start 0, end |p1 - p0|, yaw atan2(dz, dx), frame origin p0, facades ``cross -+ width / 2``."""
    import math

    from envcap.probeset.manifest import Street
    from envcap.probeset.planes import Planes

    dx, dz = p1[0] - p0[0], p1[1] - p0[1]
    return Street(name, "x", 0.0, math.hypot(dx, dz), cross, Planes(cross - width / 2, cross + width / 2, 0.0),
                  tuple(probes), yaw_deg=math.degrees(math.atan2(dz, dx)), origin_xz=(float(p0[0]), float(p0[1])))


def plan_coords(p0, p1, x, z):
    """Reference (along, across) of world points (x, z) for the centre line p0 -> p1, from the
    plan vectors alone (no angle): along = (q - p0) . t, across = (q - p0) . n with t the unit
    direction and n = (-t_z, t_x) (the frame's +Z), float64."""
    import numpy as np

    t = np.array([p1[0] - p0[0], p1[1] - p0[1]], np.float64)
    t /= np.hypot(*t)
    qx, qz = np.asarray(x, np.float64) - p0[0], np.asarray(z, np.float64) - p0[1]
    return qx * t[0] + qz * t[1], qz * t[0] - qx * t[1]
