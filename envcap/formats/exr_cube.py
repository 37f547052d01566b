"""OpenEXR cube environment maps <-> envcap cubes; the face orientation changes here only.

An OpenEXR cube map (``envmap`` attribute = cube) is one image ``N`` wide and ``6N`` tall with
the faces stacked top to bottom in the order +X, -X, +Y, -Y, +Z, -Z, each with OpenEXR's own
orientation (``ImfEnvmap.cpp``, ``CubeMap::direction`` / ``pixelPosition``).  Derivation in
``docs/formats.md``: relative to an envcap face ``[row = t, column = s]``, the OpenEXR faces
+X, -X, +Z, -Z are mirrored left-right and +Y, -Y are mirrored top-bottom (no transposition).

OpenEXR places face samples on the face edges (``pos = i / (N - 1) * 2 - 1``) whereas envcap
and GL place them at texel centers (``u = (2i + 1) / N - 1``).  The conversion keeps texel
``i`` as sample ``i`` (no resampling), so a tool that follows OpenEXR's convention sees the
face stretched by ``N / (N - 1)`` about its center: at most half a texel at the edges.
"""

from __future__ import annotations

import ctypes
import io
import os
import sys
import tempfile
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from pathlib import Path
from typing import Iterator

import numpy as np
from numpy.typing import NDArray

from envcap.core.image_read import one_line
from envcap.core.input_path import require_file
from envcap.outputs import atomic_output_file

HALF_MAX = float(np.finfo(np.float16).max)


class ExrDataError(ValueError):
    """An OpenEXR file whose pixel data cannot be used as it is: truncated or corrupt, NaN / Inf
    texels, or (read as radiance) negative R, G or B.  Reading it as another kind of image would
    not help, so callers that try several readers stop at this one."""


# Per face (GL order): (flip rows, flip columns) taking an envcap face to OpenEXR's and back.
EXR_FACE_FLIPS: tuple[tuple[bool, bool], ...] = (
    (False, True),  # +X
    (False, True),  # -X
    (True, False),  # +Y
    (True, False),  # -Y
    (False, True),  # +Z
    (False, True),  # -Z
)


def _flip_face(face: NDArray, f: int) -> NDArray:
    rows, cols = EXR_FACE_FLIPS[f]
    if rows:
        face = face[::-1]
    if cols:
        face = face[:, ::-1]
    return face


def cube_to_exr_image(cube: NDArray) -> NDArray:
    """Envcap cube ``(6, N, N, ...)`` -> OpenEXR cube image ``(6N, N, ...)`` (row 0 = top)."""
    a = np.asarray(cube)
    return np.concatenate([_flip_face(a[f], f) for f in range(6)], axis=0)


def exr_image_to_cube(img: NDArray) -> NDArray:
    """OpenEXR cube image ``(6N, N, ...)`` -> envcap cube ``(6, N, N, ...)``."""
    a = np.asarray(img)
    n = a.shape[1]
    return np.stack([_flip_face(a[f * n:(f + 1) * n], f) for f in range(6)])


