"""Output safety: envcap writes its outputs atomically and replaces only what it wrote.

* :mod:`~envcap.outputs.atomic`: ``atomic_output_dir`` / ``atomic_output_file``, the writers'
  entry points (a full disk is one line naming the output); ``retire_output_dir`` removes an
  output envcap wrote that a run made stale;
* :mod:`~envcap.outputs.claim`: check and lock an output before the work (``claim_output_dir``);
* :mod:`~envcap.outputs.guard`: which paths may be written (never an input, never the working
  directory, never a foreign non-empty directory without ``force``);
* :mod:`~envcap.outputs.marker`: the ``.envcap-output`` marker of an output envcap wrote;
* :mod:`~envcap.outputs.lock`: one writer per output (``fcntl.flock``);
* :mod:`~envcap.outputs.swap`: the old output stays until the new one is in place; recovery
  after a killed run;
* :mod:`~envcap.outputs.deferred_signals`: SIGINT/SIGTERM held back during those few steps.

The promises and their tests: ``docs/reliability.md``.
"""

from envcap.outputs.atomic import atomic_output_dir, atomic_output_file
from envcap.outputs.claim import OutputClaim, claim_output_dir
from envcap.outputs.guard import OutputRefused
from envcap.outputs.lock import OutputBusy
from envcap.outputs.marker import MARKER_NAME

__all__ = ["MARKER_NAME", "OutputBusy", "OutputClaim", "OutputRefused", "atomic_output_dir", "atomic_output_file",
           "claim_output_dir"]
