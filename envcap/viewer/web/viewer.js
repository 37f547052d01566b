// envcap viewer: the page.  A street-level view (spheres in a few materials and the probes,
// ray-traced in the fragment shader, shaded by the runtime GLSL of the chosen method; the
// background is the method's sharpest lookup from the camera), a top-down map, the controls and
// the evaluation report's plots.  window.envcap is the page's API for tests and benchmarks.
// A city (config.city, envcap/viewer/city_site.py): the map shows every street of the city; the
// view runs on one shard at a time (config.streets, the atlas) and going to a street of another
// shard loads that shard's config and face atlas (Viewer.loadShard).  URLs are relative to the
// page: the same files work from `envcap view` and from a static `envcap export web` site.
import { fetchKTX2, loadProbeSet, skyPlanName, uploadAtlas } from "./ktx2.js";
import { FULLSCREEN_VS, LookupRunner, bindProbes, fragmentSource, program, setStreet } from "./runtime.js";
import { loadGlb } from "./gltf.js";
import { DEPTH_AB, SceneRaster } from "./scene_raster.js";
import { distanceToStreet, groundAt, toFrame, toLocal } from "./street_frame.js";
import { Crowd, setupCrowdControls } from "./crowd.js";

const SCENE_MAIN = `
uniform vec3 cam_pos;            // street-local m (the street's frame, minus its origin)
uniform mat3 cam_rot;            // columns: right, up, back (world directions: the runtime takes them)
uniform vec2 viewport;
uniform float tan_half_fov;
uniform vec4 spheres[8];         // xyz street-local center, w radius
uniform vec2 view_frame;         // the street's (cos yaw, sin yaw): world directions -> frame
uniform vec4 materials[8];       // rgb albedo, w kind: 0 diffuse, 1 glossy (glossy_power), 2 mirror
uniform int nspheres;
uniform float glossy_power;
uniform float background_power;
uniform float exposure;
uniform int show_probes;
uniform vec2 depth_ab;           // the projection's depth terms (scene_raster.js): spheres vs scene.glb
out vec4 o;
float hit_sphere(vec3 ro, vec3 rd, vec4 s) {
    vec3 oc = ro - s.xyz;
    float b = dot(oc, rd), c = dot(oc, oc) - s.w * s.w, h = b * b - c;
    if (h < 0.0) return -1.0;
    float t = -b - sqrt(h);
    return t > 1e-3 ? t : -1.0;
}
void main() {
    vec2 uv = (gl_FragCoord.xy / viewport) * 2.0 - 1.0;
    uv.x *= viewport.x / viewport.y;
    vec3 rd = normalize(cam_rot * vec3(uv * tan_half_fov, -1.0));   // world
    vec3 rf = envcap_frame_dir(rd, view_frame);   // the same ray in the street's frame (cam_pos, spheres, probes)
    float tb = 1e30; int hit = -1; vec4 sph = vec4(0.0);
    for (int i = 0; i < 8; ++i) {
        if (i >= nspheres) break;
        float t = hit_sphere(cam_pos, rf, spheres[i]);
        if (t > 0.0 && t < tb) { tb = t; hit = i; sph = spheres[i]; }
    }
    bool marker = false;
    if (show_probes != 0) {
        for (int i = 0; i < ENVCAP_MAX_PROBES; ++i) {
            if (i >= envcap_street.count) break;
            float t = hit_sphere(cam_pos, rf, vec4(envcap_street.pos[i].xyz, 0.25));
            if (t > 0.0 && t < tb) { tb = t; hit = i; marker = true; }
        }
    }
    // one lookup call site (the runtime inlines into each): pick its x, direction, power, weight
    vec3 x = cam_pos, dir = rd, weight = vec3(1.0);
    float w = background_power;
    if (hit >= 0 && !marker) {
        x = cam_pos + tb * rf;
        vec3 nf = normalize(x - sph.xyz);   // frame -> world: the transpose of envcap_frame_dir
        vec3 n = vec3(view_frame.x * nf.x - view_frame.y * nf.z, nf.y, view_frame.y * nf.x + view_frame.x * nf.z);
        vec4 m = materials[hit];
        weight = m.rgb;
        dir = m.w < 0.5 ? n : reflect(rd, n);
        w = m.w < 0.5 ? 1.0 : (m.w < 1.5 ? glossy_power : 1e6);
    }
    float ze = tb * dot(rd, cam_rot[2]);   // eye-space z of the hit (< 0)
    gl_FragDepth = hit >= 0 ? clamp(0.5 * (depth_ab.x * ze + depth_ab.y) / -ze + 0.5, 0.0, 1.0) : 1.0;
    vec3 L = marker ? vec3(4.0, 3.0, 0.6) / exposure : weight * viewer_lookup(x, dir, w);
    vec3 c = L * exposure;
    c = c / (1.0 + c);
    o = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
}`;

