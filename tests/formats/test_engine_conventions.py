"""The engine recipes of docs/engines.md, section 5, checked against each engine's own lookup math,
transcribed from its source (no engine runs here): an envcap lat-long map of a direction-coded cube
(each texel's RGB = its direction), looked up the way the engine's sky shader does, must give back
the direction the engine looks along, once envcap's frame is mapped to the engine's.

* Godot 4 (``servers/rendering/renderer_rd/shaders/environment/sky.glsl``, godotengine/godot
  0095d7d0): ``SKY_COORDS = (atan(x, -z) / 2 pi  wrapped to [0, 1), acos(y) / pi)``, the image's
  top row at v = 0; Godot's world is envcap's (right-handed, Y up): no turn, no flip.
* Unity (``DefaultResourcesExtra/Skybox-Panoramic.shader``, Unity's built-in shaders, MIT):
  ``ToRadialCoords``: ``u = 0.5 - atan2(z, x) / 2 pi``, ``v = 1 - acos(y) / pi`` (v = 1 is the
  image's top row); the vertex is turned by ``RotateAroundYInDegrees(_Rotation)`` and the texture
  looked up along the unturned one.  Unity is left-handed: envcap's geometry goes in with X (or Z)
  negated, and the sky then needs the ``_Rotation`` that docs/recipes/EnvcapPanoramicSky.cs sets
  (read from that file here).
* Godot's textures from probes.ktx2 (docs/recipes/envcap_probes.gd): the script's reading,
  transcribed to Python, gives every layer-face the texels envcap's reader gives, each image with
  the full mip chain Godot's ``Image`` requires.
"""

import re
from pathlib import Path

import numpy as np
import pytest

from envcap.core import cube
from envcap.formats.latlong_exr import cube_to_latlong_seamless

RECIPE_CS = Path(__file__).resolve().parents[2] / "docs" / "recipes" / "EnvcapPanoramicSky.cs"
N = 32   # cube faces; the map is 64 x 128: a pixel spans 0.05 rad


@pytest.fixture(scope="module")
def direction_map():
    d = cube.texel_directions(N)
    return cube_to_latlong_seamless(np.concatenate([d, np.ones(d.shape[:-1] + (1,))], axis=-1))[..., :3]


def lookup(img, u, v_from_top):
    """Nearest-pixel lookup at texture coordinates (u to the right, v down from the top row)."""
    h, w = img.shape[:2]
    x = np.floor(np.mod(u, 1.0) * w).astype(int) % w
    y = np.clip(np.floor(v_from_top * h).astype(int), 0, h - 1)
    return img[y, x]


