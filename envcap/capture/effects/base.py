"""What a capture effect is: :class:`CaptureEffect`, and how its GLSL joins the capture shader.

An effect is one shading term of the capture (``sun_light``, ``sky_light``, ...) that runs only
when a scene lists it.  It declares:

* ``name``: as listed in a scene's ``effects``; its capitalized form is ``#define``-d in the
  capture fragment shader when the effect is applied (``SUN_SHADOWS``), so that another
  effect's GLSL can test for it.
* ``needs``: the scene data without which it is skipped (listed but not applied):
  ``"sky"`` (a sky's radiance), ``"sun"`` (the sky has a sun), ``"triangles"`` (a non-empty mesh).
* ``requires``: effects that must be listed with it (else ``ValueError``); it is applied only
  when they are.
* ``parameters``: its keyword parameters (``CubeCapture(effect_parameters={name: {...}})``),
  each with a default, a description and a check.
* ``uniforms``: the capture-program uniforms its :attr:`CaptureEffect.prepare` sets (samplers
  included); the capture checks the two agree, and sets them strictly
  (:func:`envcap.gpu.uniforms.set_uniforms`).
* ``pass_name`` and ``prepare``: the per-set pass that computes those uniforms once per
  :class:`~envcap.capture.renderer.CubeCapture` (recorded in ``passes_run`` under ``pass_name``
  when set; ``None`` for effects that only set uniforms).
* GLSL, inserted into ``shaders/capture/capture_frag.glsl`` at its three ``// @effects:`` lines
  in registry order (:func:`capture_fragment_source`):

  - ``glsl_declarations``: file scope (uniforms, functions, ``#include "capture/..."`` lines);
  - ``glsl_irradiance``: in ``main``, for front faces only, in a block of its own; adds to
    ``vec3 E``, the irradiance on the surface (same units as ``sky.radiance`` times sr);
  - ``glsl_radiance``: after ``L = v_albedo / PI * E``; changes ``vec3 L``, the radiance
    leaving the surface toward the probe (front faces only; back faces stay 0).

  Both code hooks can read ``n`` (unit surface normal), ``v_local`` (surface point in meters
  relative to the mesh origin ``EffectInputs.origin``: world positions never reach the GPU),
  ``v_rel`` (surface point minus probe), ``dist`` (``|v_rel|``), ``v_albedo`` (diffuse
  reflectance) and ``v_emission`` (emitted radiance).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Protocol, Sequence

import moderngl
import numpy as np
from numpy.typing import NDArray

from envcap.core import checks
from envcap.core.resources import expand_includes, shader_source

NEEDS: tuple[str, ...] = ("sky", "sun", "triangles")
"""Scene data an effect may need: a sky's radiance, the sky's sun, a mesh with triangles."""

HOOKS: tuple[str, ...] = ("declarations", "irradiance", "radiance")
"""The ``// @effects:HOOK`` lines of ``capture_frag.glsl``, in file order."""

FRAGMENT_SHADER = "capture/capture_frag.glsl"

_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


class SunLike(Protocol):
    """The sun of a sky (:class:`envcap.sky.sun.Sun` has these)."""

    direction: NDArray[np.floating]
    """(3,) toward the sun, any length > 0."""
    illuminance: NDArray[np.floating]
    """(3,) RGB illuminance at normal incidence."""


class SkyLike(Protocol):
    """What the capture effects need from :class:`envcap.sky.base.Sky`."""

    sun: SunLike | None

    def radiance(self, dirs: NDArray[np.floating]) -> NDArray[np.floating]:
        """Linear RGB radiance ``(..., 3)`` toward unit directions ``(..., 3)``, sun excluded."""
        ...


@dataclass(frozen=True)
class EffectParameter:
    """One keyword parameter of an effect: ``default``, what it is (``doc``, with units), and
    ``check``, which returns the value to use or raises ``ValueError``."""

    default: Any
    doc: str
    check: Callable[[Any], Any]


def positive_int(what: str) -> Callable[[Any], int]:
    """A parameter check accepting integers >= 1 (not bools); the message names ``what``."""

    def check(v: Any) -> int:
        return checks.positive_int(v, what)

    return check


@dataclass(frozen=True)
class EffectInputs:
    """What an effect's per-set pass can use.

    ``positions`` (V, 3) float32 mesh vertices in meters relative to ``origin`` ((3,) float64,
    world meters: :attr:`envcap.scene.model.SceneMesh.origin`); matrices and points an effect
    gives the shader must be relative to ``origin`` too.  ``vertex_buffer``: the mesh on the
    GPU, 12 float32 per vertex (position, normal, albedo, emission: moderngl format
    ``"3f 3f 3f 3f"``); ``index_buffer``: uint32 triangles (in chunk order); both ``None``
    when the mesh has no triangles.  ``max_texture_size``: ``GL_MAX_TEXTURE_SIZE`` of ``ctx``.
    """

    ctx: moderngl.Context
    sky: SkyLike | None
    positions: NDArray[np.float32]
    origin: NDArray[np.float64]
    vertex_buffer: moderngl.Buffer | None
    index_buffer: moderngl.Buffer | None
    max_texture_size: int