const MATERIALS = [
  { name: "white diffuse", albedo: [0.8, 0.8, 0.8], kind: 0 },
  { name: "glossy copper", albedo: [0.95, 0.64, 0.54], kind: 1 },
  { name: "mirror", albedo: [0.9, 0.9, 0.9], kind: 2 },
  { name: "red diffuse", albedo: [0.7, 0.12, 0.1], kind: 0 },
  { name: "figure body (glossy blue)", albedo: [0.2, 0.3, 0.8], kind: 1 },
  { name: "figure head (diffuse skin)", albedo: [0.8, 0.6, 0.5], kind: 0 },
];

const $ = (id) => document.getElementById(id);
const status = (text) => { $("status").textContent = text; };

class Viewer {
  constructor(config, library, gl, textures) {
    this.cfg = config; this.lib = library; this.gl = gl; this.tex = textures;
    this.methods = config.methods;
    this.method = this.methods.find((m) => m.name === "planes_mip") || this.methods[0];
    this.shard = config.city ? config.city.shard : 0;   // the loaded shard of a city
    this.loading = null;                               // a shard load in flight (a promise)
    this.programs = new Map();
    this.vao = gl.createVertexArray();
    this.runner = new LookupRunner(gl, library, textures);
    const st = config.streets[0], p0 = st.probes[0].position, p1 = (st.probes[1] || st.probes[0]).position;
    this.cam = { pos: [(p0[0] + p1[0]) / 2, p0[1], (p0[2] + p1[2]) / 2], yaw: Math.atan2(st.direction[1], st.direction[0]), pitch: 0.05 };
    this.glossyPower = 64; this.ev = 0; this.showProbes = true;
    this.scene = null; this.showScene = true;  // scene.glb's SceneRaster (setScene), drawn when showScene
    this.exposure0 = this.autoExposure();
    this.placeGroup();
    this.keys = new Set();
  }
  autoExposure() {  // 0.5 / mean luminance of the sky's broadest level
    const lv = this.tex.skyKtx.levels[this.tex.skyKtx.levels.length - 1], d = lv.data;
    const val = (i) => (d instanceof Float32Array ? d[i] : halfToFloat(d[i]));
    let s = 0, n = 0;
    for (let i = 0; i < d.length / this.tex.skyKtx.layers; i += 4) { s += 0.2126 * val(i) + 0.7152 * val(i + 1) + 0.0722 * val(i + 2); ++n; }
    this.skyMean = s / n;
    return s > 0 ? 0.5 / (s / n) : 1;
  }
  crowdLoad() { return (this.crowdLoading ||= Crowd.load(this.gl, this.cfg.crowd.url, this.methods).then((c) => (this.crowd = c))); }
  setScene(mesh) { this.scene = new SceneRaster(this.gl, mesh, this.skyMean, this.cfg.sun); }
  streetIndex(streets = this.cfg.streets) {  // the street whose box (in its own frame) is nearest to the camera
    let best = 0, bd = Infinity;
    streets.forEach((s, i) => { const dist = distanceToStreet(s, this.cam.pos); if (dist < bd) { bd = dist; best = i; } });
    return best;
  }
  // A city: load the shard of the street the camera is in, unless loaded or loading.
  followShard() {
    if (!this.cfg.city || this.loading) return;
    const s = this.cfg.city.streets[this.streetIndex(this.cfg.city.streets)].shard;
    if (s !== this.shard) this.loading = this.loadShard(s).finally(() => { this.loading = null; });
  }
  async loadShard(s) {  // shard s's config (streets with uniforms) and face atlas; the sky is the city's
    status(`loading shard ${s + 1} of ${this.cfg.city.shards.length} ...`);
    const sc = await fetch(this.cfg.city.shards[s].config).then((r) => r.json());
    const ktx = await fetchKTX2(sc.files.atlas);
    const atlas = uploadAtlas(this.gl, ktx);
    this.gl.deleteTexture(this.tex.atlas);
    this.tex.atlas = atlas; this.tex.atlasKtx = ktx;
    this.cfg.streets = sc.streets; this.cfg.files.atlas = sc.files.atlas;
    this.shard = this.cfg.city.shard = s;
    status(statusLine(this.cfg, this.tex, this));
    this.render();
  }
  forward() { const { yaw, pitch } = this.cam; return [Math.cos(pitch) * Math.cos(yaw), Math.sin(pitch), Math.cos(pitch) * Math.sin(yaw)]; }
  placeGroup() {  // the spheres 7 m in front of the camera, across the view
    const f = this.forward(), h = Math.hypot(f[0], f[2]) || 1, fx = f[0] / h, fz = f[2] / h;
    const base = [this.cam.pos[0] + 7 * fx, 0, this.cam.pos[2] + 7 * fz], rx = -fz, rz = fx;
    const at = (lat, y, r) => [base[0] + lat * rx, y, base[2] + lat * rz, r];
    this.group = [at(-3, 0.6, 0.6), at(-1.5, 0.6, 0.6), at(0, 0.6, 0.6), at(1.5, 0.6, 0.6), at(3, 0.9, 0.35), at(3, 1.55, 0.18)];
    // sphere y above the street's ground under it (the nearest probe's ground plane and slope)
    const st = this.cfg.streets[this.streetIndex()];
    this.group.forEach((s) => { s[1] += groundAt(st, s); });
  }
  programFor(m) {
    if (!this.programs.has(m.name)) this.programs.set(m.name, program(this.gl, FULLSCREEN_VS, fragmentSource(this.lib, m, SCENE_MAIN), `view ${m.name}`));
    return this.programs.get(m.name);
  }
  render() {
    this.followShard();
    const gl = this.gl, canvas = gl.canvas;
    const si = this.streetIndex(), st = this.cfg.streets[si], o = st.origin;
    const prog = this.programFor(this.method);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.useProgram(prog);
    bindProbes(gl, prog, this.tex);
    setStreet(gl, prog, st.uniforms[this.method.planes === "fitted" ? "fitted" : "nominal"]);
    const loc = (v) => toLocal(st, v);
    const f = this.forward(), right = norm(cross(f, [0, 1, 0])), up = cross(right, f);
    const U = (n) => gl.getUniformLocation(prog, n);
    gl.uniform3fv(U("cam_pos"), loc(this.cam.pos));
    gl.uniformMatrix3fv(U("cam_rot"), false, [...right, ...up, -f[0], -f[1], -f[2]]);
    gl.uniform2f(U("viewport"), canvas.width, canvas.height);
    gl.uniform1f(U("tan_half_fov"), Math.tan(0.5 * 70 * Math.PI / 180));
    const sp = [], mt = [];
    this.group.forEach((s, i) => { sp.push(...loc(s), s[3]); mt.push(...MATERIALS[i].albedo, MATERIALS[i].kind); });
    gl.uniform4fv(U("spheres"), sp);
    gl.uniform2fv(U("view_frame"), st.uniforms.nominal.frame);
    gl.uniform4fv(U("materials"), mt);
    gl.uniform1i(U("nspheres"), this.group.length);
    gl.uniform1f(U("glossy_power"), this.glossyPower);
    gl.uniform1f(U("background_power"), this.cfg.powers[0] || 1e6);
    gl.uniform1f(U("exposure"), this.exposure0 * Math.pow(2, this.ev));
    gl.uniform1i(U("show_probes"), this.showProbes ? 1 : 0);
    gl.uniform2f(U("depth_ab"), DEPTH_AB[0], DEPTH_AB[1]);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.ALWAYS);
    gl.depthMask(true);
    gl.clearDepth(1);
    gl.clear(gl.DEPTH_BUFFER_BIT);
    gl.bindVertexArray(this.vao);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    if (this.scene && this.showScene) {
      this.scene.draw(this.cam.pos, [...right, ...up, -f[0], -f[1], -f[2]], Math.tan(0.5 * 70 * Math.PI / 180),
                      canvas.width / canvas.height, this.exposure0 * Math.pow(2, this.ev));
    }
    const rot = [...right, ...up, -f[0], -f[1], -f[2]], cs = this.crowd && this.cfg.streets[this.crowd.desc.street];
    if (cs) this.crowd.draw(this.crowd.camera(this.cam.pos, rot, Math.tan(0.5 * 70 * Math.PI / 180), canvas.width / canvas.height), cs, this.tex, this.method, this.exposure0 * Math.pow(2, this.ev));
    gl.disable(gl.DEPTH_TEST);
    this.cfg.currentMethod = this.method.name;
    drawMap($("map"), this.cfg, this.cam, this.group.concat(this.crowd ? this.crowd.positions() : []));  // spheres and walkers
    let where = `street ${st.name}${st.frame.yaw_deg ? ` (${st.frame.yaw_deg.toFixed(1)}\u00b0)` : ""}` +
      (this.cfg.city ? ` (shard ${this.shard + 1} of ${this.cfg.city.shards.length})` : "") + `  x=${this.cam.pos.map((v) => v.toFixed(1)).join(", ")} m  method ${this.method.name}`;
    const ev = nearestEvaluation(this.cfg.evaluation || [], this.cam.pos);
    if (ev && ev.dist < 5 && ev.e.error[this.method.name] !== undefined) {
      where += ` | evaluation position ${ev.dist.toFixed(1)} m away: rel. RMSE ${(100 * ev.e.error[this.method.name]).toFixed(1)} %`;
    }
    $("where").textContent = where;
  }
  // Lookups of `methodName` on street `si` at world points xs (n x 3 flat), unit ds, powers ws.
  lookups(methodName, si, xs, ds, ws) {
    const m = methodName === "plain" || methodName === "sky" ? { name: methodName } : this.methods.find((q) => q.name === methodName);
    if (!m) throw new Error(`method ${methodName} is not available in the viewer`);
    const st = this.cfg.streets[si], n = ws.length;
    const xw = new Float32Array(4 * n), d = new Float32Array(4 * n);
    for (let i = 0; i < n; ++i) {  // points: world -> street-local (frame); directions stay world
      xw.set(toLocal(st, [xs[3 * i], xs[3 * i + 1], xs[3 * i + 2]]), 4 * i);
      for (let c = 0; c < 3; ++c) d[4 * i + c] = ds[3 * i + c];
      xw[4 * i + 3] = ws[i];
    }
    this.runner.prepare(xw, d, 256);
    this.runner.draw(m, st.uniforms[m.planes === "fitted" ? "fitted" : "nominal"]);
    return this.runner.read();
  }
  // Street-local points (float32, flat) of world points xs (n x 3 flat) on street si, as the GLSL gets them.
  toLocal(si, xs) {
    const st = this.cfg.streets[si], out = [];
    for (let i = 0; i < xs.length; i += 3) out.push(...toLocal(st, [xs[i], xs[i + 1], xs[i + 2]]));
    return out;
  }
  // Median milliseconds per pass of `reps` full-screen passes of w x h lookups, per mode.
  bench(modes, w, h, reps) {
    const gl = this.gl, n = w * h, st = this.cfg.streets[0], o = st.origin;
    const a0 = toFrame(st, st.probes[0].position)[st.along], a1 = toFrame(st, st.probes[st.probes.length - 1].position)[st.along];
    const xw = new Float32Array(4 * n), d = new Float32Array(4 * n);
    let seed = 7;
    const rnd = () => { seed = (seed * 1103515245 + 12345) % 2147483648; return seed / 2147483648; };
    for (let i = 0; i < n; ++i) {  // points in the street (its frame), lobes over the sphere, w log-uniform 1 .. 1e4
      const p = [0, 0, 0];
      p[st.along] = a0 + (a1 - a0) * rnd(); p[2 - st.along] = st.planes[0] + (st.planes[1] - st.planes[0]) * rnd(); p[1] = st.planes[2] + 0.2 + 3 * rnd();
      const z = 2 * rnd() - 1, phi = 2 * Math.PI * rnd(), r = Math.sqrt(1 - z * z);
      xw.set([p[0] - o[0], p[1] - o[1], p[2] - o[2], Math.pow(10, 4 * rnd())], 4 * i);
      d.set([r * Math.cos(phi), z, r * Math.sin(phi), 0], 4 * i);
    }
    this.runner.prepare(xw, d, w);
    const px = new Float32Array(4), out = {};
    for (const name of modes) {
      const m = name === "plain" || name === "sky" ? { name } : this.methods.find((q) => q.name === name);
      const uni = st.uniforms[m.planes === "fitted" ? "fitted" : "nominal"];
      this.runner.draw(m, uni); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.FLOAT, px);  // compile + warm up
      const times = [];
      for (let r = 0; r < reps; ++r) {
        const t0 = performance.now();
        this.runner.draw(m, uni);
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.FLOAT, px);  // waits for the pass
        times.push(performance.now() - t0);
      }
      times.sort((a, b) => a - b);
      out[name] = times[Math.floor(times.length / 2)];
    }
    return out;
  }
}

