// envcap viewer: the runtime GLSL (WebGL2 target, served as /api/runtime.glsl) compiled into
// programs, one per parallax method, and the street uniforms uploaded from /api/config.json.
// The page's lookups go through `viewer_lookup(x, d, w)`: the method's runtime function
// (envcap_sample_nearest for planes_mip and fitted_planes_mip, envcap_sample_blended for blend, ...)
// or, for the two methods without one, the page's own `viewer_nearest` / `viewer_planes`.

export const VIEWER_GLSL = `
uniform ENVCAP_PROBES_SAMPLER envcap_probes;
uniform samplerCube envcap_sky;
// nearest: the nearest probe along d itself at z(w), over the sky (numpy: methods/nearest.py)
vec3 viewer_nearest(ENVCAP_PROBES_SAMPLER probes, samplerCube sky, vec3 x, vec3 d, float w, EnvcapStreet s)
{
    int i = envcap_nearest_probe(x[s.along], s.along_s, s.count);
    float z = envcap_clamp_level(envcap_z_of_w(w, s.xk, s.nlevels), s.nlevels);
    return envcap_over_sky(ENVCAP_PROBES_LOD(probes, envcap_frame_dir(d, s.frame), s.pos[i].w, z), sky, d, w, s);
}
// planes: three-plane parallax, unshifted level z(w) (numpy: methods/planes.py)
vec3 viewer_planes(ENVCAP_PROBES_SAMPLER probes, samplerCube sky, vec3 x, vec3 d, float w, EnvcapStreet s)
{
    int i = envcap_nearest_probe(x[s.along], s.along_s, s.count);
    vec4 par = envcap_parallax(x, envcap_frame_dir(d, s.frame), s.pos[i].xyz, s.planes[i], s.along);
    float z = envcap_clamp_level(envcap_z_of_w(w, s.xk, s.nlevels), s.nlevels);
    return envcap_over_sky(ENVCAP_PROBES_LOD(probes, par.xyz, s.pos[i].w, z), sky, d, w, s);
}
`;

// The lookup of one method: `vec3 viewer_lookup(vec3 x, vec3 d, float w)` (x street-local m).
// Special modes for measurements: "plain" (one face-atlas lookup of probe 0 at level z(w), the
// WebGL2 counterpart of textureLod(samplerCubeArray)), "sky" (textureLod of the sky cube at z(w)).
export function lookupGLSL(method) {
  let body;
  if (method.name === "plain") {
    body = "return ENVCAP_PROBES_LOD(envcap_probes, d, envcap_street.pos[0].w, envcap_clamp_level(envcap_z_of_w(w, envcap_street.xk, envcap_street.nlevels), envcap_street.nlevels)).rgb;";
  } else if (method.name === "sky") {
    body = "return textureLod(envcap_sky, d, envcap_clamp_level(envcap_z_of_w(w, envcap_street.xk, envcap_street.nlevels), envcap_street.nlevels)).rgb;";
  } else {
    body = `return ${method.glsl}(envcap_probes, envcap_sky, x, d, w, envcap_street);`;
  }
  return `vec3 viewer_lookup(vec3 x, vec3 d, float w)\n{\n    ${body}\n}\n`;
}

// The full fragment source: library (with the method's defines after #version) + page code + `main`.
export function fragmentSource(library, method, mainCode) {
  const nl = library.indexOf("\n");
  const defines = `#define ENVCAP_ANISO_TAPS ${method.taps || 2}\n`;
  return library.slice(0, nl + 1) + defines + library.slice(nl + 1) + VIEWER_GLSL + lookupGLSL(method) + mainCode;
}

export const FULLSCREEN_VS = `#version 300 es
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}`;

function compile(gl, type, src, what) {
  const s = gl.createShader(type);
  gl.shaderSource(s, src);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) {
    throw new Error(`${what}: ${gl.getShaderInfoLog(s)}`);
  }
  return s;
}

export function program(gl, vs, fs, what) {
  const p = gl.createProgram();
  gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, vs, what + " (vertex)"));
  gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, fs, what + " (fragment)"));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(`${what}: ${gl.getProgramInfoLog(p)}`);
  return p;
}

