// envcap's probe set in three.js on WebGPU: the example page three_webgpu.html, the WebGPU twin of
// three.html.  The same view as three_example.js (a camera in the first street between its first
// two probes, looking along it; four spheres: white diffuse, glossy copper, mirror, red diffuse;
// the background: the street from the camera at the sharpest lobe, the sky above), with the
// probes in a cube-map array on three.js's WebGPURenderer device (three_probes.js
// loadProbeSetWebGPU) and the runtime in WGSL (three_webgpu.wgsl: planes_mip, envcap_sample_nearest;
// spheres ray-cast per pixel).  window.example: the page's API for tests (ready, view(), render()).
import * as THREE from "three/webgpu";
import { loadProbeSetWebGPU, streetBlock } from "./three_probes.js";
import { groundAt, toLocal } from "./street_frame.js";

const VERTEX = `@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4f {
  var p = array(vec2f(-1.0, -1.0), vec2f(3.0, -1.0), vec2f(-1.0, 3.0));
  return vec4f(p[i], 0.0, 1.0);
}`;
const SPHERES = [
  { name: "white diffuse", albedo: [0.8, 0.8, 0.8], kind: 0, across: -3 },
  { name: "glossy copper", albedo: [0.95, 0.64, 0.54], kind: 1, across: -1 },
  { name: "mirror", albedo: [0.9, 0.9, 0.9], kind: 2, across: 1 },
  { name: "red diffuse", albedo: [0.7, 0.12, 0.1], kind: 0, across: 3 },
];
const FOV_DEG = 70, RADIUS = 0.6, GLOSSY_POWER = 64, MAX_SPHERES = 4;

function skyExposure(skyKtx) {  // 0.5 / mean luminance of the sky's broadest level (as three_example.js)
  const d = skyKtx.levels[skyKtx.levels.length - 1].data;
  if (!(d instanceof Float32Array)) return 1;
  let s = 0, n = 0;
  for (let i = 0; i < d.length / skyKtx.layers; i += 4) { s += 0.2126 * d[i] + 0.7152 * d[i + 1] + 0.0722 * d[i + 2]; ++n; }
  return s > 0 ? 0.5 * n / s : 1;
}

