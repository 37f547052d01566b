// tests/viewer/test_three.py: envcap/viewer/web/three_probes.js in three.js, lookups rendered by a
// RawShaderMaterial into a float render target and read back.  window.check.lookups(kind, ...);
// window.check.skyPlan: the sky's format as loaded; window.check.reload(options) loads the set again
// (options.claimFloatLinear: tell three_probes.js the device filters float textures, whatever it
// says: the control of tests/viewer/test_sky_fallback.py).
import * as THREE from "three";
import { loadProbeSetThree, runtimeChunk, streetUniformValue } from "/web/three_probes.js";

const VS = `in vec3 position; void main() { gl_Position = vec4(position.xy, 0.0, 1.0); }`;
const MAIN = {
  // the sky cube at z(w); the nearest probe along d over the sky (methods/nearest.py); planes_mip
  sky: "textureLod(envcap_sky, d, envcap_clamp_level(envcap_z_of_w(w, envcap_street.xk, envcap_street.nlevels), envcap_street.nlevels)).rgb",
  nearest: `envcap_over_sky(ENVCAP_PROBES_LOD(envcap_probes, d, envcap_street.pos[envcap_nearest_probe(x[envcap_street.along], envcap_street.along_s, envcap_street.count)].w,
             envcap_clamp_level(envcap_z_of_w(w, envcap_street.xk, envcap_street.nlevels), envcap_street.nlevels)), envcap_sky, d, w, envcap_street)`,
  planes_mip: "envcap_sample_nearest(envcap_probes, envcap_sky, x, d, w, envcap_street)",
};

async function main(options = {}) {
  const [config, library] = await Promise.all([fetch("/api/config.json").then((r) => r.json()), fetch("/api/runtime.glsl").then((r) => r.text())]);
  const renderer = new THREE.WebGLRenderer({ canvas: document.createElement("canvas") });
  const claimed = { extensions: { has: () => true } };
  const ps = await loadProbeSetThree(THREE, config.files, { renderer: options.claimFloatLinear ? claimed : renderer });
  window.check.skyPlan = ps.skyPlan;
  const camera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1);
  const street = config.streets[0], o = street.origin;
  return (kind, xs, ds, ws) => {
    const n = ws.length, w = Math.min(n, 256), h = Math.ceil(n / w);
    const xw = new Float32Array(4 * w * h), dd = new Float32Array(4 * w * h);
    for (let i = 0; i < n; ++i) {
      for (let c = 0; c < 3; ++c) { xw[4 * i + c] = xs[3 * i + c] - o[c]; dd[4 * i + c] = ds[3 * i + c]; }
      xw[4 * i + 3] = ws[i];
    }
    const input = (data) => { const t = new THREE.DataTexture(data, w, h, THREE.RGBAFormat, THREE.FloatType); t.needsUpdate = true; return t; };
    const material = new THREE.RawShaderMaterial({
      glslVersion: THREE.GLSL3, vertexShader: VS,
      fragmentShader: runtimeChunk(library) + `uniform highp sampler2D in_xw; uniform highp sampler2D in_d; out vec4 o;
        void main() { ivec2 p = ivec2(gl_FragCoord.xy); vec4 xw = texelFetch(in_xw, p, 0); vec3 x = xw.xyz; float w = xw.w;
          vec3 d = texelFetch(in_d, p, 0).xyz; o = vec4(${MAIN[kind]}, 1.0); }`,
      uniforms: { envcap_probes: { value: ps.atlas }, envcap_sky: { value: ps.sky }, in_xw: { value: input(xw) },
                  in_d: { value: input(dd) }, envcap_street: { value: streetUniformValue(street.uniforms.nominal) } },
    });
    const scene = new THREE.Scene();
    const quad = new THREE.Mesh(new THREE.PlaneGeometry(2, 2), material);
    quad.frustumCulled = false;
    scene.add(quad);
    const rt = new THREE.WebGLRenderTarget(w, h, { type: THREE.FloatType, format: THREE.RGBAFormat, depthBuffer: false });
    renderer.setRenderTarget(rt);
    renderer.render(scene, camera);
    const px = new Float32Array(4 * w * h);
    renderer.readRenderTargetPixels(rt, 0, 0, w, h, px);
    renderer.setRenderTarget(null);
    rt.dispose(); material.dispose();
    const out = [];
    for (let i = 0; i < n; ++i) out.push(px[4 * i], px[4 * i + 1], px[4 * i + 2]);
    return out;
  };
}

window.check = {};
const ready = main().catch((e) => { console.error(e.message); throw e; });
window.check.ready = ready.then(() => true);
ready.then((f) => { window.check.lookups = f; });
window.check.reload = (options) => main(options).then((f) => { window.check.lookups = f; return window.check.skyPlan; });
