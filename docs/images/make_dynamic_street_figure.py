"""Regenerate docs/images/dynamic_street.png: Eq. 3 error against the visible sky hidden by a ring
of spheres in the bundled canyon, without and with the dynamic terms (paper and envcap models).

Run: python3 docs/images/make_dynamic_street_figure.py [BENCH_OUT]
With BENCH_OUT (the --out of a finished ``envcap bench dynamic_street``) the figure is redrawn
from its dynamic_street.json; without, the benchmark runs first (3 positions, ~10 min on 2 cores).
"""

import json
import shutil
import sys
import tempfile
from pathlib import Path

from envcap.benchmarks.dynamic_street import plot
from envcap.cli import main as envcap_main

HERE = Path(__file__).resolve().parent


def main() -> None:
    if len(sys.argv) > 1:
        result = json.loads((Path(sys.argv[1]) / "dynamic_street.json").read_text())
        plot(result["rows"], list(result["models"]), HERE / "dynamic_street.png")
    else:
        tmp = Path(tempfile.mkdtemp())
        try:
            envcap_main(["bench", "dynamic_street", "--out", str(tmp / "out")])
            shutil.copyfile(tmp / "out" / "dynamic_street.png", HERE / "dynamic_street.png")
        finally:
            shutil.rmtree(tmp)
    print(HERE / "dynamic_street.png")


if __name__ == "__main__":
    main()
