"""The crowd's vertex stage, captured by transform feedback: every walker's skinned positions equal
envcap.dynamic.gltf_skin.skin with its root and gait sample, and the blocker joints it passes equal
the numpy twin (envcap.crowd.sphere_buffer.self_blockers)."""

import numpy as np

from envcap.crowd.inputs import default_avatar
from envcap.crowd.instances import AvatarCycle, instance_texture, pose_crowd
from envcap.crowd.renderer import crowd_sources
from envcap.crowd.sphere_buffer import self_blockers, self_spheres
from envcap.crowd.walkers import place_walkers
from envcap.dynamic.gltf_skin import joint_matrices, skin
from envcap.gpu.uniforms import set_uniforms
from envcap.runtime.street import StreetProbes
from terrain_manifest import terrain_manifest


def test_vertex_stage_skins_and_places_self_spheres_as_the_twin(gl_ctx):
    av = default_avatar()
    a = av.avatar
    st = StreetProbes.from_manifest(terrain_manifest((3.0, 3.4), (0.08, 0.06), 35.0).streets[0])
    wk = place_walkers(st, 3, seed=4)
    cycle = AvatarCycle.of(a, av.spheres)
    pose = pose_crowd(wk, cycle, 0.61, np.array([10.0, 3.0, 20.0]))
    vert, _ = crowd_sources("envcap_sample_oblique")
    prog = gl_ctx.program(vertex_shader=vert, varyings=["v_position", "v_blockers"])
    tex = instance_texture(pose)
    t = gl_ctx.texture((tex.shape[1], tex.shape[0]), 4, tex.tobytes(), dtype="f4")
    vbo = gl_ctx.buffer(np.concatenate([a.positions, a.normals, a.joints, a.weights, av.blockers, av.scores],
                                       axis=1).astype(np.float32).tobytes())
    vao = gl_ctx.vertex_array(prog, [(vbo, "3f 3x4 4f 4f 4f 4f", "in_position", "in_joints", "in_weights",   # normal unused
                                      "in_blockers", "in_blocker_weights")])
    out = gl_ctx.buffer(reserve=len(wk) * len(a.positions) * 5 * 4)
    fbo = gl_ctx.simple_framebuffer((4, 4))         # a bound framebuffer (EGL has no default one)
    try:
        fbo.use()
        t.use(5)
        set_uniforms(prog, {"crowd_joint_count": a.joint_count, "crowd_view_proj": np.eye(4), "crowd_instances": 5},
                     sources=(vert,))
        vao.transform(out, mode=0, instances=len(wk))                 # GL_POINTS: one record per vertex
        raw = out.read()
        got = np.frombuffer(raw, np.float32).reshape(len(wk), len(a.positions), 5)
        ids = np.frombuffer(raw, np.int32).reshape(len(wk), len(a.positions), 5)[..., 3:]
        for i in range(len(wk)):
            g = pose.roots[i] @ np.eye(4)
            pos, _ = skin(joint_matrices(a, 0, float(cycle.times[pose.samples[i]])), a)
            pos = pos @ g[:3, :3].T + g[:3, 3]
            assert np.allclose(got[i, :, :3], pos, atol=2e-5)
            assert np.array_equal(ids[i], self_blockers(av.blockers, av.scores))
        assert (ids[..., 0] >= 0).mean() > 0.5 and (ids[..., 1] >= 0).any()
        # at the vertices, the spheres the fragment places: many slid off their fitted centres
        want = self_spheres(got[-1, :, :3].astype(np.float64), ids[-1], pose.spheres[-1], pose.heads[-1], clamp=0.0)
        live = ids[-1, :, 0] >= 0
        slid = np.linalg.norm(want[:, 0, :3] - pose.spheres[-1][ids[-1, :, 0], :3], axis=1) > 1e-3
        assert slid[live].mean() > 0.2
    finally:
        for o in (fbo, out, vao, vbo, t, prog):
            o.release()
