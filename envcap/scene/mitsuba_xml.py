"""Mitsuba 3 scene XML as envcap surfaces (a ``[[mesh]]`` table's ``file = "city.xml"``).

Read with the standard library's XML parser (``xml.etree.ElementTree``).  What is taken:

* ``<shape type="ply">`` / ``"obj"`` with ``<string name="filename">`` (relative to the XML's
  folder) and ``<transform name="to_world">`` (``translate``, ``scale``, ``rotate``, ``matrix``,
  ``lookat``, applied in the order written, as Mitsuba does);
* the shape's bsdf (``<ref id>`` to a top-level ``<bsdf>``, or nested): see
  :mod:`envcap.scene.mesh_surfaces` for which reflectances are read; ``twosided`` is noted (envcap
  orients surfaces by the winding rule and lights the front side);
* an ``area`` emitter inside a shape: its ``radiance`` rgb becomes the shape's emission;
* ``<default name value>`` and ``$name`` substitution;
* ``<include filename="part.xml"/>``: the included scene's elements in its place (as Mitsuba
  does), read from the main file's folder or below it only (a name that leads outside it, through
  ``..`` or a link, is an error naming it), at most :data:`MAX_INCLUDE_DEPTH` deep and never in a
  cycle; file names inside it are relative to the main file's folder, as Mitsuba resolves them.
  (Before issue 20 an include was dropped without a word.)

What is skipped, each reported once in ``Surfaces.notes``: top-level emitters (the sky and sun come
from the scene's ``[sky]``), other shape types (``rectangle``, ``sphere``, ``serialized``, ...),
bsdfs without a diffuse colour (the table's ``albedo`` is used).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from envcap.core.color import srgb_to_linear
from envcap.scene.mesh_surfaces import Surfaces, one_line, read_mesh_surfaces, texture_image

MAX_INCLUDE_DEPTH = 8
"""Most nested ``<include>`` levels."""
WRAPPERS = ("twosided", "mask", "bumpmap", "normalmap")
"""bsdf types that wrap another bsdf: its colour is the inner one's."""


def _numbers(text: str, where: str) -> NDArray[np.float64]:
    try:
        vals = np.array([float(x) for x in re.split(r"[,\s]+", text.strip()) if x], np.float64)
    except ValueError:
        raise ValueError(f"{where}: expected numbers, got {text!r}") from None
    if not vals.size:
        raise ValueError(f"{where}: expected numbers, got {text!r}")
    if not np.all(np.isfinite(vals)):
        raise ValueError(f"{where}: numbers must be finite, got {text!r}")
    return vals


def _vec(el: ET.Element, default: float, where: str) -> NDArray[np.float64]:
    """(x, y, z) of a ``translate``/``scale``/``rotate`` element: ``value`` or x/y/z attributes."""
    if "value" in el.attrib:
        v = _numbers(el.attrib["value"], where)
        if v.size not in (1, 3):
            raise ValueError(f"{where}: expected 1 or 3 numbers, got {el.attrib['value']!r}")
        return np.repeat(v, 3) if v.size == 1 else v
    return np.array([_numbers(el.attrib.get(k, str(default)), f"{where} {k}")[0] for k in "xyz"])


def _rotation(axis: NDArray[np.float64], angle_deg: float) -> NDArray[np.float64]:
    a = axis / np.linalg.norm(axis)
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    m = np.eye(4)
    m[:3, :3] = c * np.eye(3) + s * k + (1 - c) * np.outer(a, a)
    return m


def to_world_matrix(el: ET.Element | None, where: str) -> NDArray[np.float64]:
    """4x4 matrix (column vectors) of a ``<transform>``: each child applied after the previous."""
    m = np.eye(4)
    if el is None:
        return m
    for op in el:
        step = np.eye(4)
        w = f"{where}: <{op.tag}>"
        if op.tag == "translate":
            step[:3, 3] = _vec(op, 0.0, w)
        elif op.tag == "scale":
            step[:3, :3] = np.diag(_vec(op, 1.0, w))
        elif op.tag == "rotate":
            axis = _vec(op, 0.0, w)
            if not np.linalg.norm(axis) > 0:
                raise ValueError(f"{w}: rotation axis is zero")
            step = _rotation(axis, float(_numbers(op.attrib.get("angle", "0"), f"{w} angle")[0]))
        elif op.tag == "matrix":
            vals = _numbers(op.attrib.get("value", ""), w)
            if vals.size not in (9, 16):
                raise ValueError(f"{w}: a matrix needs 9 or 16 numbers, got {vals.size}")
            if vals.size == 9:
                step[:3, :3] = vals.reshape(3, 3)
            else:
                step = vals.reshape(4, 4)
        elif op.tag == "lookat":
            if "origin" not in op.attrib or "target" not in op.attrib:
                raise ValueError(f"{w}: needs 'origin' and 'target'")
            o, t = _numbers(op.attrib["origin"], w), _numbers(op.attrib["target"], w)
            up = _numbers(op.attrib.get("up", "0 1 0"), w)
            d = (t - o) / np.linalg.norm(t - o)
            left = np.cross(up, d)
            left /= np.linalg.norm(left)
            step[:3, 0], step[:3, 1], step[:3, 2], step[:3, 3] = left, np.cross(d, left), d, o
        else:
            raise ValueError(f"{w}: unsupported transform operation")
        m = step @ m
    return m


