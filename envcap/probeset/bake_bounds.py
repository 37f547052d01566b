"""Bounds before work for a probe-set bake: probe count, peak memory, rough time, GL limits, geometry range.

:func:`envcap.probeset.bake.bake_probe_set` calls these before it builds the sky or captures
anything, so that a request that would run away with the machine (``--resolution 100000``:
74.5 GiB; ``--spacing 1e-9``: 2*10^10 probes) or could not be captured (a face atlas past the GL
texture size, a mesh whose distances overflow float32) fails at once with one line that says
what was asked, what it would cost and which option changes it.

The cost model (:func:`estimate_bake`) was fitted to the peak resident memory (``/usr/bin/time``)
and wall time of ``envcap capture`` with llvmpipe (Mesa's CPU OpenGL, 2 cores): ``canyon`` and
``avenue`` at 16^2 to 256^2 and 25 to 120 probes, ``--quality composed`` (the CLI's) and
``default``; the estimate covers the whole process (the Python, numpy and GL baseline included)
and stays above every measured peak, within 1.04-1.23x for the composed filter and 1.08-1.25x
for the others (docs/reliability.md, Limits, has the table and the command).  Memory is checked
against :func:`envcap.core.budget.memory_limit` (``ENVCAP_MAX_MEMORY`` or the memory available),
the count against :data:`envcap.probeset.placement.MAX_PROBES`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from envcap.core.budget import check_bytes, check_count, format_bytes
from envcap.prefilter.sky_visibility import visibility_bake_bytes
from envcap.probeset.float32_range import FLOAT32_MAX
from envcap.scene.model import Scene

__all__ = ["GEOMETRY_LIMIT_M", "BIG_BYTES", "BIG_SECONDS", "BakeEstimate", "estimate_bake", "check_bake_cost",
           "check_gl_limits", "check_geometry", "format_seconds"]

GEOMETRY_LIMIT_M = math.sqrt(FLOAT32_MAX / 12.0)
"""Largest coordinate (m, ~5.3e18) of a vertex or probe that a float32 capture can measure: the
squared distance between two such points (3 components of up to twice it) stays below float32's
maximum.  Past it the capture's distances are ``inf`` (the bake used to fail only when writing)."""

# Peak resident bytes of the process: what it holds before the bake (Python, numpy, the GL context
# and capture target, a bundled scene: 187 MB measured at canyon 16^2 x 30), plus per level-0 texel
# of the probe array (L x 6 x N^2) what the bake keeps and per texel of one prefilter batch (64 MiB
# of float32 RGBA level 0) its transients, plus per sky texel (6 x N^2) the sky's cubes and filter.
_BASE_BYTES = 200e6
# ``quality="composed"`` (the CLI's): kept, the capture (RGBA float32 + distance float32 +
# back-facing flag = 21 B) whose RGBA is level 0 of the chain, and levels 1.. written in place
# (16 B x 1/3): 26.3 B, measured 26.4; per batch texel 42 B and per sky texel 71 B fitted; rounded up.
_COMPOSED_KEPT_B = 28.0
_COMPOSED_BATCH_B = 48.0
_COMPOSED_SKY_B = 80.0
# Other qualities (envcap.prefilter.fast): the capture, a float64 stack of the checked cubes and the
# float32 chain (21 + 32 + 16 x 4/3 B kept; 64 B while it is stacked), per batch texel its pyramid,
# centroid directions and GL buffers (200 B, measured ~190-210), per sky texel 260 B (fitted ~200),
# above the measured peaks by 8-25 % (docs/reliability.md).
_CAPTURE_B = 21.0
_STACK_B = 64.0
_FILTER_KEPT_B = 21.0 + 32.0 + 16.0 * 4.0 / 3.0
_BATCH_B = 200.0
_SKY_B = 260.0
_UNFILTERED_B = 60.0          # filter_levels=False: capture, its float32 copy, the write
_PREFILTER_BATCH_BYTES = 64 << 20  # the default ``batch_bytes`` of envcap.prefilter.prefilter_many
# A rung ladder (ladder_mode != "paper") adds per rung layer (R per level) and level-0 texel: its
# float32 RGBA levels down to 8^2 kept (16 B x 4/3) and, per chunk of the fast rung filter
# (envcap.prefilter.rungs.CHUNK_BYTES of level-0 RGBA float32), the chunk's composed chain and GL
# buffers (33 B, fitted: canyon 64^2 x 50 probes, 128^2 x 20: 253 and 418 MiB over the paper bake, model 255 and 408).
_RUNG_KEPT_B = 16.0 * 4.0 / 3.0
_RUNG_CHUNK_B = 33.0
_RUNG_CHUNK_TEXELS = (64 << 20) / 16.0
# An opt-in writer adds its working memory on top (conservative: it runs after the bake's transients
# are freed).  ``sky_visibility``: envcap.prefilter.sky_visibility.visibility_bake_bytes, the model of
# its Funk-Hecke filter (a chunk of probes of ~1.2 MB each at most, the float32 moments of the set,
# 516 KB a probe at N >= 64) and of the write (2.75 x the moments), above the tracemalloc peak of the
# writer's work by 1.0-1.9x (16^2 x 12 to 256^2 x 20 and 128^2 x 300 probes; docs/lobes.md).

