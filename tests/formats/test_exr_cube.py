"""OpenEXR cube maps: orientation checked against OpenEXR's own ``exrenvmap``, round trips, errors.

Reference for directions: OpenEXR's LatLong convention (ImfEnvmap.cpp, ``LatLongMap``):
direction = (sin(lon) cos(lat), sin(lat), cos(lon) cos(lat)), lat = +pi/2 on the top row down to
-pi/2 on the bottom row, lon = +pi at the left column to -pi at the right column, pixel
positions edge to edge.  OpenEXR cube samples sit at face edges (pos = i / (N - 1) * 2 - 1), so
the "edge model" direction of envcap texel (face, row j, col i) is the envcap face direction at
u = 2 i / (N - 1) - 1, v = 2 j / (N - 1) - 1 (the per-face flips map this grid onto itself).
"""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import OpenEXR
import pytest

from envcap.core.cube import face_uv_to_direction, texel_directions
from envcap.formats.exr_cube import cube_to_exr_image, read_exr_cube, write_exr_cube

EXRENVMAP = shutil.which("exrenvmap")
needs_exrenvmap = pytest.mark.skipif(EXRENVMAP is None, reason="OpenEXR's exrenvmap (Debian openexr) not installed")


def edge_model_directions(n: int) -> np.ndarray:
    e = np.arange(n) / (n - 1) * 2.0 - 1.0
    v, u = np.meshgrid(e, e, indexing="ij")
    d = face_uv_to_direction(np.arange(6)[:, None, None], u[None], v[None])
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def latlong_directions(w: int, h: int) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w]
    lat = np.pi / 2 - y / (h - 1) * np.pi
    lon = np.pi - x / (w - 1) * 2 * np.pi
    return np.stack([np.sin(lon) * np.cos(lat), np.sin(lat), np.cos(lon) * np.cos(lat)], -1)


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1.0, 1.0)))


def with_alpha(d: np.ndarray) -> np.ndarray:
    return np.concatenate([d, np.ones(d.shape[:-1] + (1,))], -1).astype(np.float32)


def cube_to_latlong_with_exrenvmap(tmp_path, path, w=64):
    out = tmp_path / "ll.exr"
    subprocess.run([EXRENVMAP, "-l", "-w", str(w), str(path), str(out)], check=True, capture_output=True)
    with OpenEXR.File(str(out)) as f:
        assert f.header()["envmap"] == OpenEXR.ENVMAP_LATLONG
        return np.array(f.channels()["RGBA"].pixels, dtype=np.float64)


@needs_exrenvmap
def test_exrenvmap_cube_to_latlong_sees_our_orientation(tmp_path):
    n, w = 32, 64
    # Texels encode the direction OpenEXR assigns to their sample position: exrenvmap's lat-long
    # must then reproduce each lat-long pixel's own direction, up to its filter/interpolation.
    write_exr_cube(tmp_path / "c.exr", with_alpha(edge_model_directions(n)), half=False)
    ll = cube_to_latlong_with_exrenvmap(tmp_path, tmp_path / "c.exr", w)
    ref = latlong_directions(w, w // 2)
    err = angle_deg(ll[..., :3], ref)
    assert err.max() < 0.2, err.max()
    # Texels encoding envcap's texel-center directions: off by at most the edge/center stretch
    # (half a texel at the face border, 90/N/2 degrees).
    write_exr_cube(tmp_path / "t.exr", with_alpha(texel_directions(n)), half=False)
    err_c = angle_deg(cube_to_latlong_with_exrenvmap(tmp_path, tmp_path / "t.exr", w)[..., :3], ref)
    assert 0.3 < err_c.max() < 0.5 * 90.0 / n
    # Negative control: the same faces written without the orientation change are far off.
    raw = np.concatenate(list(with_alpha(edge_model_directions(n))), axis=0)
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_CUBE}
    OpenEXR.File(hdr, {"RGBA": raw}).write(str(tmp_path / "raw.exr"))
    err_raw = angle_deg(cube_to_latlong_with_exrenvmap(tmp_path, tmp_path / "raw.exr", w)[..., :3], ref)
    assert err_raw.max() > 45.0 and err_raw.mean() > 10 * err.max()


@needs_exrenvmap
@pytest.mark.parametrize("n", [16, 32])
def test_exrenvmap_latlong_to_cube_reads_back_in_gl_orientation(tmp_path, n):
    w, h = 256, 128
    ll = with_alpha(latlong_directions(w, h))
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_LATLONG}
    OpenEXR.File(hdr, {"RGBA": ll}).write(str(tmp_path / "ll.exr"))
    subprocess.run([EXRENVMAP, "-c", "-w", str(n), str(tmp_path / "ll.exr"), str(tmp_path / "c.exr")],
                   check=True, capture_output=True)
    rgba, dist = read_exr_cube(tmp_path / "c.exr", radiance=False)  # exrenvmap writes a tiled half file; signed test pattern
    assert rgba.shape == (6, n, n, 4) and dist is None
    err = angle_deg(rgba[..., :3].astype(np.float64), edge_model_directions(n))
    assert err.max() < 0.1, err.max()
    err_c = angle_deg(rgba[..., :3].astype(np.float64), texel_directions(n))
    assert err_c.max() < 0.5 * 90.0 / n


def test_float32_roundtrip_exact_with_distance(tmp_path):
    rng = np.random.default_rng(3)
    n = 8
    rgba = (rng.standard_normal((6, n, n, 4)) * 1e6).astype(np.float32)
    dist = rng.uniform(0, 500, (6, n, n)).astype(np.float32)
    write_exr_cube(tmp_path / "c.exr", rgba, dist, half=False)
    back, dback = read_exr_cube(tmp_path / "c.exr", radiance=False)
    assert np.array_equal(back, rgba) and np.array_equal(dback, dist)