def unit(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d[np.abs(d[:, 1]) < 0.95]   # away from the poles, where a pixel spans every longitude


def godot_sky_coords(d):
    """Godot 4's SKY_COORDS of a world direction (sky.glsl)."""
    u = np.arctan2(d[:, 0], -d[:, 2])
    u = np.where(u < 0, u + 2 * np.pi, u) / (2 * np.pi)
    return u, np.arccos(np.clip(d[:, 1], -1, 1)) / np.pi


def unity_panoramic_coords(d_unity, rotation_deg):
    """Unity's Skybox/Panoramic texture coordinates (u, v from the top) of a Unity world direction."""
    a = np.radians(rotation_deg)
    # the vertex v is drawn at Rot(v) (RotateAroundYInDegrees); the lookup is along v = Rot^-1(d)
    x = np.cos(a) * d_unity[:, 0] + np.sin(a) * d_unity[:, 2]
    z = -np.sin(a) * d_unity[:, 0] + np.cos(a) * d_unity[:, 2]
    t = np.stack([x, d_unity[:, 1], z], axis=1)
    u = 0.5 - np.arctan2(t[:, 2], t[:, 0]) / (2 * np.pi)
    v = 1.0 - np.arccos(np.clip(t[:, 1], -1, 1)) / np.pi
    return u, 1.0 - v   # v counted from the bottom row in Unity


def worst_angle(got, want):
    got = got / np.linalg.norm(got, axis=1, keepdims=True)
    return float(np.degrees(np.arccos(np.clip(np.sum(got * want, axis=1), -1, 1))).max())


def test_godot_panorama_reads_envcap_latlong_as_is(direction_map):
    d = unit(4000, 0)
    u, v = godot_sky_coords(d)
    assert worst_angle(lookup(direction_map, u, v), d) < 4.0   # a pixel and a half at 64 x 128
    for axis in (0, 2):   # the check can fail: a mirrored map is far off
        m = d.copy()
        m[:, axis] *= -1
        assert worst_angle(lookup(direction_map, *godot_sky_coords(m)), d) > 90


def recipe_rotation(name):
    m = re.search(rf"{name}\s*=\s*([0-9.]+)f", RECIPE_CS.read_text())
    assert m, f"{name} not found in {RECIPE_CS.name}"
    return float(m.group(1))


@pytest.mark.parametrize("axis, constant", [(0, "RotationForXFlip"), (2, "RotationForZFlip")])
def test_unity_panoramic_needs_the_recipes_quarter_turn(direction_map, axis, constant):
    d = unit(4000, 1)                  # envcap world directions
    flip = np.ones(3)
    flip[axis] = -1.0
    d_unity = d * flip                 # the same direction in Unity's left-handed world
    rotation = recipe_rotation(constant)
    got = lookup(direction_map, *unity_panoramic_coords(d_unity, rotation))
    assert worst_angle(got, d) < 4.0, (constant, rotation)
    for other in (rotation + 90, rotation + 180, rotation + 270):   # any other turn is off
        wrong = lookup(direction_map, *unity_panoramic_coords(d_unity, other))
        assert worst_angle(wrong, d) > 60


def gdscript_cube_images(path):
    """docs/recipes/envcap_probes.gd ``cube_images``, transcribed line by line (Godot does not run
    here): per layer-face, the bytes of every level of its mip chain down to 1 x 1 (filler below the
    file's chain), as the script hands them to ``Image.create_from_data``."""
    b = Path(path).read_bytes()
    u32 = lambda o: int.from_bytes(b[o:o + 4], "little")   # noqa: E731  (PackedByteArray.decode_u32)
    u64 = lambda o: int.from_bytes(b[o:o + 8], "little")   # noqa: E731
    vk, n, layers, faces, levels = u32(12), u32(20), max(u32(32), 1), u32(36), max(u32(40), 1)
    assert faces == 6 and u32(44) == 0 and vk in (97, 109)
    texel = 8 if vk == 97 else 16
    chain = 1
    while (n >> (chain - 1)) > 1:
        chain += 1
    out = []
    for layer in range(layers):
        for face in range(6):
            data, last = b"", b""
            for k in range(chain):
                s = max(n >> k, 1)
                if k < levels:
                    size = s * s * texel
                    start = u64(80 + 24 * k) + (layer * 6 + face) * size
                    last = b[start:start + size]
                    data += last
                else:
                    data += last[:texel] * (s * s)
            out.append((n, chain, data))
    return out


def test_gdscript_reads_probes_ktx2_layer_faces_and_chains(canyon_probe_set, tmp_path):
    from envcap.probeset.store import read_probe_set, write_probe_set

    out = write_probe_set(tmp_path / "set", canyon_probe_set, exr=False, previews=False, writers=["ktx2"])
    ps = read_probe_set(out, distance=False)
    images = gdscript_cube_images(out / "probes.ktx2")
    assert len(images) == 6 * ps.layer_count   # CubemapArray: a multiple of 6 layers
    n = ps.resolution
    for i, (size, chain, data) in enumerate(images):
        layer, face = divmod(i, 6)
        assert size == n and chain == n.bit_length()   # Godot's full chain: n, n/2, ..., 1
        # Godot's Image size with mipmaps: the sum of the levels' sizes, down to 1 x 1
        assert len(data) == sum(max(n >> k, 1) ** 2 for k in range(chain)) * 8
        off = 0
        for k, level in enumerate(ps.levels):   # each stored level is envcap's texels of this layer and face
            s = max(n >> k, 1)
            got = np.frombuffer(data[off:off + s * s * 8], np.float16).reshape(s, s, 4)
            assert np.array_equal(got.astype(np.float32), np.asarray(level)[layer, face]), (layer, face, k)
            off += s * s * 8
    # control: the faces read face-major (a wrong stride) would not match
    wrong = np.frombuffer(images[1][2][:n * n * 8], np.float16).reshape(n, n, 4)
    assert not np.array_equal(wrong.astype(np.float32), np.asarray(ps.levels[0])[1, 0])
