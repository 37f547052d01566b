#ifndef ENVCAP_CROWD_VERT_GLSL
#define ENVCAP_CROWD_VERT_GLSL
// envcap crowd, vertex stage: instanced GPU skinning of one avatar mesh, one instance per walker,
// and the vertex's two most influential blocker bones (flat; crowd_frag.glsl places their spheres).  Common subset of GLSL 4.50 / ES 3.00: a target prologue
// (envcap.runtime.shader_targets.prologue) goes first.  docs/crowd.md; numpy twin of the
// skinning: envcap.dynamic.gltf_skin.skin, of the blockers: envcap.crowd.sphere_buffer.self_blockers.
//
// crowd_instances (RGBA32F, row = walker, 6 J texels; envcap.crowd.instances): texels 4j..4j+3
// the columns of joint matrix j (root included), 4J + j bone sphere j (centre, radius), 5J + j
// bone head j.  Positions are relative to the render origin (the street's local origin).

ENVCAP_BINDING(5) uniform highp sampler2D crowd_instances;
uniform int crowd_joint_count;     // J
uniform mat4 crowd_view_proj;      // clip from render-origin-relative world

ENVCAP_IN(0) in vec3 in_position;  // bind pose (m)
ENVCAP_IN(1) in vec3 in_normal;
ENVCAP_IN(2) in vec4 in_joints;    // JOINTS_0 as floats
ENVCAP_IN(3) in vec4 in_weights;   // WEIGHTS_0
ENVCAP_IN(4) in vec4 in_blockers;  // _ENVCAP_BLOCKERS as floats
ENVCAP_IN(5) in vec4 in_blocker_weights;

out vec3 v_position;               // skinned, relative to the render origin (m)
out vec3 v_normal;                 // skinned, unit (world)
flat out ivec2 v_blockers;         // the two blocker joints in joint order (-1: none)
flat out int v_walker;

vec4 crowd_texel(int walker, int texel)
{
    return texelFetch(crowd_instances, ivec2(texel, walker), 0);
}

mat4 crowd_joint(int walker, int j)
{
    return mat4(crowd_texel(walker, 4 * j), crowd_texel(walker, 4 * j + 1),
                crowd_texel(walker, 4 * j + 2), crowd_texel(walker, 4 * j + 3));
}

void main()
{
    int walker = gl_InstanceID;
    mat4 m = in_weights.x * crowd_joint(walker, int(in_joints.x)) + in_weights.y * crowd_joint(walker, int(in_joints.y))
           + in_weights.z * crowd_joint(walker, int(in_joints.z)) + in_weights.w * crowd_joint(walker, int(in_joints.w));
    vec4 p = m * vec4(in_position, 1.0);
    vec3 a = m[0].xyz, b = m[1].xyz, c = m[2].xyz;
    mat3 cof = mat3(cross(b, c), cross(c, a), cross(a, b));
    vec3 n = cof * in_normal * sign(dot(a, cross(b, c)));
    float ln = length(n);
    v_position = p.xyz;
    v_normal = ln > 0.0 ? n / ln : vec3(0.0, 1.0, 0.0);
    // the two blockers in joint order, flat: the fragment stage places their spheres (the
    // triangle's provoking vertex names the bones; no sphere is interpolated between two bones)
    bool swap_ = in_blockers.y < in_blockers.x && in_blocker_weights.y > 0.0;
    vec2 js = swap_ ? in_blockers.yx : in_blockers.xy;
    vec2 ws = swap_ ? in_blocker_weights.yx : in_blocker_weights.xy;
    v_blockers = ivec2(ws.x > 0.0 ? int(js.x) : -1, ws.y > 0.0 ? int(js.y) : -1);
    v_walker = walker;
    gl_Position = crowd_view_proj * vec4(p.xyz, 1.0);
}

#endif  // ENVCAP_CROWD_VERT_GLSL