# Seconds at llvmpipe rates (2 CPU cores): per probe (draw setup, files), per level-0 texel of
# capture, filter and write (composed 1.0 us, fitted 0.6-1.0; other qualities 4.5 us, fitted 4.1),
# per sky texel (fitted ~9 us).  The interpreter's start (~2 s) is not counted.
_PROBE_S = 0.025 + 0.012
_COMPOSED_TEXEL_S = 1.0e-6
_TEXEL_S = 4.5e-6
_UNFILTERED_TEXEL_S = 4.5e-6
_SKY_TEXEL_S = 10e-6
_RUNG_TEXEL_S = 1.6e-6        # per rung layer and level-0 texel (fitted 1.4-1.6: canyon 64^2 x 60, 128^2 x 30, R = 4)

BIG_BYTES = 1 << 30
"""A bake estimated past this peak memory (or :data:`BIG_SECONDS`) prints its estimate first."""
BIG_SECONDS = 60.0


def format_seconds(seconds: float) -> str:
    """``"40 s"``, ``"12 min"``, ``"3.5 h"``, ``"120 days"``."""
    if not math.isfinite(seconds):
        return "forever"
    for unit, scale in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= 2 * scale:
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds:.0f} s"


def _count(probes: float) -> str:
    return f"{int(probes):,}" if probes < 1e15 else f"{probes:.3g}"


def _square(n: float) -> float:
    return n * n  # float: inf, never OverflowError


@dataclass(frozen=True)
class BakeEstimate:
    """What a bake will hold and take, before it starts.

    ``probes``: probe count (a float: may be huge); ``resolution``: face size N (texels);
    ``texels``: level-0 texels of the probe array (``probes x 6 x N^2``); ``peak_bytes``: peak
    resident memory of the process (its baseline before the bake included); ``seconds``: rough
    wall time at llvmpipe rates (a GPU is faster).
    """

    probes: float
    resolution: int
    texels: float
    peak_bytes: float
    seconds: float

    @property
    def big(self) -> bool:
        """Whether the estimate is worth printing before the work starts."""
        return self.peak_bytes > BIG_BYTES or self.seconds > BIG_SECONDS

    def describe(self) -> str:
        """``"600 probes at 16^2 per face: peak memory ~431 MiB, roughly 40 s at llvmpipe rates"``."""
        return (f"{_count(self.probes)} probes at {self.resolution}^2 per face: peak memory ~{format_bytes(self.peak_bytes)}, "
                f"roughly {format_seconds(self.seconds)} at llvmpipe (CPU) rates, less on a GPU")


def estimate_bake(probes: float, resolution: int, *, filter_levels: bool = True, quality: str = "default",
                  rungs_per_level: int = 0, writers: Iterable[str] = ()) -> BakeEstimate:
    """The cost model of a bake of ``probes`` probes at ``resolution`` texels per face
    (see the module docstring); every quantity is a float (``inf`` when past counting).
    ``quality``: the prefilter's (``"composed"``, the CLI's default, holds far less than the others).
    ``rungs_per_level``: ``R`` of a rung ladder (``envcap capture --ladder``; 0: the paper's chain).
    ``writers``: the writers that will run on the result (names; ``sky_visibility`` adds its memory)."""
    n = float(resolution) if resolution < 1 << 1000 else math.inf
    face = 6.0 * _square(n)
    texels = probes * face
    per_batch = max(1.0, math.floor(_PREFILTER_BATCH_BYTES / (face * 16.0))) if math.isfinite(face) else 1.0
    batch = min(texels, per_batch * face)
    if filter_levels and quality == "composed":
        peak = _COMPOSED_KEPT_B * texels + _COMPOSED_BATCH_B * batch + _COMPOSED_SKY_B * face
        seconds = texels * _COMPOSED_TEXEL_S
    elif filter_levels:
        peak = max((_CAPTURE_B + _STACK_B) * texels, (_CAPTURE_B + _FILTER_KEPT_B) * texels + _BATCH_B * batch)
        peak += _SKY_B * face
        seconds = texels * _TEXEL_S
    else:
        peak = _UNFILTERED_B * texels + _SKY_B * face
        seconds = texels * _UNFILTERED_TEXEL_S
    if filter_levels and rungs_per_level > 0:
        peak += rungs_per_level * (_RUNG_KEPT_B * (texels + face) + _RUNG_CHUNK_B * min(texels, _RUNG_CHUNK_TEXELS))
        seconds += rungs_per_level * texels * _RUNG_TEXEL_S
    if "sky_visibility" in set(writers):
        peak += visibility_bake_bytes(probes, n)
    peak += _BASE_BYTES
    seconds += probes * _PROBE_S + face * _SKY_TEXEL_S
    return BakeEstimate(probes, int(resolution), texels, peak, seconds)