// Upload one street's uniforms (config.streets[i].uniforms[planeSet]) to `envcap_street`.
const VEC4 = new Set(["pos", "planes"]);
const INT = new Set(["count", "along", "nlevels"]);
export function setStreet(gl, prog, uniforms) {
  for (const [name, v] of Object.entries(uniforms)) {
    const loc = gl.getUniformLocation(prog, `envcap_street.${name}`) || gl.getUniformLocation(prog, `envcap_street.${name}[0]`);
    if (loc === null) continue;  // optimized out by this method's program
    if (INT.has(name)) gl.uniform1i(loc, v);
    else if (VEC4.has(name)) gl.uniform4fv(loc, new Float32Array(v));
    else if (name === "frame") gl.uniform2fv(loc, new Float32Array(v));
    else gl.uniform1fv(loc, new Float32Array(v));
  }
}

export function bindProbes(gl, prog, tex) {
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex.atlas);
  gl.activeTexture(gl.TEXTURE1);
  gl.bindTexture(gl.TEXTURE_CUBE_MAP, tex.sky);
  gl.uniform1i(gl.getUniformLocation(prog, "envcap_probes"), 0);
  gl.uniform1i(gl.getUniformLocation(prog, "envcap_sky"), 1);
}

// Lookups at arbitrary (x, d, w) for tests and benchmarks: one RGBA32F input texel per lookup
// (x street-local in xyz, w in .w; d in a second texture), one RGBA32F output texel, read back.
const EVAL_MAIN = `
uniform highp sampler2D in_xw;
uniform highp sampler2D in_d;
out vec4 o;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 xw = texelFetch(in_xw, p, 0);
    vec3 d = texelFetch(in_d, p, 0).xyz;
    o = vec4(viewer_lookup(xw.xyz, d, xw.w), 1.0);
}`;

export class LookupRunner {
  constructor(gl, library, textures) {
    this.gl = gl; this.library = library; this.tex = textures; this.programs = new Map();
    if (!gl.getExtension("EXT_color_buffer_float")) throw new Error("WebGL2 without EXT_color_buffer_float: cannot read float results");
    this.vao = gl.createVertexArray();
  }
  programFor(method) {
    if (!this.programs.has(method.name)) {
      this.programs.set(method.name, program(this.gl, FULLSCREEN_VS, fragmentSource(this.library, method, EVAL_MAIN), `method ${method.name}`));
    }
    return this.programs.get(method.name);
  }
  _floatTex(w, h, data) {
    const gl = this.gl, t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, w, h, 0, gl.RGBA, gl.FLOAT, data);
    for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, gl.NEAREST], [gl.TEXTURE_MAG_FILTER, gl.NEAREST]]) gl.texParameteri(gl.TEXTURE_2D, k, v);
    return t;
  }
  // Prepare n lookups (xw: Float32Array 4n street-local x + w, d: Float32Array 4n) on a w x h grid.
  prepare(xw, d, width) {
    const gl = this.gl, n = xw.length / 4, w = Math.min(n, width), h = Math.ceil(n / w);
    const pad = (a) => { const b = new Float32Array(w * h * 4); b.set(a); return b; };
    this.release();
    this.size = [w, h]; this.n = n;
    this.inXw = this._floatTex(w, h, pad(xw));
    this.inD = this._floatTex(w, h, pad(d));
    this.out = this._floatTex(w, h, null);
    this.fbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.fbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, this.out, 0);
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) throw new Error("RGBA32F framebuffer incomplete");
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  }
  draw(method, uniforms) {
    const gl = this.gl, prog = this.programFor(method);
    gl.useProgram(prog);
    bindProbes(gl, prog, this.tex);
    setStreet(gl, prog, uniforms);
    gl.activeTexture(gl.TEXTURE2); gl.bindTexture(gl.TEXTURE_2D, this.inXw);
    gl.activeTexture(gl.TEXTURE3); gl.bindTexture(gl.TEXTURE_2D, this.inD);
    gl.uniform1i(gl.getUniformLocation(prog, "in_xw"), 2);
    gl.uniform1i(gl.getUniformLocation(prog, "in_d"), 3);
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.fbo);
    gl.viewport(0, 0, this.size[0], this.size[1]);
    gl.disable(gl.DEPTH_TEST);
    gl.bindVertexArray(this.vao);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  }
  read() {
    const gl = this.gl, [w, h] = this.size, px = new Float32Array(w * h * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.fbo);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.FLOAT, px);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    const out = new Array(this.n * 3);
    for (let i = 0; i < this.n; ++i) for (let c = 0; c < 3; ++c) out[3 * i + c] = px[4 * i + c];
    return out;
  }
  release() {
    const gl = this.gl;
    for (const t of [this.inXw, this.inD, this.out]) if (t) gl.deleteTexture(t);
    if (this.fbo) gl.deleteFramebuffer(this.fbo);
    this.inXw = this.inD = this.out = this.fbo = null;
  }
}
