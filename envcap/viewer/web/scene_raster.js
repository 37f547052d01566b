// envcap viewer: the bake's scene.glb (gltf.js) rasterized as the street geometry, with a simple
// sun + sky Lambert look (not the runtime: the probes shade the crowd objects, not the streets).
// Camera-relative: each frame the mesh is drawn at (mesh origin - camera) in float32 from a float64
// difference, so a scene far from the world origin keeps its float32 steps.  The projection is the
// one the ray-traced spheres use to write gl_FragDepth (viewer.js, SCENE_MAIN): the two compose
// by the depth test.
import { program } from "./runtime.js";

export const NEAR_M = 0.05;
export const FAR_M = 5000.0;
// clip z = A ze + B, clip w = -ze (ze < 0 in front of the camera; OpenGL's perspective matrix)
export const DEPTH_AB = [-(FAR_M + NEAR_M) / (FAR_M - NEAR_M), -2 * FAR_M * NEAR_M / (FAR_M - NEAR_M)];
export const SUN_TO_SKY = 3.0;
// Sun illuminance on a surface facing it, as a multiple of pi x the mean sky luminance (a look,
// not a measurement: the page has the sun's direction only).

const VS = `#version 300 es
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_nrm;
layout(location = 2) in vec3 a_col;
layout(location = 3) in vec3 a_emi;
uniform vec3 offset;      // mesh origin - camera, world m
uniform mat3 cam_rot;     // columns: right, up, back
uniform vec2 proj_xy;     // focal / aspect, focal
uniform vec2 depth_ab;
out vec3 v_nrm; out vec3 v_col; out vec3 v_emi;
void main() {
    vec3 e = (a_pos + offset) * cam_rot;   // transpose(cam_rot) * v: eye space
    v_nrm = a_nrm; v_col = a_col; v_emi = a_emi;
    gl_Position = vec4(e.x * proj_xy.x, e.y * proj_xy.y, depth_ab.x * e.z + depth_ab.y, -e.z);
}`;

const FS = `#version 300 es
precision highp float;
in vec3 v_nrm; in vec3 v_col; in vec3 v_emi;
uniform vec3 sun;         // unit, towards the sun (world)
uniform float sky_l;      // mean sky luminance (the sky's broadest level)
uniform float sun_e;      // sun illuminance facing it
uniform float exposure;
out vec4 o;
void main() {
    vec3 n = normalize(v_nrm);
    // uniform sky over the hemisphere above n: E = pi L (1 + n.y) / 2; plus the sun, no shadows
    float e = 3.14159265 * sky_l * (0.5 + 0.5 * n.y) + sun_e * max(dot(n, sun), 0.0);
    vec3 c = (v_col * (e / 3.14159265) + v_emi) * exposure;
    c = c / (1.0 + c);
    o = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
}`;

export class SceneRaster {
  // `mesh`: parseGlb's result; `skyMean`: mean sky luminance; `sun`: unit direction or null.
  constructor(gl, mesh, skyMean, sun) {
    this.gl = gl; this.origin = mesh.origin; this.triangles = mesh.triangles;
    this.count = mesh.indices.length; this.skyMean = skyMean; this.sun = sun;
    this.prog = program(gl, VS, FS, "scene.glb raster");
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    [mesh.positions, mesh.normals, mesh.colors, mesh.emission].forEach((data, loc) => {
      const b = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, b);
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
    });
    const ib = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, mesh.indices, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
  }
  // Draw with the depth test (LESS) over what is in the bound framebuffer; camera at world
  // `camPos` (float64), `camRot` the 9 numbers of cam_rot, vertical tan(fov / 2), aspect w / h.
  draw(camPos, camRot, tanHalfFov, aspect, exposure) {
    const gl = this.gl, U = (n) => gl.getUniformLocation(this.prog, n);
    gl.useProgram(this.prog);
    gl.uniform3f(U("offset"), Math.fround(this.origin[0] - camPos[0]), Math.fround(this.origin[1] - camPos[1]), Math.fround(this.origin[2] - camPos[2]));
    gl.uniformMatrix3fv(U("cam_rot"), false, camRot);
    gl.uniform2f(U("proj_xy"), 1 / (tanHalfFov * aspect), 1 / tanHalfFov);
    gl.uniform2f(U("depth_ab"), DEPTH_AB[0], DEPTH_AB[1]);
    gl.uniform3fv(U("sun"), this.sun || [0, 1, 0]);
    gl.uniform1f(U("sky_l"), this.skyMean);
    gl.uniform1f(U("sun_e"), this.sun ? SUN_TO_SKY * Math.PI * this.skyMean : 0);
    gl.uniform1f(U("exposure"), exposure);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    gl.bindVertexArray(this.vao);
    gl.drawElements(gl.TRIANGLES, this.count, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
  }
}