def check_bake_cost(est: BakeEstimate, street_length_m: float, spacing: float, max_probes: int) -> None:
    """Refuse ``est`` past ``max_probes`` probes or past the memory limit
    (:class:`envcap.core.budget.BudgetError`: what was asked, its cost, the option to change)."""
    cost = f"~{format_bytes(est.peak_bytes)}, {format_seconds(est.seconds)} at llvmpipe rates"
    check_count(f"probes for {street_length_m:g} m of streets at spacing {spacing:g} m ({cost})", est.probes,
                max_probes, "--spacing (or max_probes= of bake_probe_set)")
    check_bytes(f"bake of {_count(est.probes)} probes at {est.resolution}^2 texels per face "
                f"({format_seconds(est.seconds)} at llvmpipe rates)", est.peak_bytes, "--resolution or --spacing")


def check_gl_limits(ctx: Any, resolution: int, probes: int) -> str | None:
    """Check the capture's face atlas (3N x 2N texels) against this context's limits
    (``ValueError`` naming the largest resolution that fits); return a note when ``probes``
    cubes exceed the context's cube-map-array layers (an engine on it must split the set), else
    ``None``."""
    info = ctx.info
    renderer = info.get("GL_RENDERER", "this OpenGL")
    viewport = info.get("GL_MAX_VIEWPORT_DIMS", (math.inf, math.inf))
    limits = {"GL_MAX_TEXTURE_SIZE": info.get("GL_MAX_TEXTURE_SIZE", math.inf),
              "GL_MAX_RENDERBUFFER_SIZE": info.get("GL_MAX_RENDERBUFFER_SIZE", math.inf),
              "GL_MAX_VIEWPORT_DIMS": viewport[0] if isinstance(viewport, (tuple, list)) else viewport}
    name, most = min(limits.items(), key=lambda kv: kv[1])
    if 3 * resolution > most:
        raise ValueError(f"--resolution {resolution}: the capture renders the 6 faces into one {3 * resolution} x "
                         f"{2 * resolution} target, past {name} {most} of {renderer}; use --resolution <= {int(most) // 3}")
    layers = info.get("GL_MAX_ARRAY_TEXTURE_LAYERS")
    if layers is not None and 6 * probes > layers:
        return (f"{probes} probes are {6 * probes} cube faces, more than GL_MAX_ARRAY_TEXTURE_LAYERS {layers} of "
                f"{renderer}: a renderer like it holds the set in several cube-map arrays")
    return None


def _where(scene: Scene) -> str:
    source = scene.meta.get("source") if isinstance(scene.meta, dict) else None
    return f"scene '{scene.name}'" + (f" ({source})" if source else "")


def check_geometry(scene: Scene, positions: NDArray[np.float64]) -> None:
    """Refuse, before any capture, geometry a float32 capture cannot measure (``ValueError``
    naming the scene and the mesh's scale / offset or the streets).

    The capture renders relative to the mesh's origin (``SceneMesh.origin``): the mesh's
    float32 ``positions`` and the probes' offsets from that origin must lie within
    :data:`GEOMETRY_LIMIT_M`; the probes' world ``positions`` ``(P, 3)`` (m, float64, the
    manifest's) within float32 range.
    """
    mesh = scene.mesh
    reach = float(np.max(np.abs(mesh.positions))) if mesh.positions.size else 0.0
    if not reach <= GEOMETRY_LIMIT_M:
        raise ValueError(f"{_where(scene)}: mesh coordinates reach {reach:.3g} m, past the {GEOMETRY_LIMIT_M:.2g} m "
                         "within which a float32 capture measures distances; check the mesh's scale and offset")
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    world = float(np.max(np.abs(pos))) if pos.size else 0.0
    local = float(np.max(np.abs(pos - mesh.origin))) if pos.size else 0.0
    if not (world <= FLOAT32_MAX and local <= GEOMETRY_LIMIT_M):
        raise ValueError(f"{_where(scene)}: probe positions reach {max(world, local):.3g} m (from the mesh's origin "
                         f"{local:.3g} m), past the {GEOMETRY_LIMIT_M:.2g} m within which a float32 capture measures "
                         "distances; check the streets' coordinates")