async function main() {
  if (!navigator.gpu) throw new Error("this browser has no WebGPU (navigator.gpu)");
  const [config, fragment] = await Promise.all([
    fetch("api/config.json").then((r) => r.json()), fetch("web/three_webgpu.wgsl").then((r) => r.text())]);
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) throw new Error("no WebGPU adapter");
  // the device three.js renders with; float32-filterable where the adapter has it (RGBA32F probe sets)
  const device = await adapter.requestDevice({ requiredFeatures: adapter.features.has("float32-filterable") ? ["float32-filterable"] : [] });
  const canvas = document.getElementById("view");
  const renderer = new THREE.WebGPURenderer({ canvas, device, antialias: false });
  renderer.setPixelRatio(1);
  renderer.setSize(window.innerWidth, window.innerHeight, false);
  const ps = await loadProbeSetWebGPU(renderer, config.files);
  const street = config.streets[0];
  const exposure = skyExposure(ps.skyKtx), power = config.powers[0] || 1e6;

  const p0 = street.probes[0].position, p1 = (street.probes[1] || street.probes[0]).position;
  const w = canvas.width, h = canvas.height;
  const camera = new THREE.PerspectiveCamera(FOV_DEG, w / h, 0.05, 5000);
  camera.position.set((p0[0] + p1[0]) / 2, p0[1], (p0[2] + p1[2]) / 2);
  const [dx, dz] = street.direction;
  camera.lookAt(camera.position.x + dx, camera.position.y + 0.05, camera.position.z + dz);
  camera.updateMatrixWorld();
  const camPos = camera.position.toArray();
  const e = camera.matrixWorld.elements;
  const camRot = [e[0], e[1], e[2], e[4], e[5], e[6], e[8], e[9], e[10]];
  const tanHalf = Math.tan(0.5 * FOV_DEG * Math.PI / 180);

  const spheres = SPHERES.map((s) => {
    const c = [camPos[0] + 7 * dx - s.across * dz, 0, camPos[2] + 7 * dz + s.across * dx];
    c[1] = groundAt(street, c) + RADIUS;
    return { ...s, center: c, radius: RADIUS };
  });
  // the page block (std140, envcap/viewer/webgpu_page.py PAGE_BLOCK): 6 vec4, then 3 x 4 vec4
  const page = new Float32Array(24 + 12 * MAX_SPHERES);
  page.set([e[0], e[1], e[2], 0, e[4], e[5], e[6], 0, e[8], e[9], e[10], 0], 0);   // right, up, back
  page.set([...camPos, tanHalf], 12);
  page.set([...toLocal(street, camPos), exposure], 16);
  page.set([w, h, power, spheres.length], 20);
  spheres.forEach((s, k) => {
    page.set([...s.center, s.radius], 24 + 4 * k);
    page.set([...toLocal(street, s.center), s.kind], 24 + 4 * MAX_SPHERES + 4 * k);
    page.set([...s.albedo, GLOSSY_POWER], 24 + 8 * MAX_SPHERES + 4 * k);
  });
  const buffer = (data, usage) => {
    const b = device.createBuffer({ size: data.byteLength, usage: usage | GPUBufferUsage.COPY_DST });
    device.queue.writeBuffer(b, 0, data);
    return b;
  };
  const pageBuf = buffer(page, GPUBufferUsage.UNIFORM);
  const streetBuf = buffer(streetBlock(street.uniforms.nominal), GPUBufferUsage.STORAGE);

  const context = canvas.getContext("webgpu");
  const format = navigator.gpu.getPreferredCanvasFormat();
  context.configure({ device, format, alphaMode: "opaque" });
  const pipeline = await device.createRenderPipelineAsync({
    layout: "auto",
    vertex: { module: device.createShaderModule({ code: VERTEX }), entryPoint: "vs" },
    fragment: { module: device.createShaderModule({ code: fragment }), entryPoint: "main", targets: [{ format }] },
  });
  const group = device.createBindGroup({ layout: pipeline.getBindGroupLayout(0), entries: [
    { binding: 0, resource: { buffer: pageBuf } }, { binding: 8, resource: { buffer: streetBuf } },
    { binding: 22, resource: ps.probes }, { binding: 23, resource: ps.sampler },
    { binding: 24, resource: ps.sky }, { binding: 25, resource: ps.sampler }] });

  const render = async () => {
    const enc = device.createCommandEncoder();
    const pass = enc.beginRenderPass({ colorAttachments: [{ view: context.getCurrentTexture().createView(),
                                                            loadOp: "clear", storeOp: "store", clearValue: [0, 0, 0, 1] }] });
    pass.setPipeline(pipeline);
    pass.setBindGroup(0, group);
    pass.draw(3);
    pass.end();
    device.queue.submit([enc.finish()]);
    await device.queue.onSubmittedWorkDone();
  };
  await render();
  document.getElementById("caption").textContent =
    `${config.scene || "probe set"} in three.js r${THREE.REVISION} on WebGPU: street ${street.name}, planes_mip, ` +
    `probes: a cube-map array of ${ps.probesKtx.layers}, ${ps.probesKtx.levels.length} levels, WGSL`;
  return {
    render,
    view: () => ({ position: camPos, rot: camRot, tanHalfFov: tanHalf, width: w, height: h, exposure, power,
                   street: street.name, spheres: spheres.map((s) => ({ name: s.name, center: s.center, radius: s.radius })),
                   probes: { layers: ps.probesKtx.layers, levels: ps.probesKtx.levels.length, dimension: "cube-array" } }),
  };
}

const ready = main().catch((err) => { document.getElementById("caption").textContent = "error: " + err.message; console.error(err.message); throw err; });
window.example = { ready: ready.then(() => true) };
ready.then((api) => Object.assign(window.example, api));
