// envcap viewer: the crowd of `envcap crowd` walking in the street view, drawn with the same GLSL
// (shaders/crowd/crowd_vert.glsl and crowd_frag.glsl for the WebGL2 target, served as
// api/crowd_vert.glsl / api/crowd_frag.glsl) from the same numpy: the server places and poses
// the walkers (envcap/viewer/crowd_site.py) and sends each frame's instance and neighbour
// textures; the page uploads a frame and draws every walker in one instanced call, composed by
// depth with the spheres and scene.glb (the projection of scene_raster.js).
//
// The fragment stage is crowd_frag.glsl with its `main` renamed (`#define main crowd_shade`) and a
// `main` after it that tone-maps its linear out_color as the page does (crowd_exposure > 0), or
// keeps it linear (0: the tests' float target; < 0: the varyings, renderLinear).  The lookup is the page's method when the crowd
// shader runs it (crowd.json `methods`), else crowd.json `default_method`.
import { program, setStreet } from "./runtime.js";
import { DEPTH_AB } from "./scene_raster.js";

const FRAG_MAIN = `
#undef main
uniform float crowd_exposure;
void main() {
    crowd_shade();
    if (crowd_exposure == -1.0) out_color = vec4(v_position, float(v_walker + 1));   // tests: the shading point, walker + 1
    else if (crowd_exposure == -2.0) out_color = vec4(normalize(v_normal), 1.0);
    else if (crowd_exposure == -3.0) out_color = g_self0;
    else if (crowd_exposure == -4.0) out_color = g_self1;
    else if (crowd_exposure > 0.0) {
        vec3 c = out_color.rgb * crowd_exposure;
        c = c / (1.0 + c);
        out_color = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
    }
}`;
const ATTRIBUTES = [["in_position", 3], ["in_normal", 3], ["in_joints", 4], ["in_weights", 4], ["in_blockers", 4], ["in_blocker_weights", 4]];