def _read_root(path: Path, what: str) -> ET.Element:
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise ValueError(f"cannot read {what} {path}: {one_line(exc)}") from None
    if root.tag != "scene":
        raise ValueError(f"{path}: not a Mitsuba scene (root element <{root.tag}>, expected <scene>)")
    return root


def _expand_includes(el: ET.Element, base: Path, chain: tuple[Path, ...]) -> None:
    """Replace each ``<include filename>`` below ``el`` by the children of the scene it names (in
    place, recursively; module docstring).  ``chain``: the files being read, the main one first."""
    out: list[ET.Element] = []
    for child in list(el):
        if child.tag != "include":
            _expand_includes(child, base, chain)
            out.append(child)
            continue
        name = child.attrib.get("filename", "")
        where = f"{chain[-1]}: <include filename=\"{name}\">"
        if not name:
            raise ValueError(f"{chain[-1]}: an <include> without a filename")
        target = (base / name).resolve()
        if not target.is_relative_to(base.resolve()):
            raise ValueError(f"{where} leads outside the scene's folder {base} (to {target}); envcap reads "
                             f"included files from that folder or below it only")
        if target in chain:
            raise ValueError(f"{where} includes a file that is already being read (a cycle)")
        if len(chain) > MAX_INCLUDE_DEPTH:
            raise ValueError(f"{where}: includes nested more than {MAX_INCLUDE_DEPTH} deep")
        if not target.is_file():
            raise ValueError(f"{where}: file {target} not found")
        sub = _read_root(target, "included Mitsuba scene")
        _expand_includes(sub, base, (*chain, target))
        out.extend(sub)
    el[:] = out


def _substitute(root: ET.Element) -> None:
    """Apply ``<default name value>`` to every ``$name`` in attribute values (in place)."""
    defaults = {d.attrib["name"]: d.attrib.get("value", "") for d in root.iter("default") if "name" in d.attrib}
    if not defaults:
        return
    pattern = re.compile(r"\$(\w+)")
    for el in root.iter():
        for k, v in el.attrib.items():
            if "$" in v:
                el.attrib[k] = pattern.sub(lambda m: defaults.get(m.group(1), m.group(0)), v)


def _reflectance(bsdf: ET.Element, base: Path, where: str) -> tuple[NDArray[np.float64] | None, Path | None, bool]:
    """(rgb, bitmap file, twosided) of a bsdf; rgb None when it has no diffuse colour."""
    twosided = False
    while bsdf.attrib.get("type") in WRAPPERS:
        twosided |= bsdf.attrib.get("type") == "twosided"
        inner = bsdf.find("bsdf")
        if inner is None:
            return None, None, twosided
        bsdf = inner
    names = {"diffuse": "reflectance", "roughdiffuse": "reflectance", "plastic": "diffuse_reflectance",
             "roughplastic": "diffuse_reflectance", "principled": "base_color"}
    name = names.get(bsdf.attrib.get("type", ""))
    if name is None:
        return None, None, twosided
    for el in bsdf:
        if el.attrib.get("name") != name:
            continue
        if el.tag == "rgb":
            v = _numbers(el.attrib.get("value", ""), where)
            return np.clip(np.resize(v, 3), 0.0, 1.0), None, twosided
        if el.tag == "float":
            return np.clip(np.full(3, _numbers(el.attrib.get("value", ""), f"{where}: <float name=\"{name}\">")[0]),
                           0.0, 1.0), None, twosided
        if el.tag == "texture" and el.attrib.get("type") == "bitmap":
            fn = el.find("string[@name='filename']")
            if fn is not None:
                return np.ones(3), base / fn.attrib["value"], twosided
    return (np.full(3, 0.5) if bsdf.attrib.get("type") in ("diffuse", "roughdiffuse") else None), None, twosided