def write_exr_cube(
    path: str | os.PathLike[str],
    rgba: NDArray,
    distance: NDArray | None = None,
    *,
    half: bool | None = True,
) -> Path:
    """Write an envcap cube as an OpenEXR cube env map, atomically.

    ``rgba`` is ``(6, N, N, 4)`` (linear HDR, envcap orientation); ``distance`` (optional) is
    ``(6, N, N)`` in meters, stored as channel ``Z`` in float32.  ``half=True`` stores RGBA as
    half floats and raises ``ValueError`` if any magnitude exceeds 65504; ``half=False`` stores
    float32; ``half=None`` picks half when every value fits and float32 otherwise.  NaN or Inf
    in the inputs raise ``ValueError``.
    """
    import OpenEXR

    a = np.asarray(rgba)
    if a.ndim != 4 or a.shape[0] != 6 or a.shape[1] != a.shape[2] or a.shape[3] != 4 or a.shape[1] < 1:
        raise ValueError(f"EXR cube rgba must have shape (6, N, N, 4), got {a.shape}")
    if not np.issubdtype(a.dtype, np.floating) and not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"EXR cube rgba must be numeric, got dtype {a.dtype}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"EXR cube rgba: {int(np.count_nonzero(~np.isfinite(a)))} value(s) are NaN or Inf")
    n = a.shape[1]
    over = int(np.count_nonzero(np.abs(a) > HALF_MAX))
    if half is None:
        half = over == 0
    if half and over:
        raise ValueError(
            f"EXR cube rgba: {over} value(s) exceed the half-float maximum {HALF_MAX:g} "
            f"(largest {float(np.max(np.abs(a))):g}); write with half=False (float32) or half=None (auto)"
        )
    dtype = np.float16 if half else np.float32
    if not half and np.any(np.abs(a) > np.finfo(np.float32).max):
        raise ValueError("EXR cube rgba: values exceed the float32 range")
    img = cube_to_exr_image(a).astype(dtype)
    channels = {c: np.ascontiguousarray(img[..., i]) for i, c in enumerate("RGBA")}
    if distance is not None:
        d = np.asarray(distance, dtype=np.float64)
        if d.shape != (6, n, n):
            raise ValueError(f"EXR cube distance must have shape (6, {n}, {n}), got {d.shape}")
        if not np.all(np.isfinite(d)) or np.any(d < 0) or np.any(d > np.finfo(np.float32).max):
            raise ValueError("EXR cube distance must be finite and >= 0 (meters)")
        channels["Z"] = np.ascontiguousarray(cube_to_exr_image(d).astype(np.float32))
    header = {
        "compression": OpenEXR.ZIP_COMPRESSION,
        "type": OpenEXR.scanlineimage,
        "envmap": OpenEXR.ENVMAP_CUBE,
    }
    final = Path(path)
    with atomic_output_file(final) as tmp:
        OpenEXR.File(header, channels).write(str(tmp))
    return final


def _flush_c_stdio() -> None:
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no C library to ask (not on Linux/macOS)
        pass


@contextmanager
def _library_output_held() -> Iterator[list[str]]:
    # On a corrupt file the OpenEXR binding prints a warning through Python's sys.stdout and the
    # library prints its own on file descriptor 2: hold both (the yielded list gets the text when
    # the block ends) so that the error stays one line.  Where the descriptors cannot be
    # duplicated only the Python-level output is held.
    held: list[str] = []
    text = io.StringIO()
    for stream in (sys.stdout, sys.stderr):  # what is already written goes out first
        if stream is not None:
            stream.flush()
    with redirect_stdout(text), redirect_stderr(text):
        try:
            saved = [os.dup(1), os.dup(2)]
        except (OSError, ValueError):
            try:
                yield held
            finally:
                held.append(text.getvalue())
            return
        with tempfile.TemporaryFile() as tmp:
            os.dup2(tmp.fileno(), 1)
            os.dup2(tmp.fileno(), 2)
            try:
                yield held
            finally:
                _flush_c_stdio()  # C/C++ output still buffered goes to the held file, not after it
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                for fd in saved:
                    os.close(fd)
                tmp.seek(0)
                held.append(text.getvalue() + tmp.read().decode(errors="replace"))


def _read_exr(p: Path, header_only: bool) -> tuple[dict, dict[str, NDArray]]:
    # The header and (unless header_only) every channel as its own 2-D array; ExrDataError if
    # the binding cannot read the file.
    import OpenEXR

    try:
        with _library_output_held() as held, OpenEXR.File(str(p), separate_channels=True, header_only=header_only) as f:
            header = dict(f.header())  # the binding clears its own dict when the file closes
            chans = {} if header_only else {k: np.array(c.pixels) for k, c in f.channels().items()}
    except Exception as e:  # the binding raises several types for corrupt data
        detail = one_line("\n".join([str(e), *held]))
        raise ExrDataError(f"{p}: truncated or corrupt OpenEXR file ({detail})") from e
    return header, chans


