// envcap's probe set in Babylon.js: the example page (babylon.html) of `envcap view` and of a
// static `envcap export web` site, the same scene as three.html.  A camera in the first street,
// between its first two probes, looking along it; four spheres (white diffuse, glossy copper,
// mirror, red diffuse) shaded by the runtime GLSL in Babylon ShaderMaterials (planes_mip:
// envcap_sample_nearest); the background is the same lookup from the camera at the sharpest lobe.
// The envcap parts: babylon_probes.js (the textures, the runtime source, the street uniform) and
// street_frame.js (world points -> the street-local points the runtime takes); the rest is plain
// Babylon.js (the UMD build's global BABYLON, loaded by babylon.html from babylon/babylon.js).
// window.example: the page's API for tests (ready, view(), render()).
import { bindProbeSet, fetchProbeFiles, loadProbeSetBabylon, runtimeSource, SAMPLERS, setStreet, streetUniformNames }
  from "./babylon_probes.js";
import { groundAt, toLocal } from "./street_frame.js";

const TONEMAP = `
uniform float exposure;
vec3 tonemap(vec3 L) { vec3 c = L * exposure; c = c / (1.0 + c); return pow(c, vec3(1.0 / 2.2)); }
`;

// The background: a full-screen triangle; per pixel the camera ray (world) looked up from the camera.
const BACKGROUND_VS = `#version 300 es
precision highp float;
in vec3 position;
void main() { gl_Position = vec4(position.xy, 1.0, 1.0); }`;
const BACKGROUND_FS = `
uniform vec3 cam_local;      // the camera, street-local (street_frame.js toLocal)
uniform mat3 cam_rot;        // columns: right, up, back (world)
uniform vec2 viewport;       // drawing-buffer pixels
uniform float tan_half_fov;
uniform float power;         // the sharpest lobe power of the set
out vec4 o;
void main() {
    vec2 uv = (gl_FragCoord.xy / viewport) * 2.0 - 1.0;
    uv.x *= viewport.x / viewport.y;
    vec3 d = normalize(cam_rot * vec3(uv * tan_half_fov, -1.0));
    o = vec4(tonemap(envcap_sample_nearest(envcap_probes, envcap_sky, cam_local, d, power, envcap_street)), 1.0);
}`;

// A sphere: Babylon projects it (its world and viewProjection matrices); the fragment shades
// its surface point with the runtime.
const SPHERE_VS = `#version 300 es
precision highp float;
uniform mat4 world;
uniform mat4 viewProjection;
in vec3 position;
in vec3 normal;
out vec3 v_n;
void main() { v_n = normal; gl_Position = viewProjection * world * vec4(position, 1.0); }`;
const SPHERE_FS = `
uniform vec3 center_local;   // the sphere's centre, street-local
uniform float radius;
uniform vec3 cam_offset;     // camera - centre (world m)
uniform vec3 albedo;
uniform int kind;            // 0 diffuse, 1 glossy (glossy_power), 2 mirror
uniform float glossy_power;
in vec3 v_n;
out vec4 o;
void main() {
    vec3 n = normalize(v_n);                                         // world (unit sphere, no rotation)
    vec3 x = center_local + envcap_frame_dir(radius * n, envcap_street.frame);   // street-local point
    vec3 dir = kind == 0 ? n : reflect(normalize(radius * n - cam_offset), n);
    float w = kind == 0 ? 1.0 : (kind == 1 ? glossy_power : 1e6);
    o = vec4(tonemap(albedo * envcap_sample_nearest(envcap_probes, envcap_sky, x, dir, w, envcap_street)), 1.0);
}`;

const SPHERES = [
  { name: "white diffuse", albedo: [0.8, 0.8, 0.8], kind: 0, across: -3 },
  { name: "glossy copper", albedo: [0.95, 0.64, 0.54], kind: 1, across: -1 },
  { name: "mirror", albedo: [0.9, 0.9, 0.9], kind: 2, across: 1 },
  { name: "red diffuse", albedo: [0.7, 0.12, 0.1], kind: 0, across: 3 },
];
const FOV_DEG = 70;
const RADIUS = 0.6;

function skyExposure(skyKtx) {  // 0.5 / mean luminance of the sky's broadest level (as the viewer)
  const d = skyKtx.levels[skyKtx.levels.length - 1].data;
  if (!(d instanceof Float32Array)) return 1;
  let s = 0, n = 0;
  for (let i = 0; i < d.length / skyKtx.layers; i += 4) { s += 0.2126 * d[i] + 0.7152 * d[i + 1] + 0.0722 * d[i + 2]; ++n; }
  return s > 0 ? 0.5 * n / s : 1;
}

function material(BABYLON, scene, name, vs, fs, street, extraUniforms) {
  const m = new BABYLON.ShaderMaterial(name, scene, { vertexSource: vs, fragmentSource: fs }, {
    attributes: ["position", "normal"], samplers: SAMPLERS,
    uniforms: ["world", "viewProjection", "exposure", ...extraUniforms, ...streetUniformNames(street.uniforms.nominal)],
  });
  setStreet(BABYLON, m, street.uniforms.nominal);
  return m;
}

