"""The own-bone term has no creases: the self spheres are placed per fragment from the bones its
triangle's provoking vertex names, never interpolated between two bones.  Also: each is clamped
to SELF_CLAMP times its distance, and the shader's clamp constant equals the Python one."""

import re

import numpy as np

from envcap.crowd.camera import Camera
from envcap.crowd.instances import AvatarCycle, pose_crowd
from envcap.crowd.renderer import crowd_sources
from envcap.crowd.run import CrowdJob
from envcap.crowd.sphere_buffer import SELF_CLAMP, self_spheres

from envcap.core.resources import shader_source


def test_self_spheres_are_never_between_two_bones(canyon_probe_dir, gl_ctx):
    """Every avatar pixel's own spheres are one bone's sphere placed at that pixel's point
    (envcap.crowd.sphere_buffer.self_spheres of some joint), never a blend of two bones' (the
    crease: a sphere interpolated across a triangle whose vertices name different bones)."""
    job = CrowdJob.prepare("canyon", canyon_probe_dir, 1, size=(80, 120), seed=5)
    r = job.renderer(gl_ctx, targets=True)
    try:
        pose = pose_crowd(job.walkers, AvatarCycle.of(job.avatar.avatar, job.avatar.spheres), 0.3, r.origin)
        hips = pose.feet[0] - r.origin + [0.0, 0.9, 0.0]
        out = r.render(pose, Camera(hips + [1.6, 0.2, 1.2], hips, 80 / 120))
        mask = out["normal"][..., 3] == 1.0
        assert mask.sum() > 800, "too few avatar pixels"
        x = out["position"][mask][:, :3].astype(np.float64)
        joints = len(pose.spheres[0])
        # each joint's sphere placed at every pixel: (P, J, 4)
        cand = np.stack([self_spheres(x, np.full((len(x), 1), j), pose.spheres[0], pose.heads[0])[:, 0]
                         for j in range(joints)], axis=1)
        live = 0
        for slot in ("self0", "self1"):
            got = out[slot][mask].astype(np.float64)
            on = got[:, 3] > 0
            live += on.sum()
            err = np.abs(cand[on] - got[on, None, :]).max(axis=2).min(axis=1)
            assert err.max() < 1e-4, err.max()          # float32 GPU: ~1e-6
        assert live > 0.5 * mask.sum()
        # the clamp acts: somewhere a sphere is smaller than its fitted radius
        r0 = out["self0"][mask][:, 3]
        fitted = cand[..., 3].max(axis=1)
        assert np.any(r0 < 0.99 * np.minimum(fitted, pose.spheres[0][:, 3].max()))
        assert np.all(r0 <= SELF_CLAMP * np.linalg.norm(out["self0"][mask][:, :3] - x, axis=1) + 1e-5)
    finally:
        r.release()


def test_self_clamp_define_equals_python():
    src = shader_source("crowd/crowd_frag.glsl")
    m = re.search(r"#define CROWD_SELF_CLAMP ([0-9.eE+-]+)", src)
    assert m is not None, "crowd_frag.glsl defines no CROWD_SELF_CLAMP"
    assert float(m.group(1)) == SELF_CLAMP
    for target in ("gl450", "webgl2"):
        assert f"#define CROWD_SELF_CLAMP {SELF_CLAMP!r}\n" in crowd_sources("envcap_sample_oblique", target)[1]