def read_exr_cube(path: str | os.PathLike[str], *, radiance: bool = True
                  ) -> tuple[NDArray[np.float32], NDArray[np.float32] | None]:
    """Read an OpenEXR cube env map into ``(rgba (6, N, N, 4) float32, distance (6, N, N) | None)``.

    Faces come back in envcap/GL orientation.  A file without an ``A`` channel gets alpha 1;
    ``distance`` is the ``Z`` channel or ``None``.  Raises ``FileNotFoundError`` for a missing
    file and ``ValueError`` for a file that is not an EXR, not a cube env map, not ``N`` by
    ``6N`` or lacks R, G or B; :class:`ExrDataError` (a ``ValueError``, one line naming the file)
    for a truncated or corrupt file (a header the binding cannot decode included), NaN / Inf
    texels, negative Z (a distance) and, by default, negative R, G or B (radiance and premultiplied
    street probes are never negative), each with their count.  ``radiance=False`` reads signed
    data (e.g. a map of directions in a test) as written.
    """
    import OpenEXR

    p = require_file(path, "EXR file")
    if not OpenEXR.isOpenExrFile(str(p)):
        raise ValueError(f"{p} is not an OpenEXR file")
    try:
        return _read_cube_checked(p, radiance)
    except UnicodeDecodeError as e:
        # a header byte the binding cannot decode: it leaves the error pending, and it surfaces
        # at a later, unrelated line
        raise ExrDataError(f"{p}: corrupt OpenEXR header ({e})") from e


def _read_cube_checked(p: Path, radiance: bool) -> tuple[NDArray[np.float32], NDArray[np.float32] | None]:
    import OpenEXR

    header, _ = _read_exr(p, header_only=True)  # a lat-long image is told apart before its pixels are read
    envmap = header.get("envmap")
    if envmap != OpenEXR.ENVMAP_CUBE:
        raise ValueError(f"{p}: not a cube environment map (envmap attribute is {envmap!r})")
    _, chans = _read_exr(p, header_only=False)
    missing = [c for c in "RGB" if c not in chans]
    if missing:
        raise ValueError(f"{p}: missing channel(s) {missing}; have {sorted(chans)}")
    h, w = chans["R"].shape
    if w < 1 or h != 6 * w:
        raise ValueError(f"{p}: a cube env map must be N wide and 6N tall, got {w}x{h}")
    alpha = chans.get("A", np.ones((h, w)))
    img = np.stack([chans["R"], chans["G"], chans["B"], alpha], axis=-1).astype(np.float32)
    nonfinite = int(np.count_nonzero(~np.all(np.isfinite(img), axis=-1)))
    if nonfinite:
        raise ExrDataError(f"{p}: RGBA holds NaN or Inf in {nonfinite} texel(s) of {6 * w * w}")
    negative = int(np.count_nonzero(np.any(img[..., :3] < 0, axis=-1))) if radiance else 0
    if negative:
        raise ExrDataError(f"{p}: {negative} texel(s) of {6 * w * w} have negative R, G or B "
                           f"(radiance must be >= 0; smallest {float(img[..., :3].min()):g})")
    dist = None
    if "Z" in chans:
        dist = exr_image_to_cube(chans["Z"].astype(np.float32))
        if not np.all(np.isfinite(dist)):
            raise ExrDataError(f"{p}: Z (distance) holds NaN or Inf in {int(np.count_nonzero(~np.isfinite(dist)))} texel(s)")
        if np.any(dist < 0):
            raise ExrDataError(f"{p}: {int(np.count_nonzero(dist < 0))} texel(s) of Z (distance) are negative "
                               f"(smallest {float(dist.min()):g}); distances are >= 0 m")
    return np.ascontiguousarray(exr_image_to_cube(img)), dist