function nearestEvaluation(list, p) {
  let best = null;
  for (const e of list) {
    const dist = Math.hypot(e.position[0] - p[0], e.position[1] - p[1], e.position[2] - p[2]);
    if (!best || dist < best.dist) best = { e, dist };
  }
  return best;
}

function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
function norm(a) { const l = Math.hypot(...a) || 1; return a.map((v) => v / l); }
function halfToFloat(h) {
  const s = h & 0x8000 ? -1 : 1, e = (h >> 10) & 0x1f, f = h & 0x3ff;
  if (e === 0) return s * f * Math.pow(2, -24);
  if (e === 31) return f ? NaN : s * Infinity;
  return s * (1 + f / 1024) * Math.pow(2, e - 15);
}

// The top-down map: streets (between their facades), probes, the spheres, the camera.
function mapStreets(cfg) { return cfg.city ? cfg.city.streets : cfg.streets; }  // a city: all its streets

function mapTransform(canvas, cfg) {  // bounds of the streets' world corners
  let x0 = Infinity, x1 = -Infinity, z0 = Infinity, z1 = -Infinity;
  for (const s of mapStreets(cfg)) {
    for (const [x, z] of s.corners) { x0 = Math.min(x0, x); x1 = Math.max(x1, x); z0 = Math.min(z0, z); z1 = Math.max(z1, z); }
  }
  const pad = 10, sc = Math.min((canvas.width - 2 * pad) / (x1 - x0 || 1), (canvas.height - 2 * pad) / (z1 - z0 || 1));
  const ox = pad + 0.5 * (canvas.width - 2 * pad - sc * (x1 - x0)), oz = pad + 0.5 * (canvas.height - 2 * pad - sc * (z1 - z0));
  return { to: (x, z) => [ox + sc * (x - x0), oz + sc * (z - z0)], from: (u, v) => [x0 + (u - ox) / sc, z0 + (v - oz) / sc], sc };
}