def iter_mitsuba_surfaces(path: Path, default_albedo: NDArray[np.float64], emission_scale: float = 100.0,
                          notes: list[str] | None = None) -> Iterator[Surfaces]:
    """:class:`Surfaces` of each ply/obj shape of the Mitsuba 3 scene ``path`` in document order
    (``to_world`` applied, materials from the bsdfs), one at a time (an importer keeps only what
    it has prepared); what was skipped is appended to ``notes`` once the shapes are exhausted.
    ``ValueError`` naming the file and the shape on a parse error, a bad attribute, a missing
    shape file or texture, or a scene without such shapes."""
    root = _read_root(path, "Mitsuba scene")
    base = path.parent
    _expand_includes(root, base, (path.resolve(),))
    _substitute(root)
    bsdfs = {b.attrib["id"]: b for b in root.findall("bsdf") if "id" in b.attrib}
    skipped: Counter[str] = Counter()
    bitmaps: dict[Path, NDArray[np.uint8]] = {}     # one texture per file, however many shapes use it
    count = 0
    for e in root.findall("emitter"):
        skipped[f"top-level emitter '{e.attrib.get('type', '?')}' (the scene's [sky] lights it)"] += 1
    for i, shape in enumerate(root.findall("shape")):
        kind = shape.attrib.get("type", "")
        where = f"{path}: shape {i} ({kind})"
        if kind not in ("ply", "obj"):
            skipped[f"shape type '{kind}'"] += 1
            continue
        fn = shape.find("string[@name='filename']")
        if fn is None or "value" not in fn.attrib:
            raise ValueError(f"{where}: no <string name=\"filename\" value=...>")
        file = base / fn.attrib["value"]
        if not file.is_file():
            raise ValueError(f"{where}: file {file} not found")
        ref = shape.find("ref")
        bsdf = bsdfs.get(ref.attrib.get("id", "")) if ref is not None else shape.find("bsdf")
        if ref is not None and bsdf is None:
            raise ValueError(f"{where}: <ref id=\"{ref.attrib.get('id')}\"> names no top-level bsdf")
        m4 = to_world_matrix(shape.find("transform[@name='to_world']"), where)
        surf = read_mesh_surfaces(file, default_albedo, emission_scale)
        surf.sources = [(fn.attrib["value"], surf.tri.shape[0])]
        surf.tri = surf.tri @ m4[:3, :3].T + m4[:3, 3]
        if np.linalg.det(m4[:3, :3]) < 0:   # a mirroring transform turns the winding: every corner array
            surf.tri, surf.albedo, surf.emission = (a[:, [0, 2, 1]] for a in (surf.tri, surf.albedo, surf.emission))
            if surf.uvl is not None:
                surf.uvl = surf.uvl[:, [0, 2, 1]]
        if bsdf is not None:
            _apply_bsdf(surf, bsdf, base, where, file, skipped, bitmaps)
        emitter = shape.find("emitter[@type='area']")
        if emitter is not None:
            rad = emitter.find("rgb[@name='radiance']")
            if rad is not None:
                surf.emission[:] = np.resize(_numbers(rad.attrib.get("value", ""), where), 3).astype(np.float32)
        count += 1
        yield surf
    if not count:
        raise ValueError(f"{path}: no ply or obj shapes to import")
    if notes is not None:
        notes += [f"{n} x {what}" for what, n in skipped.items()]


def _apply_bsdf(surf: Surfaces, bsdf: ET.Element, base: Path, where: str, file: Path, skipped: Counter[str],
                bitmaps: dict[Path, NDArray[np.uint8]]) -> None:
    """The bsdf's colour (and bitmap texture, on the shape's own texture coordinates) into ``surf``."""
    rgb, bitmap, twosided = _reflectance(bsdf, base, where)
    if twosided:
        skipped["twosided bsdf (lit on the front side, after the winding rule)"] += 1
    if rgb is None:
        skipped[f"bsdf type '{bsdf.attrib.get('type')}' without a diffuse colour (table albedo used)"] += 1
        return
    if bitmap is None:
        surf.albedo[:] = rgb.astype(np.float32)
        return
    if bitmap not in bitmaps:
        try:
            with Image.open(bitmap) as img:
                bitmaps[bitmap] = texture_image(img)
        except OSError as exc:
            raise ValueError(f"{where}: cannot read texture {bitmap}: {one_line(exc)}") from None
    texture = bitmaps[bitmap]
    mean = srgb_to_linear(texture[..., :3].reshape(-1, 3).mean(axis=0) / 255.0).astype(np.float32)
    if surf.uvl is None:
        skipped[f"bitmap texture on parts without texture coordinates (their mean colour used; {file.name})"] += 1
        surf.albedo[:] = mean
        return
    textured = np.isfinite(surf.uvl[..., 0])                          # corners with texture coordinates
    if not textured.all():
        skipped[f"bitmap texture on parts without texture coordinates (their mean colour used; {file.name})"] += 1
    surf.albedo[:] = np.where(textured[..., None], np.float32(1.0), mean)
    surf.textures = [texture]
    surf.uvl[..., 2] = np.where(textured, 0.0, -1.0)


def read_mitsuba_surfaces(path: Path, default_albedo: NDArray[np.float64], emission_scale: float = 100.0) -> Surfaces:
    """Every shape of :func:`iter_mitsuba_surfaces` joined into one :class:`Surfaces` (notes included)."""
    notes: list[str] = []
    parts = list(iter_mitsuba_surfaces(path, default_albedo, emission_scale, notes))
    joined = Surfaces.join(parts)
    joined.sources = [src for p in parts for src in p.sources]
    joined.notes = notes
    return joined
