"""The manifest's optional ``ladder`` entry: a probe set baked with a rung ladder
(``envcap capture --ladder half_octave``; ``docs/lobes.md``, "Ladder modes"; ``docs/formats.md``).

A set without the entry (JSON key absent) holds the paper's single chain: one layer per probe.
With it, ``probes.ktx2`` holds ``per_level`` layers per probe: layer ``p R + r`` of level ``j``
is probe ``p`` convolved with the normalized ``cos^powers[j R + r]`` lobe (``R = per_level``),
and ``sky.ktx2`` is an ``R``-layer cube-map array (layer ``r`` of level ``j``: rung ``j R + r``).
The manifest's ``levels`` and ``lobes`` then describe layer ``r = 0`` of each level (the capture
at level 0, one lobe per level), ``sizes`` the levels' face sizes ``N >> j`` (the chain stops at
8^2 faces).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from envcap.core.rungs import RUNG_RULE, RUNGS_PER_LEVEL, RungLadder
from envcap.probeset.json_codec import ManifestError

__all__ = ["LadderTable", "check_ladder_table"]


@dataclass(frozen=True)
class LadderTable:
    """The rung ladder of a probe set: ``mode`` (``"half_octave"`` or ``"octave"``), the levels'
    face ``sizes``, the ``len(sizes) * per_level`` rung ``powers`` (strictly decreasing; rung
    ``i`` is level ``i // per_level``, layer ``i % per_level`` of each probe) and the lookup
    ``rule`` (:data:`envcap.core.rungs.RUNG_RULE`)."""

    mode: str
    sizes: tuple[int, ...]
    powers: tuple[float, ...]
    per_level: int
    rule: str

    @staticmethod
    def of(mode: str, ladder: RungLadder) -> "LadderTable":
        """The entry of ``ladder`` (:meth:`envcap.core.rungs.RungLadder.to_manifest`) baked as ``mode``."""
        m: dict[str, Any] = ladder.to_manifest()
        return LadderTable(mode, tuple(m["sizes"]), tuple(m["powers"]), m["per_level"], m["rule"])

    def rung_ladder(self) -> RungLadder:
        """The :class:`envcap.core.rungs.RungLadder` (``ValueError`` if the table is not one)."""
        return RungLadder.from_manifest({"sizes": list(self.sizes), "powers": list(self.powers),
                                         "per_level": self.per_level, "rule": self.rule})


def check_ladder_table(t: LadderTable, level_sizes: tuple[int, ...], where: str) -> None:
    """``ManifestError`` (one line, naming ``where``) unless ``t`` is a valid rung ladder of
    ``mode``'s layers per level whose sizes are the manifest's level sizes."""
    if t.mode not in RUNGS_PER_LEVEL or t.per_level != RUNGS_PER_LEVEL[t.mode]:
        raise ManifestError(f"{where}: ladder.mode must be one of {sorted(RUNGS_PER_LEVEL)} with its per_level "
                            f"({RUNGS_PER_LEVEL}), got {t.mode!r} with {t.per_level}")
    if t.rule != RUNG_RULE:
        raise ManifestError(f"{where}: ladder.rule {t.rule!r} is not {RUNG_RULE!r}")
    try:
        t.rung_ladder()
    except (ValueError, KeyError) as e:
        raise ManifestError(f"{where}: ladder: {e}") from None
    if tuple(t.sizes) != tuple(level_sizes):
        raise ManifestError(f"{where}: ladder.sizes {list(t.sizes)} must be the levels' sizes {list(level_sizes)}")
