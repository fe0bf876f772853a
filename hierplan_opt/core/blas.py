"""One BLAS thread for the ``hierplan`` command, chosen before numpy loads.

The command does its numerics on small arrays, where OpenBLAS's worker thread never
helps: started when numpy loads, it spins for a while before it sleeps, and a short
solve that starts within that window counts its spin (up to 4 ms of CPU against a 1 ms
solve on empty-8-8, ``docs/cbs.md``). Importing this module before numpy sets
``OPENBLAS_NUM_THREADS=1`` for the ``hierplan`` command only, and only if the user has
not chosen: a program that imports the library keeps its own BLAS threading.

Example
-------
>>> command_blas_threads(["/venv/bin/hierplan", "solve"], {})
{'OPENBLAS_NUM_THREADS': '1'}
>>> command_blas_threads(["notebook.py"], {}), command_blas_threads(
...     ["/venv/bin/hierplan"], {"OPENBLAS_NUM_THREADS": "4"})
({}, {'OPENBLAS_NUM_THREADS': '4'})
"""

from __future__ import annotations

import os
import sys
from collections.abc import MutableMapping, Sequence

#: The console script's name (``[project.scripts]`` in pyproject.toml).
COMMAND = "hierplan"


def command_blas_threads(
    argv: Sequence[str], environ: MutableMapping[str, str]
) -> MutableMapping[str, str]:
    """``environ`` with one OpenBLAS thread when ``argv`` is the ``hierplan`` command
    and the user has not set ``OPENBLAS_NUM_THREADS``; returned for convenience."""
    if argv and os.path.basename(argv[0]) == COMMAND:
        environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    return environ


if "numpy" not in sys.modules:  # too late once numpy has started its threads
    command_blas_threads(sys.argv, os.environ)
