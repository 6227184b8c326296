"""scipy's k-d tree, imported when first needed, and importable in the background.

``import scipy.spatial`` takes about 0.3 s (it loads scipy.sparse, qhull, the
distance functions and the rotations with it), about half of ``import ncopt.api``.
Code that imports ncopt and never searches neighbours (a library user reading
programs, a rewrite with a mesh whose operations need no tree) does not pay it,
and a rewrite starts the import in a thread while the program is parsed: most of
the parse is numpy work that releases the GIL.  A rewrite that loads a mesh imports
it instead (:func:`load`) in the mesh's thread once the mesh is built, or in the main
thread if that has to wait for the mesh first: an import holds the GIL, and a third busy
thread on two cores often holds it while it waits for a core.
"""

from __future__ import annotations

import os
import threading

_started: threading.Thread | None = None
_lock = threading.Lock()


def cKDTree(*args, **kwargs):
    """``scipy.spatial.cKDTree(*args, **kwargs)`` (waits for a prefetch under way:
    Python's import lock makes a second import of a module wait for the first)."""
    from scipy.spatial import cKDTree as tree  # deferred: see the module docstring
    return tree(*args, **kwargs)


def prefetch() -> None:
    """Start importing scipy.spatial in a daemon thread (once per process)."""
    global _started
    with _lock:
        if _started is not None:
            return
        _started = threading.Thread(target=load, name="ncopt-import-scipy", daemon=True)
        _started.start()


def _join() -> None:
    """Before a fork: let the import finish, so no child starts with scipy half
    imported and its module lock held by a thread the child does not have."""
    started = _started
    if started is not None and started.is_alive():
        started.join()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(before=_join)


def load() -> None:
    """Import scipy.spatial in the calling thread, now: the prefetch thread, or a thread
    that is there anyway (a mesh's loading thread once the mesh is built, the main thread
    while it waits for the mesh) instead of one of its own beside them."""
    try:
        import scipy.spatial  # noqa: F401 (the import is the point: module docstring)
    except Exception:  # the caller's own import raises it again, where it is needed
        pass

