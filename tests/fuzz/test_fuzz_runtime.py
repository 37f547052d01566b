"""Fuzz the runtime numerics (the numpy twin in ``envcap.runtime``): three-plane parallax and the
mip shift at their edges -- rays parallel to a plane (direction components exactly +0.0 / -0.0 or
denormal), shading points on a plane, outside the street or below the ground, far from the
origin; lobe powers 0, 1e7, Inf, NaN, negative; the whole lookup (``sample_street``) on cube
faces of one texel, with a huge sun in the sky and NaN / Inf texels.

Property: for finite geometry the outputs are finite, unit directions stay unit, ratios and mip
levels stay in their documented ranges; a lookup either returns finite radiance or raises a
one-line ``ValueError`` (NaN / Inf textures must not turn into NaN light silently).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from fuzz_harness import PINNED, fuzz_settings, require_finite, run_case, settle
from fuzz_known import known_issue
from fuzz_sandbox import sandbox
from hypothesis import example, given
from hypothesis import strategies as st

from envcap.runtime.chains import ProbeChains
from envcap.runtime.limits import FAR, MAX_RATIO
from envcap.runtime.mip import clamp_level, lobe_table, shift_power, z_of_w
from envcap.runtime.parallax import clamp_to_street, exit_distance, parallax
from envcap.runtime.sampling import sample_street
from envcap.runtime.shading import lafortune_lobe
from envcap.runtime.synthetic_street import synthetic_probe_set

pytestmark = pytest.mark.slow  # property-based: up to tens of seconds per test

COORDS = [0.0, -0.0, 1e-300, 5e-324, 1e-9, 0.5, 1.6, 5.9999999, 6.0, -6.0, 10.0, 1e6, 1e7, -1e7, 1e12, -1e12]
"""Coordinates at the edges: on the planes (+-6 facades, 0 ground), just inside, far outside."""


def coords() -> st.SearchStrategy[float]:
    return st.one_of(st.sampled_from(COORDS), st.floats(-1e4, 1e4, allow_nan=False))


@st.composite
def directions(draw) -> np.ndarray:
    """Unit vectors, many with exact +-0 or denormal components (parallel to a plane)."""
    comp = st.one_of(st.sampled_from([0.0, -0.0, 1.0, -1.0, 5e-324, -5e-324, 1e-300, 1e-9]), st.floats(-1, 1, allow_nan=False))
    for _ in range(10):
        v = np.array([draw(comp) for _ in range(3)], dtype=np.float64)
        n = math.sqrt(float(np.dot(v, v)))
        if n > 1e-150:  # the normalization itself stays exact in float64
            return v / n
    return np.array([0.0, -0.0, 1.0])


@st.composite
def planes(draw) -> np.ndarray:
    lo = draw(st.sampled_from([-6.0, -1e-3, -1e6, 0.0, -10.0]))
    width = draw(st.sampled_from([12.0, 1e-3, 1e-6, 2e6, 20.0]))
    ground = draw(st.sampled_from([0.0, -1.0, 1e6, -1e6, 2.5]))
    return np.array([lo, lo + width, ground])


W_VALUES = [0.0, -0.0, 1e-9, 1.0, 4.0, 1e7, 1e30, math.inf, -1.0, math.nan]


@st.composite
def parallax_cases(draw):
    pl = draw(planes())
    along = draw(st.sampled_from([0, 2]))
    c = 2 - along
    x = np.array([draw(coords()) for _ in range(3)])
    where = draw(st.sampled_from(["free", "on_min", "on_max", "on_ground", "outside", "below"]))
    if where == "on_min":
        x[c] = pl[0]
    elif where == "on_max":
        x[c] = pl[1]
    elif where == "on_ground":
        x[1] = pl[2]
    elif where == "outside":
        x[c] = pl[1] + draw(st.sampled_from([1e-9, 1.0, 1e6]))
    elif where == "below":
        x[1] = pl[2] - draw(st.sampled_from([1e-9, 1.0, 1e6]))
    p = np.array([draw(coords()), pl[2] + draw(st.sampled_from([1.6, 2.0, 1e-4, 0.0])), 0.5 * (pl[0] + pl[1])])
    p[[0, 2]] = p[[0, 2]] if along == 0 else p[[2, 0]]
    d = draw(directions())
    w = draw(st.sampled_from(W_VALUES))
    dtype = draw(st.sampled_from([np.float64, np.float32]))
    return {"x": x, "d": d, "p": p, "planes": pl, "along": along, "w": w, "dtype": dtype, "where": where}


def check_parallax(fuzz_base, case, tolerate: bool) -> None:
    with sandbox(fuzz_base) as sb:
        def run():
            dt = case["dtype"]
            r, ratio = parallax(case["x"], case["d"], case["p"], case["planes"], case["along"], dtype=dt)
            t = exit_distance(clamp_to_street(case["x"], case["planes"], case["along"], dt), case["d"],
                              case["planes"], case["along"], dt)
            xk = lobe_table([1024.0, 256.0, 64.0, 16.0, 4.0, 1.0, 0.0])
            z = clamp_level(z_of_w(shift_power(case["w"], ratio, dt), xk, dt), xk.size, dt)
            w_finite = case["w"] if math.isfinite(case["w"]) else 1.0  # Eq. 3 lobes take finite powers
            c, wt = lafortune_lobe(case["d"], [-1.0, -1.0, 1.0], w_finite, dt)
            return r, ratio, t, z, c, wt

        res = run_case(sb, run)
        if res.ok:
            r, ratio, t, z, c, wt = res.value
            require_finite(res, {"r": r, "ratio": ratio, "t": t, "z": z, "c": c, "weight": wt})
            if not res.problems:
                tol = 1e-3 if case["dtype"] is np.float32 else 1e-9
                if abs(float(np.linalg.norm(r.astype(np.float64))) - 1) > tol:
                    res.violate(f"wrong: |r| = {float(np.linalg.norm(r))}")
                if not (1 / MAX_RATIO <= float(ratio) <= MAX_RATIO):
                    res.violate(f"wrong: ratio {float(ratio)} outside [1/{MAX_RATIO}, {MAX_RATIO}]")
                if not (0 <= float(z) <= 6):
                    res.violate(f"wrong: level {float(z)} outside [0, 6]")
                if not (0 <= float(t) <= FAR):
                    res.violate(f"wrong: exit distance {float(t)} outside [0, FAR]")
        settle("runtime.parallax", case, res, known=known_issue if tolerate else None)


@fuzz_settings(150)
@given(case=parallax_cases())
def test_parallax_is_finite_and_in_range(fuzz_base, case):
    check_parallax(fuzz_base, case, tolerate=True)


# --------------------------------------------------------------------------------------------
# The whole lookup


SETS: dict[tuple[int, int], tuple] = {}


def probe_set(n: int, count: int):
    """The analytic street's probe set (cached: it is deterministic), copied so a case may edit it."""
    if (n, count) not in SETS:
        SETS[(n, count)] = synthetic_probe_set(n=n, count=count)
    probes, sky, street, powers = SETS[(n, count)]
    return [a.copy() for a in probes], [a.copy() for a in sky], street, powers


