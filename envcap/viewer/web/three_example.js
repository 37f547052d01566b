// envcap's probe set in three.js: the example page (three.html) of `envcap view` and of a static
// `envcap export web` site.  A camera in the first street, between its first two probes, looking
// along it; four spheres (white diffuse, glossy copper, mirror, red diffuse) shaded by the runtime
// GLSL in RawShaderMaterials (planes_mip: envcap_sample_nearest); the background is the same
// lookup from the camera at the sharpest lobe: the street as the probes see it, the sky above.
// The envcap parts: three_probes.js (the textures, the runtime chunk, the street uniform) and
// street_frame.js (world points -> the street-local points the runtime takes); the rest is plain
// three.js.  window.example: the page's API for tests (ready, view(), render()).
import * as THREE from "three";
import { loadProbeSetThree, runtimeChunk, streetUniformValue } from "./three_probes.js";
import { groundAt, toLocal } from "./street_frame.js";

const TONEMAP = `
uniform float exposure;
vec3 tonemap(vec3 L) { vec3 c = L * exposure; c = c / (1.0 + c); return pow(c, vec3(1.0 / 2.2)); }
`;

// The background: a full-screen triangle; per pixel the camera ray (world) looked up from the camera.
const BACKGROUND_VS = `in vec3 position; void main() { gl_Position = vec4(position.xy, 1.0, 1.0); }`;
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

// A sphere: three.js projects it; the fragment shades its surface point with the runtime.
const SPHERE_VS = `
uniform mat4 modelMatrix;
uniform mat4 viewMatrix;
uniform mat4 projectionMatrix;
in vec3 position;
in vec3 normal;
out vec3 v_n;
void main() { v_n = normal; gl_Position = projectionMatrix * viewMatrix * modelMatrix * vec4(position, 1.0); }`;
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
    vec3 n = normalize(v_n);                                         // world
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

async function main() {
  const [config, library] = await Promise.all([
    fetch("api/config.json").then((r) => r.json()), fetch("api/runtime.glsl").then((r) => r.text())]);
  const canvas = document.getElementById("view");
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(window.innerWidth, window.innerHeight, false);
  const ps = await loadProbeSetThree(THREE, { ...config.files, skyLayer0: !!config.ladder }, { renderer });
  const chunk = runtimeChunk(library) + TONEMAP;
  const street = config.streets[0];
  const envcap = { envcap_probes: { value: ps.atlas }, envcap_sky: { value: ps.sky },
                   envcap_street: { value: streetUniformValue(street.uniforms.nominal) } };
  const exposure = skyExposure(ps.skyKtx), power = config.powers[0] || 1e6;

  // the camera: between the street's first two probes, at their height, looking along the street
  const p0 = street.probes[0].position, p1 = (street.probes[1] || street.probes[0]).position;
  const w = canvas.width, h = canvas.height;
  const camera = new THREE.PerspectiveCamera(FOV_DEG, w / h, 0.05, 5000);
  camera.position.set((p0[0] + p1[0]) / 2, p0[1], (p0[2] + p1[2]) / 2);
  const [dx, dz] = street.direction;
  camera.lookAt(camera.position.x + dx, camera.position.y + 0.05, camera.position.z + dz);
  camera.updateMatrixWorld();
  const camPos = camera.position.toArray();
  const e = camera.matrixWorld.elements;   // column-major: right, up, back in columns 0..2
  const camRot = [e[0], e[1], e[2], e[4], e[5], e[6], e[8], e[9], e[10]];

  const scene = new THREE.Scene();
  const background = new THREE.Mesh(new THREE.BufferGeometry().setAttribute(
    "position", new THREE.Float32BufferAttribute([-1, -1, 0, 3, -1, 0, -1, 3, 0], 3)),
  new THREE.RawShaderMaterial({
    glslVersion: THREE.GLSL3, vertexShader: BACKGROUND_VS, fragmentShader: chunk + BACKGROUND_FS, depthTest: false, depthWrite: false,
    uniforms: { ...envcap, exposure: { value: exposure }, power: { value: power }, tan_half_fov: { value: Math.tan(0.5 * FOV_DEG * Math.PI / 180) },
                viewport: { value: new THREE.Vector2(w, h) }, cam_local: { value: new THREE.Vector3(...toLocal(street, camPos)) },
                cam_rot: { value: new THREE.Matrix3().fromArray(camRot) } } }));
  background.frustumCulled = false;
  background.renderOrder = -1;
  scene.add(background);

  // the spheres: 7 m ahead, across the view, standing on the street's ground
  const geometry = new THREE.SphereGeometry(1, 48, 24);
  const spheres = SPHERES.map((s) => {
    const c = [camPos[0] + 7 * dx - s.across * dz, 0, camPos[2] + 7 * dz + s.across * dx];
    c[1] = groundAt(street, c) + RADIUS;
    const mesh = new THREE.Mesh(geometry, new THREE.RawShaderMaterial({
      glslVersion: THREE.GLSL3, vertexShader: SPHERE_VS, fragmentShader: chunk + SPHERE_FS,
      uniforms: { ...envcap, exposure: { value: exposure }, center_local: { value: new THREE.Vector3(...toLocal(street, c)) },
                  radius: { value: RADIUS }, cam_offset: { value: new THREE.Vector3(camPos[0] - c[0], camPos[1] - c[1], camPos[2] - c[2]) },
                  albedo: { value: new THREE.Vector3(...s.albedo) }, kind: { value: s.kind }, glossy_power: { value: 64 } } }));
    mesh.position.set(...c);
    mesh.scale.setScalar(RADIUS);
    scene.add(mesh);
    return { name: s.name, center: c, radius: RADIUS };
  });

  const render = () => renderer.render(scene, camera);
  render();
  document.getElementById("caption").textContent =
    `${config.scene || "probe set"} in three.js r${THREE.REVISION}: street ${street.name}, planes_mip, ` +
    `sky ${ps.skyPlan.format.toUpperCase()}${ps.skyPlan.linear ? "" : " nearest"}`;
  return {
    render,
    view: () => ({ position: camPos, rot: camRot, tanHalfFov: Math.tan(0.5 * FOV_DEG * Math.PI / 180), width: w, height: h,
                   exposure, power, street: street.name, spheres, skyPlan: ps.skyPlan }),
  };
}

const ready = main().catch((err) => { document.getElementById("caption").textContent = "error: " + err.message; console.error(err.message); throw err; });
window.example = { ready: ready.then(() => true) };
ready.then((api) => Object.assign(window.example, api));