function drawMap(canvas, cfg, cam, group) {
  const c = canvas.getContext("2d"), T = mapTransform(canvas, cfg);
  c.fillStyle = "#222"; c.fillRect(0, 0, canvas.width, canvas.height);
  for (const s of mapStreets(cfg)) {  // the street between its facades: a rectangle turned with its frame
    c.fillStyle = "#555"; c.strokeStyle = "#555"; c.lineWidth = 2; c.beginPath();
    s.corners.forEach(([x, z], k) => { const [u, v] = T.to(x, z); if (k === 0) c.moveTo(u, v); else c.lineTo(u, v); });
    c.closePath(); c.fill(); c.stroke();
  }
  for (const s of cfg.streets) {  // the probes (a city: of the loaded shard)
    c.fillStyle = "#fc3";
    for (const p of s.probes) { const [u, v] = T.to(p.position[0], p.position[2]); c.beginPath(); c.arc(u, v, 3, 0, 2 * Math.PI); c.fill(); }
  }
  // evaluation positions of the report: squares colored by this method's error (green 0 .. red >= 50 %)
  for (const e of cfg.evaluation || []) {
    const err = e.error[cfg.currentMethod], [u, v] = T.to(e.position[0], e.position[2]);
    const t = err === undefined ? null : Math.min(1, err / 0.5);
    c.fillStyle = t === null ? "#888" : `rgb(${Math.round(255 * t)}, ${Math.round(255 * (1 - t))}, 60)`;
    c.fillRect(u - 3, v - 3, 6, 6);
  }
  c.fillStyle = "#6cf";
  for (const s of group) { const [u, v] = T.to(s[0], s[2]); c.fillRect(u - 1.5, v - 1.5, 3, 3); }
  const [u, v] = T.to(cam.pos[0], cam.pos[2]);
  c.strokeStyle = "#f44"; c.lineWidth = 2; c.beginPath(); c.arc(u, v, 5, 0, 2 * Math.PI);
  c.moveTo(u, v); c.lineTo(u + 14 * Math.cos(cam.yaw), v + 14 * Math.sin(cam.yaw)); c.stroke();
}