@dataclass
class EffectSetup:
    """The result of an effect's per-set pass.

    ``uniforms``: capture-program uniform values (see :func:`envcap.gpu.uniforms.set_uniforms`
    for the conventions); ``textures``: sampler uniform name -> moderngl texture, bound to a unit
    of its own for every probe; ``gl_objects``: released with the capture; ``facts``: numbers a
    bake records (e.g. ``sun_shadows``' texel size in meters), collected in
    :attr:`envcap.capture.renderer.CubeCapture.effect_facts` as ``"EFFECT.NAME"``;
    ``per_probe`` (``None``: nothing per probe): called with each probe's position (3,) float64
    meters relative to the origin before the probe is drawn (timed under the effect's
    ``pass_name``); returns the uniforms that change (e.g. ``sun_shadows``' cascades that follow
    the probe).
    """

    uniforms: dict[str, Any] = field(default_factory=dict)
    textures: dict[str, Any] = field(default_factory=dict)
    gl_objects: list[Any] = field(default_factory=list)
    facts: dict[str, float] = field(default_factory=dict)
    per_probe: Callable[[NDArray[np.float64]], Mapping[str, Any]] | None = None


@dataclass(frozen=True)
class CaptureEffect:
    """One capture effect; the fields are described in the module docstring."""

    name: str
    summary: str
    needs: frozenset[str] = frozenset()
    requires: tuple[str, ...] = ()
    parameters: Mapping[str, EffectParameter] = field(default_factory=dict)
    uniforms: tuple[str, ...] = ()
    pass_name: str | None = None
    prepare: Callable[[EffectInputs, Mapping[str, Any]], EffectSetup] | None = None
    glsl_declarations: str = ""
    glsl_irradiance: str = ""
    glsl_radiance: str = ""
    glsl_defines: Callable[[Mapping[str, Any]], Mapping[str, object]] | None = None
    """Extra names to ``#define`` in the capture shader for the effect's resolved parameters
    (e.g. ``sun_shadows``' cascade code only where cascades can be needed); uniforms declared
    in code they leave out may still be set (they are ignored)."""

    def __post_init__(self) -> None:
        if not _NAME.match(self.name):
            raise ValueError(f"effect name {self.name!r} must be lower_case letters, digits and _")
        unknown = sorted(set(self.needs) - set(NEEDS))
        if unknown:
            raise ValueError(f"effect '{self.name}': unknown needs {unknown}; known: {list(NEEDS)}")
        if (self.uniforms or self.pass_name) and self.prepare is None:
            raise ValueError(f"effect '{self.name}' sets uniforms or has a pass but no prepare function")
        for hook in HOOKS:
            if "// @effects:" in getattr(self, f"glsl_{hook}"):
                raise ValueError(f"effect '{self.name}': GLSL must not contain '// @effects:' lines")

    @property
    def define(self) -> str:
        """The preprocessor name defined while the effect is applied."""
        return self.name.upper()

    def resolve_parameters(self, given: Mapping[str, Any] | None) -> dict[str, Any]:
        """Defaults overridden by ``given``, each checked.  Raises ``ValueError`` for a name
        the effect does not have or a value its check refuses."""
        given = dict(given or {})
        unknown = sorted(set(given) - set(self.parameters))
        if unknown:
            raise ValueError(f"effect '{self.name}' has no parameter(s) {unknown}; "
                             f"it has: {sorted(self.parameters)}")
        return {k: p.check(given.get(k, p.default)) for k, p in self.parameters.items()}

    def setup(self, inputs: EffectInputs, params: Mapping[str, Any]) -> EffectSetup:
        """Run the per-set pass; returns the uniforms to set.  Raises ``RuntimeError`` if they
        differ from the declared :attr:`uniforms`."""
        out = self.prepare(inputs, params) if self.prepare is not None else EffectSetup()
        got = set(out.uniforms) | set(out.textures)
        if got != set(self.uniforms):
            raise RuntimeError(f"effect '{self.name}' set uniforms {sorted(got)}, declares {sorted(self.uniforms)}")
        return out


def capture_fragment_source(effects: Sequence[CaptureEffect], extra_defines: Mapping[str, object] | None = None) -> str:
    """The capture fragment shader with ``effects`` (applied, in registry order) compiled in:
    each effect's name defined, and its GLSL at the ``// @effects:HOOK`` lines; ``extra_defines``
    (e.g. ``ENVCAP_TEXTURED``) are defined too."""
    defines: dict[str, object] = {k: 1 for k in sorted(e.define for e in effects)}
    defines.update(extra_defines or {})
    src = shader_source(FRAGMENT_SHADER, defines or None)
    for hook in HOOKS:
        marker = re.compile(rf"^([ \t]*)// @effects:{hook}[ \t]*$", re.MULTILINE)
        found = marker.findall(src)
        if len(found) != 1:
            raise RuntimeError(f"{FRAGMENT_SHADER} must have one '// @effects:{hook}' line, found {len(found)}")
        indent = found[0]
        parts = []
        for e in effects:
            code = getattr(e, f"glsl_{hook}").strip("\n")
            if not code:
                continue
            if hook == "declarations":
                parts.append(f"// effect {e.name}\n{code}\n")
            else:  # a block of its own: effects may use the same local names
                body = "".join(f"{indent}    {ln}\n" if ln else "\n" for ln in code.splitlines())
                parts.append(f"{indent}{{   // effect {e.name}\n{body}{indent}}}\n")
        src = marker.sub(lambda _: "".join(parts).rstrip("\n"), src)
    return expand_includes(src)