def test_half_roundtrip_and_float32_distance(tmp_path):
    rng = np.random.default_rng(4)
    n = 8
    rgba = rng.uniform(-100, 100, (6, n, n, 4)).astype(np.float32)
    dist = rng.uniform(0, 500, (6, n, n)).astype(np.float32) + np.float32(1e-3)
    write_exr_cube(tmp_path / "c.exr", rgba, dist)  # half RGBA by default
    with OpenEXR.File(str(tmp_path / "c.exr"), separate_channels=True) as f:
        ch = f.channels()
        assert ch["R"].pixels.dtype == np.float16 and ch["Z"].pixels.dtype == np.float32
        assert f.header()["envmap"] == OpenEXR.ENVMAP_CUBE
        assert ch["R"].pixels.shape == (6 * n, n)
    back, dback = read_exr_cube(tmp_path / "c.exr", radiance=False)
    assert np.array_equal(back, rgba.astype(np.float16).astype(np.float32))
    assert np.all(np.abs(back - rgba) <= np.abs(rgba) * 2.0**-11 + 1e-7)  # half rounding bound
    assert np.array_equal(dback, dist)  # distance exact: stored as float32


def test_face_layout_in_file(tmp_path):
    """Hand-derived case: envcap +X texel (row 0, col 0) is OpenEXR +X image pixel (y 0, x N-1)."""
    n = 4
    cube = np.zeros((6, n, n, 4), np.float32)
    cube[0, 0, 0] = [1, 2, 3, 4]  # +X, t=0, s=0: direction (1, 1, 1)-ish (top, towards +Z)
    cube[2, 0, 0] = [5, 6, 7, 8]  # +Y, t=0, s=0: direction (-1, 1, -1)-ish
    img = cube_to_exr_image(cube)
    assert np.array_equal(img[0, n - 1], [1, 2, 3, 4])
    assert np.array_equal(img[2 * n + n - 1, 0], [5, 6, 7, 8])
    # OpenEXR +X: pixel (x, y) -> pif = (N-1-y, x) -> dir (1, pos(pif.x), pos(pif.y)); for
    # (x=N-1, y=0): dir (1, 1, 1), the same corner as envcap's +X (1, -v, -u) at u = v = -1.
    assert np.allclose(face_uv_to_direction(0, -1.0, -1.0), [1, 1, 1])


def test_half_overflow_nan_inf(tmp_path):
    rgba = np.ones((6, 2, 2, 4), np.float32)
    rgba[0, 0, 0, 0] = 1e5  # the sun
    with pytest.raises(ValueError, match=r"1 value\(s\) exceed the half-float maximum 65504"):
        write_exr_cube(tmp_path / "c.exr", rgba)
    assert not (tmp_path / "c.exr").exists()
    write_exr_cube(tmp_path / "auto.exr", rgba, half=None)  # auto: float32
    back, _ = read_exr_cube(tmp_path / "auto.exr", radiance=False)
    assert back[0, 0, 0, 0] == 1e5 and np.all(np.isfinite(back))
    for bad in (np.nan, np.inf):
        r = np.ones((6, 2, 2, 4), np.float32)
        r[3, 1, 0, 2] = bad
        with pytest.raises(ValueError, match="NaN or Inf"):
            write_exr_cube(tmp_path / "c.exr", r, half=False)
    with pytest.raises(ValueError, match="distance must be finite"):
        write_exr_cube(tmp_path / "c.exr", np.ones((6, 2, 2, 4)), np.full((6, 2, 2), np.nan))
    with pytest.raises(ValueError, match=r"distance must have shape \(6, 2, 2\)"):
        write_exr_cube(tmp_path / "c.exr", np.ones((6, 2, 2, 4)), np.ones((6, 3, 3)))
    with pytest.raises(ValueError, match=r"\(6, N, N, 4\)"):
        write_exr_cube(tmp_path / "c.exr", np.ones((6, 2, 2, 3)))


def test_one_texel_faces(tmp_path):
    rgba = np.arange(24, dtype=np.float32).reshape(6, 1, 1, 4)
    write_exr_cube(tmp_path / "c.exr", rgba, half=False)
    assert np.array_equal(read_exr_cube(tmp_path / "c.exr", radiance=False)[0], rgba)


def test_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        read_exr_cube(tmp_path / "missing.exr")
    (tmp_path / "junk.exr").write_bytes(b"not an exr at all")
    with pytest.raises(ValueError, match="not an OpenEXR file"):
        read_exr_cube(tmp_path / "junk.exr")
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(hdr, {"RGBA": np.ones((24, 4, 4), np.float32)}).write(str(tmp_path / "plain.exr"))
    with pytest.raises(ValueError, match="not a cube environment map"):
        read_exr_cube(tmp_path / "plain.exr")
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_CUBE}
    OpenEXR.File(hdr, {"RGBA": np.ones((20, 4, 4), np.float32)}).write(str(tmp_path / "short.exr"))
    with pytest.raises(ValueError, match="N wide and 6N tall, got 4x20"):
        read_exr_cube(tmp_path / "short.exr")
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "envmap": OpenEXR.ENVMAP_CUBE}
    OpenEXR.File(hdr, {"Y": np.ones((24, 4), np.float32)}).write(str(tmp_path / "lum.exr"))
    with pytest.raises(ValueError, match="missing channel"):
        read_exr_cube(tmp_path / "lum.exr")
    good = tmp_path / "good.exr"
    write_exr_cube(good, np.ones((6, 8, 8, 4), np.float32))
    (tmp_path / "trunc.exr").write_bytes(good.read_bytes()[:200])
    with pytest.raises(ValueError):
        read_exr_cube(tmp_path / "trunc.exr")