function setupControls(viewer) {
  const sel = $("method");
  for (const m of viewer.methods) { const o = document.createElement("option"); o.value = m.name; o.textContent = m.name; o.title = m.summary; sel.appendChild(o); }
  sel.value = viewer.method.name;
  const redraw = () => requestAnimationFrame(() => viewer.render());
  sel.onchange = () => { viewer.method = viewer.methods.find((m) => m.name === sel.value); redraw(); };
  const lp = $("power");
  lp.oninput = () => { viewer.glossyPower = Math.pow(10, Number(lp.value)); $("power_value").textContent = viewer.glossyPower.toFixed(viewer.glossyPower < 10 ? 1 : 0); redraw(); };
  lp.value = String(Math.log10(viewer.glossyPower)); lp.oninput();
  const ev = $("ev");
  ev.oninput = () => { viewer.ev = Number(ev.value); $("ev_value").textContent = ev.value; redraw(); };
  $("probes").onchange = (e) => { viewer.showProbes = e.target.checked; redraw(); };
  $("group").onclick = () => { viewer.placeGroup(); redraw(); };
  setupCrowdControls(viewer, redraw);
  const canvas = viewer.gl.canvas;
  let drag = null;
  canvas.onmousedown = (e) => { drag = [e.clientX, e.clientY]; };
  window.onmouseup = () => { drag = null; };
  window.onmousemove = (e) => {
    if (!drag) return;
    viewer.cam.yaw += 0.005 * (e.clientX - drag[0]);
    viewer.cam.pitch = Math.max(-1.5, Math.min(1.5, viewer.cam.pitch - 0.005 * (e.clientY - drag[1])));
    drag = [e.clientX, e.clientY]; redraw();
  };
  canvas.onwheel = (e) => { e.preventDefault(); move(viewer, -Math.sign(e.deltaY) * 2, 0, 0); redraw(); };
  $("map").onclick = (e) => {
    const r = e.target.getBoundingClientRect(), [x, z] = mapTransform(e.target, viewer.cfg).from(e.clientX - r.left, e.clientY - r.top);
    viewer.cam.pos[0] = x; viewer.cam.pos[2] = z; redraw();
  };
  window.onkeydown = (e) => {
    if (e.target.tagName === "SELECT" || e.target.tagName === "INPUT") return;
    const k = e.key.toLowerCase(), step = e.shiftKey ? 5 : 1;
    const moves = { w: [step, 0, 0], s: [-step, 0, 0], a: [0, -step, 0], d: [0, step, 0], e: [0, 0, 0.5], q: [0, 0, -0.5] };
    if (moves[k]) move(viewer, ...moves[k]);
    else if (k === "arrowleft") viewer.cam.yaw -= 0.05;
    else if (k === "arrowright") viewer.cam.yaw += 0.05;
    else if (k === "arrowup") viewer.cam.pitch = Math.min(1.5, viewer.cam.pitch + 0.05);
    else if (k === "arrowdown") viewer.cam.pitch = Math.max(-1.5, viewer.cam.pitch - 0.05);
    else if (k === "g") viewer.placeGroup();
    else if (/^[1-9]$/.test(k) && viewer.methods[Number(k) - 1]) { viewer.method = viewer.methods[Number(k) - 1]; sel.value = viewer.method.name; }
    else return;
    e.preventDefault(); redraw();
  };
}

