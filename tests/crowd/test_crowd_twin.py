"""The crowd shader's terms equal their numpy twin on sampled pixels: Eq. 3 through the runtime
lookup (envcap.runtime.sampling.sample_street), and bounced - blocked of the avatar's own blocker
bones and of its neighbours (envcap.dynamic.terms.dynamic_terms over the spheres
envcap.crowd.sphere_buffer.fragment_spheres gathers), from the shader's float targets (position,
normal, the self spheres its vertex stage placed)."""

import numpy as np
import pytest

from envcap.crowd.camera import Camera
from envcap.crowd.inputs import ALBEDO, material
from envcap.crowd.instances import AvatarCycle, pose_crowd
from envcap.crowd.run import CrowdJob
from envcap.crowd.sphere_buffer import nearest_neighbours
from envcap.crowd.twin import CrowdTwin


@pytest.mark.parametrize("probe_dir, method", [("canyon_probe_dir", "fitted_planes_oblique"),
                                               ("canyon_distance_dir", "depth_refine")])
def test_glsl_terms_equal_the_numpy_twin(probe_dir, method, gl_ctx, request):
    """Default lookup of each set: fitted_planes_oblique without the distance texture,
    depth_refine (the texture bound) with it."""
    job = CrowdJob.prepare("canyon", request.getfixturevalue(probe_dir), 12, size=(64, 48), seed=5)
    assert job.method.name == method
    r = job.renderer(gl_ctx, targets=True)
    try:
        cycle = AvatarCycle.of(job.avatar.avatar, job.avatar.spheres)
        pose = pose_crowd(job.walkers, cycle, 0.3, r.origin)
        # a close camera on one walker among the others: neighbours near (bone spheres) and far (one sphere)
        hips = pose.feet - r.origin + [0.0, 1.0, 0.0]
        k = int(np.argmin(np.abs(hips - hips.mean(axis=0)).sum(axis=1)))
        cam = Camera(hips[k] + [2.5, 0.6, 1.5], hips[k], 64 / 48)
        out = r.render(pose, cam)
        mask = out["normal"][..., 3] == 1.0
        assert mask.sum() >= 30, "too few avatar pixels to compare"
        rows, cols = np.nonzero(mask)
        pick = np.random.default_rng(0).choice(len(rows), size=min(24, len(rows)), replace=False)
        rs = r.uniforms
        twin = CrowdTwin(job.probes, job.walkers.street.runtime_street(job.method.planes), job.method, material(),
                         r.origin, ALBEDO)
        neighbours = nearest_neighbours(pose.one)
        got, want, moved = [], [], 0
        for i in pick:
            y, x = rows[i], cols[i]
            pos = out["position"][y, x]
            selfs = np.stack([out["self0"][y, x], out["self1"][y, x]])
            t = twin.terms(pos[:3], out["normal"][y, x, :3], cam.eye, int(round(pos[3])), selfs, pose, neighbours)
            got.append(np.concatenate([out[k][y, x, :3] for k in ("eq3", "self_term", "all_term")]))
            want.append(np.concatenate([t.eq3, t.self_term, t.all_term]))
            moved += np.abs(t.all_term).max() > 1e-3 * np.abs(t.eq3).max()
        got, want = np.array(got), np.array(want)
        scale = np.abs(want[:, :3]).max(axis=1, keepdims=True)          # each pixel's Eq. 3
        err = np.abs(got - want) / scale
        assert np.all(np.isfinite(got))
        assert err.max() < 2e-3, err.max(axis=0)   # float32 GPU against float64 numpy: ~1e-6 measured
        assert moved >= len(pick) // 4, "the dynamic terms changed too few pixels to test anything"
        neighbours_seen = np.abs(want[:, 6:] - want[:, 3:6]).max(axis=1) > 1e-3 * scale[:, 0]
        assert neighbours_seen.sum() >= 1, "no pixel where the neighbours changed the terms"
        assert rs.count >= 1
    finally:
        r.release()
