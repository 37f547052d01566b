"""Render docs/images/runtime_sphere.png: a sphere in a street lit by the runtime library (Eq. 3,
two Lafortune materials), without parallax (left) and with parallax + mip shift (right).

The probe set is synthetic: the analytic street of envcap.runtime.synthetic_street (facades 12 m apart,
12 m high, window pattern, checker ground), probes every 10 m, box-filtered mips.

    python3 docs/examples/render_sphere.py [--out docs/images/runtime_sphere.png] [--size 256]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image

import sys

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # run from a checkout without install

from envcap.runtime import synthetic_street as ss  # noqa: E402
from envcap.outputs import atomic_output_file
from envcap.gpu.context import create_context
from envcap.gpu.cube_array import CubeArrayTexture, cube_texture
from envcap.gpu.uniforms import set_uniforms
from envcap.core.resources import expand_includes

HERE = Path(__file__).resolve().parent
VERT = """#version 430
out vec2 uv;
void main() { vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2); uv = p; gl_Position = vec4(p * 2.0 - 1.0, 0, 1); }
"""


def tonemap(rgb: np.ndarray) -> np.ndarray:
    x = np.clip(rgb, 0, None)
    x = x / (1.0 + x)
    return (np.clip(x, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(HERE.parent / "images" / "runtime_sphere.png"))
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--face", type=int, default=128)
    args = ap.parse_args()
    probes, sky, street, powers = ss.synthetic_probe_set(args.face, count=4, start=0.0, end=30.0)
    ctx = create_context()
    pt, st = CubeArrayTexture(probes), cube_texture(ctx, sky)
    frag_src = (HERE / "sphere.frag").read_text()
    frag_src = expand_includes(frag_src)
    fbo = ctx.framebuffer([ctx.renderbuffer((args.size, args.size), 4, dtype="f4")])
    fbo.use()
    pt.use(3)
    st.use(4)
    # sphere 4.5 m off the probe line, near a facade, between probes: where parallax matters
    # positions go to GLSL in the street-local frame of the uniforms (here origin = (0, 0, 0))
    su = street.uniforms(powers)
    uni = {**su.values(), "eye": tuple(su.to_local((10.0, 2.2, -3.0))), "center": tuple(su.to_local((15.0, 1.3, 3.8))),
           "radius": 1.3}
    halves = []
    for par in (0, 1):
        src = frag_src.replace("#version 430", f"#version 430\n#define PARALLAX {par}", 1)
        prog = ctx.program(vertex_shader=VERT, fragment_shader=src)
        set_uniforms(prog, uni, sources=(src,))
        vao = ctx.vertex_array(prog, [])
        vao.render(vertices=3)
        img = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(args.size, args.size, 4)
        if not np.all(np.isfinite(img)):
            raise RuntimeError("render produced NaN or Inf")
        halves.append(tonemap(img[::-1, :, :3]))
        vao.release()
        prog.release()
    sep = np.full((args.size, 4, 3), 255, np.uint8)
    with atomic_output_file(args.out) as tmp:
        Image.fromarray(np.concatenate([halves[0], sep, halves[1]], axis=1)).save(tmp, format="PNG")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