export class Crowd {
  // crowd.json (`desc`), the avatar mesh (avatar.bin), the two GLSL sources; `methods`: config.methods.
  static async load(gl, url, methods) {
    const desc = await fetch(url).then((r) => r.json());
    const [mesh, vert, frag] = await Promise.all([
      fetch(desc.avatar.url).then((r) => r.arrayBuffer()), fetch("api/crowd_vert.glsl").then((r) => r.text()),
      fetch("api/crowd_frag.glsl").then((r) => r.text())]);
    const crowd = new Crowd(gl, desc, mesh, vert, frag, methods);
    await crowd.setCount(desc.default_count);
    return crowd;
  }
  constructor(gl, desc, mesh, vert, frag, methods) {
    if (!gl.getExtension("EXT_color_buffer_float")) throw new Error("WebGL2 without EXT_color_buffer_float");
    this.gl = gl; this.desc = desc; this.vert = vert; this.frag = frag; this.methods = methods;
    this.programs = new Map(); this.clips = new Map();
    this.on = true; this.terms = 2; this.frame = 0; this.time = 0; this.count = 0; this.uploaded = null;
    const a = desc.avatar, nv = a.vertices * a.vertex_floats;
    this.vertices = new Float32Array(mesh, 0, nv);
    this.indices = new Uint32Array(mesh, 4 * nv, 3 * a.triangles);
    this.rowTexels = desc.texels_per_joint * desc.joints;
    this.instances = this._texture(); this.neighbours = this._texture();
  }
  _texture() {
    const gl = this.gl, t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    for (const k of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, k, gl.NEAREST);
    return t;
  }
  // The walkers' clip of `n` (walkers_n.bin, fetched once).
  async setCount(n) {
    const url = this.desc.counts[String(n)];
    if (!url) throw new Error(`the crowd has no clip of ${n} walkers (counts: ${Object.keys(this.desc.counts).join(", ")})`);
    if (!this.clips.has(n)) this.clips.set(n, new Float32Array(await fetch(url).then((r) => r.arrayBuffer())));
    this.count = n; this.uploaded = null;
  }
  // World positions [x, y, z] of the walkers shown (their first joint's head, clip frame), for the map.
  positions() {
    if (!this.on || !this.count) return [];
    const clip = this.clips.get(this.count), d = this.desc, o = d.origin, row = this.rowTexels * 4;
    const base = this.frame * this.count * (row + 2 * d.neighbours * 4), at = 4 * 5 * d.joints, out = [];
    for (let i = 0; i < this.count; ++i) { const k = base + i * row + at; out.push([clip[k] + o[0], clip[k + 1] + o[1], clip[k + 2] + o[2]]); }
    return out;
  }
  setTime(t) { this.time = t; this.frame = Math.floor(t * this.desc.fps + 1e-6) % this.desc.frames; }
  method(pageMethod) {  // {name, glsl, planes, taps} the crowd shader runs
    const name = this.desc.methods.includes(pageMethod.name) ? pageMethod.name : this.desc.default_method;
    return this.methods.find((m) => m.name === name);
  }
  programFor(m) {
    if (!this.programs.has(m.name)) {
      const nl = this.frag.indexOf("\n");
      const head = `#define CROWD_METHOD ${m.glsl}\n#define ENVCAP_ANISO_TAPS ${m.taps || 2}\n#define main crowd_shade\n`;
      const fs = this.frag.slice(0, nl + 1) + head + this.frag.slice(nl + 1) + FRAG_MAIN;
      const gl = this.gl, p = program(gl, this.vert, fs, `crowd ${m.name}`);
      const vao = gl.createVertexArray(), vbo = gl.createBuffer(), ibo = gl.createBuffer();
      gl.bindVertexArray(vao);
      gl.bindBuffer(gl.ARRAY_BUFFER, vbo);
      gl.bufferData(gl.ARRAY_BUFFER, this.vertices, gl.STATIC_DRAW);
      let off = 0;
      for (const [name, n] of ATTRIBUTES) {
        const loc = gl.getAttribLocation(p, name);
        if (loc >= 0) { gl.enableVertexAttribArray(loc); gl.vertexAttribPointer(loc, n, gl.FLOAT, false, 4 * this.desc.avatar.vertex_floats, 4 * off); }
        off += n;
      }
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibo);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, this.indices, gl.STATIC_DRAW);
      gl.bindVertexArray(null);
      this.programs.set(m.name, { p, vao });
    }
    return this.programs.get(m.name);
  }
  _upload() {  // frame `this.frame` of the clip into the instance and neighbour textures
    const key = `${this.count}/${this.frame}`;
    if (this.uploaded === key) return;
    const gl = this.gl, n = this.count, clip = this.clips.get(n), d = this.desc;
    const ni = n * this.rowTexels * 4, nn = n * 2 * d.neighbours * 4, base = this.frame * (ni + nn);
    gl.bindTexture(gl.TEXTURE_2D, this.instances);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, this.rowTexels, n, 0, gl.RGBA, gl.FLOAT, clip.subarray(base, base + ni));
    gl.bindTexture(gl.TEXTURE_2D, this.neighbours);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, 2 * d.neighbours, n, 0, gl.RGBA, gl.FLOAT, clip.subarray(base + ni, base + ni + nn));
    this.uploaded = key;
  }
  // The page camera's clip-from-render-origin matrix (column-major, float32): eye space as
  // scene_raster.js (columns of camRot: right, up, back), its projection (DEPTH_AB); and the eye
  // relative to the render origin.  Differences to the origin in float64.
  camera(camPos, camRot, tanHalfFov, aspect) {
    const o = this.desc.origin, t = [o[0] - camPos[0], o[1] - camPos[1], o[2] - camPos[2]];
    const axis = (k) => [camRot[3 * k], camRot[3 * k + 1], camRot[3 * k + 2]];
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    const rows = [[1 / (tanHalfFov * aspect), axis(0)], [1 / tanHalfFov, axis(1)], [DEPTH_AB[0], axis(2)], [-1, axis(2)]];
    const m = new Float32Array(16);
    rows.forEach(([s, a], r) => { for (let c = 0; c < 3; ++c) m[4 * c + r] = s * a[c]; m[12 + r] = s * dot(a, t) + (r === 2 ? DEPTH_AB[1] : 0); });
    return { viewProj: m, eye: [-t[0], -t[1], -t[2]] };
  }
  // Draw the crowd into the bound framebuffer with the depth test: `view` {viewProj, eye} from
  // camera(), `street` the config street (its uniforms), `tex` the page's probe textures,
  // `pageMethod` the page's method, `exposure` (0: linear radiance out).
  draw(view, street, tex, pageMethod, exposure) {
    if (!this.on || !this.count) return;
    const gl = this.gl, d = this.desc, m = this.method(pageMethod), { p, vao } = this.programFor(m), mat = d.material;
    this._upload();
    gl.useProgram(p);
    setStreet(gl, p, street.uniforms[m.planes === "fitted" ? "fitted" : "nominal"]);
    const units = [[gl.TEXTURE_2D_ARRAY, tex.atlas, "probes"], [gl.TEXTURE_CUBE_MAP, tex.sky, "sky"],
                   [gl.TEXTURE_2D, this.instances, "crowd_instances"], [gl.TEXTURE_2D, this.neighbours, "crowd_neighbours"]];
    const U = (n) => gl.getUniformLocation(p, n);
    units.forEach(([target, t, name], i) => { gl.activeTexture(gl.TEXTURE0 + i); gl.bindTexture(target, t); gl.uniform1i(U(name), i); });
    gl.uniformMatrix4fv(U("crowd_view_proj"), false, view.viewProj);
    gl.uniformMatrix3fv(U("crowd_to_local"), false, new Float32Array(d.to_local));
    gl.uniform3fv(U("crowd_camera"), view.eye);
    gl.uniform1i(U("crowd_joint_count"), d.joints);
    gl.uniform1i(U("crowd_terms"), this.terms);
    gl.uniform3fv(U("crowd_rho_d"), mat.crowd_rho_d);
    gl.uniform4fv(U("crowd_C"), mat.crowd_C);
    gl.uniform3fv(U("crowd_rho_s"), mat.crowd_rho_s);
    gl.uniform1i(U("crowd_nlobes"), mat.crowd_nlobes);
    gl.uniform1f(U("crowd_albedo"), mat.crowd_albedo);
    gl.uniform3fv(U("crowd_sun_dir"), d.sun.direction);
    gl.uniform3fv(U("crowd_sun_e"), d.sun.irradiance);
    gl.uniform1f(U("crowd_sun_cos"), d.sun.cos_radius);
    gl.uniform1f(U("crowd_near_factor"), d.near_factor);
    gl.uniform1f(U("crowd_exposure"), exposure);
    gl.enable(gl.DEPTH_TEST); gl.depthFunc(gl.LESS); gl.depthMask(true);
    gl.bindVertexArray(vao);
    gl.drawElementsInstanced(gl.TRIANGLES, this.indices.length, gl.UNSIGNED_INT, 0, this.count);
    gl.bindVertexArray(null);
  }
  // Tests: the crowd alone into a width x height RGBA32F target cleared to 0 (linear radiance,
  // alpha 1 on walkers), rows from the bottom; `view` {viewProj (16, column-major), eye}.
  // `output`: 0 radiance, -1 the shading point (render frame; w: walker + 1), -2 the interpolated
  // normal, -3 / -4 the self spheres the fragment placed (crowd_frag.glsl g_self0 / g_self1).
  renderLinear(view, street, tex, pageMethod, width, height, output = 0) {
    const gl = this.gl, fbo = gl.createFramebuffer(), color = gl.createTexture(), depth = gl.createRenderbuffer();
    gl.bindTexture(gl.TEXTURE_2D, color);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, width, height, 0, gl.RGBA, gl.FLOAT, null);
    gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, width, height);
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, color, 0);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
    gl.viewport(0, 0, width, height);
    gl.clearColor(0, 0, 0, 0); gl.clearDepth(1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    this.draw({ viewProj: new Float32Array(view.viewProj), eye: view.eye }, street, tex, pageMethod, output);
    const px = new Float32Array(4 * width * height);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.FLOAT, px);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.deleteFramebuffer(fbo); gl.deleteTexture(color); gl.deleteRenderbuffer(depth);
    gl.disable(gl.DEPTH_TEST);
    return px;
  }
}