async function main() {
  const BABYLON = window.BABYLON;
  if (!BABYLON) throw new Error("babylon/babylon.js did not load (envcap does not ship Babylon.js: see README.md)");
  const [config, library] = await Promise.all([
    fetch("api/config.json").then((r) => r.json()), fetch("api/runtime.glsl").then((r) => r.text())]);
  const canvas = document.getElementById("view");
  const engine = new BABYLON.Engine(canvas, false, { preserveDrawingBuffer: true, stencil: false }, false);
  if (engine.webGLVersion < 2) throw new Error("Babylon.js got no WebGL2 context");
  engine.resize();
  const scene = new BABYLON.Scene(engine);
  scene.useRightHandedSystem = true;   // envcap's (and GL's) axes
  scene.clearColor = new BABYLON.Color4(0, 0, 0, 1);
  const ps = loadProbeSetBabylon(BABYLON, scene, await fetchProbeFiles({ ...config.files, skyLayer0: !!config.ladder }));
  const fs = runtimeSource(library) + TONEMAP;
  const street = config.streets[0];
  const exposure = skyExposure(ps.skyKtx), power = config.powers[0] || 1e6;

  // the camera: between the street's first two probes, at their height, looking along the street
  const p0 = street.probes[0].position, p1 = (street.probes[1] || street.probes[0]).position;
  const w = engine.getRenderWidth(), h = engine.getRenderHeight();
  const camera = new BABYLON.FreeCamera("camera", new BABYLON.Vector3((p0[0] + p1[0]) / 2, p0[1], (p0[2] + p1[2]) / 2), scene);
  camera.fov = FOV_DEG * Math.PI / 180;   // vertical (Babylon's default fovMode)
  camera.minZ = 0.05;
  camera.maxZ = 5000;
  const [dx, dz] = street.direction;
  camera.setTarget(new BABYLON.Vector3(camera.position.x + dx, camera.position.y + 0.05, camera.position.z + dz));
  camera.computeWorldMatrix(true);
  const camPos = camera.position.asArray();
  const m = camera.getWorldMatrix().m;   // Babylon's rows: right, up, back (right-handed scene)
  const camRot = [m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]];
  const tanHalfFov = Math.tan(0.5 * camera.fov);

  const background = new BABYLON.Mesh("background", scene);
  const tri = new BABYLON.VertexData();
  tri.positions = [-1, -1, 0, 3, -1, 0, -1, 3, 0];
  tri.normals = [0, 0, 1, 0, 0, 1, 0, 0, 1];
  tri.indices = [0, 1, 2];
  tri.applyToMesh(background);
  const bg = material(BABYLON, scene, "background", BACKGROUND_VS, fs + BACKGROUND_FS, street,
                      ["cam_local", "cam_rot", "viewport", "tan_half_fov", "power"]);
  bg.backFaceCulling = false;
  bg.disableDepthWrite = true;
  bindProbeSet(bg, ps);
  bg.setFloat("exposure", exposure);
  bg.setFloat("power", power);
  bg.setFloat("tan_half_fov", tanHalfFov);
  bg.setVector2("viewport", new BABYLON.Vector2(w, h));
  bg.setVector3("cam_local", BABYLON.Vector3.FromArray(toLocal(street, camPos)));
  bg.setMatrix3x3("cam_rot", new Float32Array(camRot));
  background.material = bg;
  background.alwaysSelectAsActiveMesh = true;   // never frustum-culled
  background.renderingGroupId = 0;

  // the spheres: 7 m ahead, across the view, standing on the street's ground
  const spheres = SPHERES.map((s, i) => {
    const c = [camPos[0] + 7 * dx - s.across * dz, 0, camPos[2] + 7 * dz + s.across * dx];
    c[1] = groundAt(street, c) + RADIUS;
    const mesh = BABYLON.MeshBuilder.CreateSphere(`sphere${i}`, { diameter: 2, segments: 32 }, scene);
    const mat = material(BABYLON, scene, s.name, SPHERE_VS, fs + SPHERE_FS, street,
                         ["center_local", "radius", "cam_offset", "albedo", "kind", "glossy_power"]);
    bindProbeSet(mat, ps);
    mat.setFloat("exposure", exposure);
    mat.setVector3("center_local", BABYLON.Vector3.FromArray(toLocal(street, c)));
    mat.setFloat("radius", RADIUS);
    mat.setVector3("cam_offset", new BABYLON.Vector3(camPos[0] - c[0], camPos[1] - c[1], camPos[2] - c[2]));
    mat.setVector3("albedo", BABYLON.Vector3.FromArray(s.albedo));
    mat.setInt("kind", s.kind);
    mat.setFloat("glossy_power", 64);
    mesh.material = mat;
    mesh.position = BABYLON.Vector3.FromArray(c);
    mesh.scaling = new BABYLON.Vector3(RADIUS, RADIUS, RADIUS);
    mesh.renderingGroupId = 1;
    return { name: s.name, center: c, radius: RADIUS };
  });

  await scene.whenReadyAsync();
  const render = () => scene.render();
  render();
  document.getElementById("caption").textContent =
    `${config.scene || "probe set"} in Babylon.js ${BABYLON.Engine.Version}: street ${street.name}, planes_mip, ` +
    `sky ${ps.skyPlan.format.toUpperCase()}${ps.skyPlan.linear ? "" : " nearest"}`;
  return {
    render,
    view: () => ({ position: camPos, rot: camRot, tanHalfFov, width: w, height: h,
                   exposure, power, street: street.name, spheres, skyPlan: ps.skyPlan }),
  };
}

const ready = main().catch((err) => { document.getElementById("caption").textContent = "error: " + err.message; console.error(err.message); throw err; });
window.example = { ready: ready.then(() => true) };
ready.then((api) => Object.assign(window.example, api));