function move(viewer, fwd, side, up) {
  const f = viewer.forward(), h = Math.hypot(f[0], f[2]) || 1, fx = f[0] / h, fz = f[2] / h;
  viewer.cam.pos[0] += fwd * fx - side * fz;
  viewer.cam.pos[2] += fwd * fz + side * fx;
  viewer.cam.pos[1] = Math.max(0.1, viewer.cam.pos[1] + up);
}

async function main() {
  const canvas = $("view");
  const gl = canvas.getContext("webgl2", { antialias: false, preserveDrawingBuffer: true });
  if (!gl) throw new Error("this browser has no WebGL2");
  const [config, library] = await Promise.all([
    fetch("api/config.json").then((r) => r.json()), fetch("api/runtime.glsl").then((r) => r.text())]);
  status("loading probes ...");
  const textures = await loadProbeSet(gl, config.files, { skyLayer0: !!config.ladder });
  const viewer = new Viewer(config, library, gl, textures);
  if (config.files.scene) {
    status("loading scene.glb ...");
    viewer.setScene(await loadGlb(config.files.scene));
  }
  setupControls(viewer);
  for (const url of config.plots) {
    const fig = document.createElement("figure"), img = document.createElement("img"), cap = document.createElement("figcaption");
    img.src = url; cap.textContent = url.split("/").pop(); fig.append(img, cap); $("plots").appendChild(fig);
  }
  $("plots_title").hidden = config.plots.length === 0;
  viewer.render();
  status(statusLine(config, textures, viewer));
  return viewer;
}