// The crowd's controls (index.html #crowd_controls): on/off, terms, walker count, walking.
// `viewer.crowdLoad()` loads the crowd on first use; `redraw()` asks for a frame.
export function setupCrowdControls(viewer, redraw) {
  const $ = (id) => document.getElementById(id);
  if (!viewer.cfg.crowd) return;
  $("crowd_controls").hidden = false;
  for (const n of viewer.cfg.crowd.counts) { const o = document.createElement("option"); o.value = o.textContent = String(n); $("crowd_count").appendChild(o); }
  $("crowd_count").value = String(viewer.cfg.crowd.default_count);
  // walking: advance the clip's time by the time that passed, one frame of the clip at a time
  // (a timer at its frame rate: drawing more often would show the same frame again)
  let last = null;
  const step = () => {
    if (!viewer.crowd || !$("crowd_walk").checked || !viewer.crowd.on) { last = null; return; }
    const now = performance.now();
    if (last !== null) viewer.crowd.setTime(viewer.crowd.time + (now - last) / 1000);
    last = now; viewer.render(); setTimeout(step, 1000 / viewer.crowd.desc.fps);
  };
  const apply = async () => {
    const c = await viewer.crowdLoad();
    c.on = $("crowd").checked; c.terms = Number($("crowd_terms").value);
    await c.setCount(Number($("crowd_count").value));
    redraw();
    if ($("crowd_walk").checked && last === null) step();
  };
  for (const id of ["crowd", "crowd_terms", "crowd_count", "crowd_walk"]) $(id).onchange = () => { apply().catch((e) => { $("status").textContent = "crowd: " + e.message; }); };
}
