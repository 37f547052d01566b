"""Pass seconds of a bake captured in several yaw groups (streets at different angles, review of
issue 10): the capture's per-set passes count once, every group's per-probe seconds count, also
those of per-probe passes named like a per-set one (shadow cascades redrawn as the probe moves are
timed under ``shadow_map``; only the first group's were counted)."""

from __future__ import annotations

from envcap.probeset.bake import merged_pass_times


def test_every_groups_per_probe_seconds_count_and_per_set_passes_once():
    per_set = {"sky_sh": 0.5, "shadow_map": 2.0}                       # run once, before any probe
    first = {"sky_sh": 0.5, "shadow_map": 2.25, "render": 1.0, "readback": 0.25}     # + 0.25 s of cascade redraws
    second = {"sky_sh": 0.5, "shadow_map": 2.5, "render": 3.0, "readback": 0.5}      # + 0.5 s
    third = {"sky_sh": 0.5, "shadow_map": 2.0, "render": 0.5, "readback": 0.125, "windows": 0.0625}
    got = merged_pass_times(per_set, [first, second, third])
    assert got == {"sky_sh": 0.5, "shadow_map": 2.75, "render": 4.5, "readback": 0.875, "windows": 0.0625}
    assert merged_pass_times(per_set, [first]) == first and merged_pass_times(per_set, [first]) is not first


def test_pass_times_of_a_two_angle_bake_name_every_pass_once(gl_ctx):
    from envcap.probeset.bake import bake_probe_set
    from envcap.scene import scene_from_dict

    doc = {"name": "two_angles", "effects": ["sun_light", "sun_shadows"], "shadows": {"fit": "mesh", "texel_m": 0.1},
           "sky": {"type": "uniform", "radiance": 1.0, "sun": {"elevation_deg": 50.0, "azimuth_deg": 30.0,
                                                                "illuminance": 1.0e5}},
           "ground": {"albedo": 0.5, "extent": 4000.0},
           "streets": [{"name": "a", "p0": [0.0, 0.0], "p1": [30.0, 0.0], "width": 10.0},
                       {"name": "d", "p0": [0.0, 40.0], "p1": [20.0, 60.0], "width": 10.0}]}
    ps = bake_probe_set(scene_from_dict(doc), resolution=4, spacing=10.0, filter_levels=False, ctx=gl_ctx,
                        progress=False)
    t = ps.manifest.timings.passes_s
    assert {"shadow_map", "render", "readback"} <= set(t) and all(v >= 0 for v in t.values())
    assert len({round(st.frame_yaw_deg, 6) for st in ps.manifest.streets}) == 2      # two yaw groups were captured
    assert len(ps.manifest.shadow_cascade_texels_m or ()) >= 2                       # cascades, redrawn per probe