function statusLine(config, textures, viewer) {
  const where = config.city
    ? `a city of ${config.city.streets.length} streets in ${config.city.shards.length} shards (shard ${viewer.shard + 1}: ` +
      `${config.streets.length} street(s), ${config.streets.reduce((n, s) => n + s.probes.length, 0)} probes)`
    : `${config.streets.length} street(s), ${config.streets.reduce((n, s) => n + s.probes.length, 0)} probes`;
  return `${config.scene || "probe set"}: ${where}, ${config.resolution}\u00b2 faces, sky ${skyPlanName(textures.skyPlan)}` +
         (config.ladder ? `, rung ladder ${config.ladder.mode}: shown through ${config.ladder.shown}` : "") +
         (viewer.scene ? `, scene.glb ${viewer.scene.triangles} triangles` : "");
}

const ready = main().catch((err) => { status("error: " + err.message); console.error(err.message); throw err; });
window.envcap = {
  ready: ready.then(() => true),
  viewer: null,
};
ready.then((v) => {
  window.envcap.viewer = v;
  window.envcap.lookups = (...a) => v.lookups(...a);
  window.envcap.bench = (...a) => v.bench(...a);
  window.envcap.methods = () => v.methods.map((m) => m.name);
  window.envcap.mapPoint = (x, z) => mapTransform($("map"), v.cfg).to(x, z);  // world plan point -> map pixel
  window.envcap.crowd = () => v.crowdLoad();  // the crowd (crowd.js Crowd), loaded on first use
  window.envcap.settled = () => Promise.resolve(v.loading).then(() => v.shard);  // a city: the shard once loaded
});
