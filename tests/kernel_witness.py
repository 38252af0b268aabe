"""The flight that shows a process which compiled the numba kernel matches one which loaded it.

``tests/test_flight_engines.py::test_a_process_that_compiles_the_kernel_matches_one_that_loads_it``
compares the positions of :data:`FLY_AND_SAVE` flown by a process that met a cold numba cache (it
compiled the kernel) with those of a process that met a warm one (it loaded the kernel). The cold
compile is a minute or more of CPU, and a fresh clone's test run already pays it once: the session's
warm-up child (``tests/conftest.py``) compiles the kernel beside the first tests. So that child flies
:data:`FLY_AND_SAVE` first, and when it met a cache without the kernel (:func:`kernel_cache_files`
empty) its positions are the cold witness; the test then only flies the warm one. Otherwise (a warm
cache, or the test run alone) the test compiles in a fresh cache of its own, as it always did.
"""

from __future__ import annotations

from pathlib import Path

#: Flies 24 drones round circles for 1 s with the numba engine and saves the positions to ``argv[1]``.
FLY_AND_SAVE = """
import sys, numpy as np
from sim.flight import TrackingReference, simulate
rng = np.random.default_rng(0)
ref = TrackingReference.circle(rng.uniform(-20.0, 20.0, (24, 3)) + [0.0, 0.0, 30.0], radius_m=3.0, omega_rad_s=0.5)
np.save(sys.argv[1], simulate(ref, duration_s=1.0, engine="numba").positions_m)
"""

#: :data:`FLY_AND_SAVE` in a process that must load the kernel: the cache holds it before the flight,
#: and the flight writes nothing to it (no compile).
FLY_LOADED = (
    "from tests.kernel_witness import kernel_cache_files\n_before = kernel_cache_files()\n"
    f"{FLY_AND_SAVE}\n"
    "assert _before, 'no kernel in the cache to load'\n"
    "assert kernel_cache_files() == _before, 'the flight compiled: ' + repr((_before, kernel_cache_files()))\n"
)


def kernel_cache_files() -> dict[str, int]:
    """The numba cache files of the flight engines' module (name -> mtime, ns) in this process's cache.

    The cache directory is the one numba uses for ``sim/flight/engines/_numba.py`` (``NUMBA_CACHE_DIR``
    or the ``__pycache__`` beside it), read from one of the module's cached dispatchers; empty when
    there is none (nothing compiled yet) or numba's internals moved (then the callers take the slow,
    self-contained path).
    """
    from sim.flight.engines import _numba

    for obj in vars(_numba).values():
        path = getattr(getattr(obj, "_cache", None), "_cache_path", None)
        if isinstance(path, str):
            d = Path(path)
            return {p.name: p.stat().st_mtime_ns for p in d.glob("_numba.*") if p.suffix in (".nbi", ".nbc")}
    return {}


#: Run by the warm-up child before it warms anything up: flies :data:`FLY_AND_SAVE` to
#: ``<dir>/cold.npy`` and writes ``<dir>/cold.ok`` when the cache held no kernel before that flight
#: and holds one after it (the flight compiled it, as the test's own cold process would).
#: A failure is printed and left at that: the warm-up goes on, and the test takes its slow path.
WITNESS_IN_WARM_UP = """
import sys, traceback
from pathlib import Path
try:
    from tests.kernel_witness import FLY_AND_SAVE, kernel_cache_files
    _dir = Path(sys.argv[1])
    _before = kernel_cache_files()
    _argv, sys.argv = sys.argv, [sys.argv[0], str(_dir / "cold.npy")]
    exec(compile(FLY_AND_SAVE, "<fly-and-save>", "exec"), {"__name__": "__main__"})
    sys.argv = _argv
    if not _before and kernel_cache_files():
        (_dir / "cold.ok").touch()
except Exception:
    traceback.print_exc()
"""