@st.composite
def lookup_cases(draw):
    n = draw(st.sampled_from([1, 2, 4]))
    count = draw(st.sampled_from([1, 2, 3]))
    texels = draw(st.sampled_from(["plain", "plain", "huge_sun", "nan_probe", "inf_sky", "nan_sky", "neg_probe"]))
    x = np.array([draw(coords()), draw(st.sampled_from([1.6, 0.0, -1.0, 1e6])), draw(coords())])
    d = draw(directions())
    w = draw(st.sampled_from(W_VALUES))
    method = draw(st.sampled_from(["planes_mip", "blend", "nearest", "planes"]))
    return {"n": n, "count": count, "texels": texels, "x": x, "d": d, "w": w, "method": method}


def check_lookup(fuzz_base, case, tolerate: bool) -> None:
    probes, sky, street, powers = probe_set(case["n"], case["count"])
    t = case["texels"]
    if t == "huge_sun":
        for a in sky:
            a[2, 0, 0, :3] = 3.0e38  # the largest float32 radiance, in every level
    elif t == "nan_probe":
        probes[0][0, 0, 0, 0, 0] = np.nan
    elif t == "inf_sky":
        sky[0][2, 0, 0, 1] = np.inf
    elif t == "nan_sky":
        for a in sky:
            a[...] = np.nan
    elif t == "neg_probe":
        probes[0][0, 0, 0, 0, :3] = -1e4
    with sandbox(fuzz_base) as sb:
        res = run_case(sb, lambda: sample_street(ProbeChains(probes, powers), sky, street, case["x"], case["d"], case["w"],
                                                 method=case["method"]))
        if res.ok:
            require_finite(res, res.value, "radiance", limit=math.inf)
        settle("runtime.lookup", dict(case), res, known=known_issue if tolerate else None)


@fuzz_settings(60)
@given(case=lookup_cases())
def test_lookup_is_finite_or_fails_in_one_line(fuzz_base, case):
    check_lookup(fuzz_base, case, tolerate=True)


@PINNED
@example(texels="nan_sky", method="planes_mip")
@given(texels=st.sampled_from(["nan_probe", "inf_sky", "nan_sky"]), method=st.sampled_from(["blend", "nearest"]))
def test_pinned_nan_textures_do_not_become_nan_light(fuzz_base, texels, method):
    """NaN / Inf texels are refused when the chains are built, naming level and layer (old: NaN
    radiance, silently)."""
    case = {"n": 4, "count": 2, "texels": texels, "x": np.array([5.0, 1.6, 0.0]), "d": np.array([0.0, 0.0, 1.0]),
            "w": 1.0, "method": method}
    check_lookup(fuzz_base, case, tolerate=False)
