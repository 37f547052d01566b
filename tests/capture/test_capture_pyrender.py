"""Independent check of the capture's geometry (distance, alpha) with pyrender.

pyrender renders the same six 90-degree views (its own camera model, its own EGL context, its own
shaders); its linear z-depth is converted to radial distance and compared with our distance
channel, and its coverage (depth > 0) with our alpha.  pyrender reads color back as 8 bits, so
only geometry is compared.

pyrender runs in a subprocess (this file run as a script): two EGL contexts in one process would
leave pyrender's context current after it renders, and the session-wide moderngl context used by
every other test would then draw into the wrong context.  ``pyrender.Mesh.bounds`` uses
``np.infty`` (removed in numpy 2); we avoid that code path by setting the mesh's bounds ourselves
before the mesh is added to a scene (see docs/capture.md).
"""

import os
import subprocess
import sys

import numpy as np

from envcap.core import cube
from envcap.capture.renderer import CubeCapture
from envcap.scene.synthetic import box, quad
from envcap.scene.model import SceneMesh

NEAR = 0.05


def _face_frame(f):
    """Camera axes (x right, y up, z back) for face f: x = d(dir)/du, y = d(dir)/dv, z = -major."""
    o = cube.face_uv_to_direction(f, 0.0, 0.0)
    x = cube.face_uv_to_direction(f, 1.0, 0.0) - o
    y = cube.face_uv_to_direction(f, 0.0, 1.0) - o
    return x, y, -o


def _pyrender_depth(positions, indices, probe, n):  # runs in the subprocess
    import numpy as np
    import pyrender
    import trimesh

    tm = trimesh.Trimesh(positions, indices, process=False)
    mat = pyrender.MetallicRoughnessMaterial(doubleSided=True)
    mesh = pyrender.Mesh.from_trimesh(tm, material=mat, smooth=False)
    mesh._bounds = np.array([positions.min(axis=0), positions.max(axis=0)], dtype=np.float64)  # avoid np.infty
    scene = pyrender.Scene(bg_color=(0, 0, 0, 0))
    scene.add(mesh)
    # pyrender renders into a 4x MSAA buffer and blits depth with GL_NEAREST, which returns
    # sample 0, at (0.375, 0.125) of the pixel in Mesa's standard 4x pattern, not its center.
    # Shift the principal point by that offset so that sample 0 looks through the texel center.
    dx, dy = float(os.environ.get("ENVCAP_PYR_DX", -0.125)), float(os.environ.get("ENVCAP_PYR_DY", 0.375))
    cam = pyrender.IntrinsicsCamera(fx=n / 2, fy=n / 2, cx=n / 2 + dx, cy=n / 2 + dy, znear=NEAR, zfar=10000.0)
    node = scene.add(cam, pose=np.eye(4))
    r = pyrender.OffscreenRenderer(n, n)
    out = np.zeros((6, n, n), np.float32)
    for f in range(6):
        x, y, z = _face_frame(f)
        flip = np.dot(np.cross(x, y), z) < 0  # a mirrored face frame: render with -y, flip rows back
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, (-y if flip else y), z, probe
        scene.set_pose(node, pose)
        depth = r.render(scene, flags=pyrender.RenderFlags.DEPTH_ONLY)
        # pyrender's row 0 is the top of the image (+y): t = 1 at the top, so flip to row = t.
        out[f] = depth if flip else depth[::-1]
    r.delete()
    return out


def _radial_from_zdepth(z, n):
    c = cube.texel_centers(n)
    v, u = np.meshgrid(c, c, indexing="ij")
    return z * np.sqrt(1.0 + u * u + v * v)[None]


def _street():
    parts = [quad((-40, 0, 30), (80, 0, 0), (0, 0, -60), (0.3, 0.3, 0.3))]
    rng = np.random.default_rng(5)
    for side in (-1, 1):
        for b in range(5):
            x0 = -30 + 12 * b
            h = rng.uniform(6, 25)
            z0, z1 = (side * 7.0, side * 20.0) if side > 0 else (side * 20.0, side * 7.0)
            parts.append(box((x0, 0, z0), (x0 + 10, h, z1)))
    parts.append(box((-2, 0.0, -1), (-1, 3.0, 1)))  # a kiosk next to the probe
    parts.append(quad((3, 2, 2), (0.5, 0, 0), (0, 0.5, 0.2)))  # a slanted sign, single-sided
    return SceneMesh.concatenate(parts)


def test_distance_and_alpha_agree_with_pyrender(gl_ctx, tmp_path):
    n = 64
    mesh = _street()
    probe = np.array([0.7, 1.6, 0.9])
    with CubeCapture(mesh, n, ctx=gl_ctx, near=NEAR) as cap:
        got = cap.capture(probe)
    inp = tmp_path / "in.npz"
    outp = tmp_path / "out.npz"
    np.savez(inp, positions=mesh.positions, indices=mesh.indices, probe=probe, n=n)
    import envcap

    root = os.path.dirname(os.path.dirname(os.path.abspath(envcap.__file__)))
    env = dict(os.environ, PYOPENGL_PLATFORM="egl",
               PYTHONPATH=os.pathsep.join([root, os.environ.get("PYTHONPATH", "")]))
    res = subprocess.run([sys.executable, __file__, str(inp), str(outp)], capture_output=True, text=True, env=env,
                         timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    z = np.load(outp)["depth"]
    ref = _radial_from_zdepth(z.astype(np.float64), n)
    ref_alpha = z > 0
    alpha = got.rgba[..., 3] > 0
    # Sanity: the scene is neither empty nor full in any sense.
    assert 0.2 < ref_alpha.mean() < 0.95
    # Alpha may differ only on silhouette texels (a neighbour differs in pyrender's own mask).
    mismatch = alpha != ref_alpha
    pad = np.pad(ref_alpha, ((0, 0), (1, 1), (1, 1)), mode="edge")
    edge = np.zeros_like(ref_alpha)
    for dj, di in [(0, 1), (2, 1), (1, 0), (1, 2)]:
        edge |= pad[:, dj:dj + n, di:di + n] != ref_alpha
    assert not np.any(mismatch & ~edge), np.argwhere(mismatch & ~edge)[:10]
    assert mismatch.mean() <= 0.001  # measured: 0 of 24576
    # Distance where both see geometry, away from silhouettes (depth discontinuities).
    both = alpha & ref_alpha & ~edge
    rel = np.abs(got.distance[both] - ref[both]) / ref[both]
    assert np.percentile(rel, 99) < 2e-4 and np.median(rel) < 5e-5  # measured 4.6e-5, 9.6e-6
    # Depth discontinuities inside the mask may pick either side: allow a few texels.
    assert np.mean(rel > 1e-2) < 0.003  # measured 0.0007


if __name__ == "__main__":
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    data = np.load(sys.argv[1])
    depth = _pyrender_depth(data["positions"].astype(np.float64), data["indices"].astype(np.int64),
                            data["probe"], int(data["n"]))
    np.savez(sys.argv[2], depth=depth)
