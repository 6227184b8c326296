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

:func:`in_tree_order` makes a twin of a built tree with its points stored leaf by leaf,
whose queries give the same results faster.
"""

from __future__ import annotations

import os
import threading

import numpy as np

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


def in_tree_order(tree, k: int):
    """A twin of the k-d tree ``tree`` (built on C-contiguous float64 points) whose
    points are stored in the tree's own order, leaf by leaf, and the order: ``(twin,
    order, ordered)`` with ``ordered = points[order]`` the twin's points; None where
    this scipy keeps its trees otherwise.

    The twin is the same tree (the nodes are copied as pickling copies them), so a query
    visits the same nodes and points in the same sequence, computes the same distances
    and keeps the same neighbours in the same order (equal distances included: the
    order among those is the history of the search, which is the same); its indices
    are positions in ``ordered``, ``order[i]`` in the original.  A leaf's points lie
    together in memory instead of across the whole array (a pass's neighbours on the
    next passes are thousands of points away along the path), and points queried in
    this order find the nodes of the last query in the cache: 20-28 % less time a
    query.  A few points are queried in both trees to check that they agree.
    """
    state = tree.__getstate__()
    if not (isinstance(state, tuple) and len(state) == 10 and state[8] is None):
        return None  # another layout of scipy's state, or a periodic tree
    nodes, data, n, m, leafsize, maxes, mins, order, boxsize, boxsize_data = state
    del state
    if not (isinstance(data, np.ndarray) and data.shape == (n, m) and order.shape == (n,)):
        return None
    del data  # the state's copy of the points: they are read from the tree's own (24 MB less)
    ordered = np.take(tree.data, order, axis=0)
    twin = type(tree).__new__(type(tree))
    twin.__setstate__((nodes, ordered, n, m, leafsize, maxes, mins,
                       np.arange(n, dtype=order.dtype), boxsize, boxsize_data))
    probe = ordered[np.linspace(0, n - 1, min(n, 64)).astype(np.intp)]
    k = max(1, min(k, n))
    want, got = tree.query(probe, k=k), twin.query(probe, k=k)
    if not (np.array_equal(want[0], got[0]) and np.array_equal(want[1], order[got[1]])):
        return None
    return twin, order, ordered
