"""scipy's k-d tree is imported only when needed, and a fork never meets it half imported."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from ncopt.contacts import kdtree


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=60)


def test_importing_the_api_does_not_import_scipy_spatial():
    done = _run("""
        import sys
        import ncopt.api, ncopt.cli.app
        print('scipy.spatial' in sys.modules)
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


def test_importing_the_api_loads_no_mesh_library():
    # libigl brings scipy.sparse (~0.11 s of the import), numpy-stl ~0.03 s: only a mesh
    # needs them
    done = _run("""
        import sys
        import ncopt.api, ncopt.cli.app, ncopt.contacts.geometry
        print(sorted(m for m in ('igl', 'fcpw', 'scipy.sparse', 'stl') if m in sys.modules))
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_a_mesh_indexed_in_a_thread_while_the_tree_is_prefetched():
    # both imports load scipy.sparse, from two threads at once: Python's module locks
    # make one wait for the other
    done = _run("""
        import threading
        import numpy as np
        from ncopt.contacts import kdtree
        from ncopt.contacts.geometry import MeshIndex
        from ncopt.contacts.mesh import Mesh
        V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
        F = np.array([[0, 1, 2]])
        got = []
        t = threading.Thread(target=lambda: got.append(MeshIndex(Mesh(V, F))))
        kdtree.prefetch()
        t.start(); t.join()
        cl = got[0].closest(np.array([[0.2, 0.2, 1.0]]))
        print(round(float(cl.dist_mm[0]), 6), int(kdtree.cKDTree(V).query(V[1])[1]))
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["1.0", "1"]


def test_the_tree_is_scipys():
    pts = np.random.default_rng(1).random((50, 3))
    dist, j = kdtree.cKDTree(pts).query(pts[:3], k=2)
    assert (j[:, 0] == [0, 1, 2]).all() and np.allclose(dist[:, 0], 0.0)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork is what is guarded")
def test_a_fork_right_after_the_prefetch_gets_a_usable_scipy():
    # without the at-fork join the child may start with scipy.spatial's module lock held
    # by the prefetch thread, which the child does not have: its import then hangs
    done = _run("""
        import os, sys
        from ncopt.contacts import kdtree
        kdtree.prefetch()
        pid = os.fork()
        if pid == 0:
            from ncopt.contacts.kdtree import cKDTree
            cKDTree([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]).query([[0.1, 0.0, 0.0]])
            os._exit(0)
        _, status = os.waitpid(pid, 0)
        print(os.waitstatus_to_exitcode(status), 'scipy.spatial' in sys.modules)
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["0", "True"]


def test_prefetch_starts_one_thread_per_process():
    done = _run("""
        import threading
        from ncopt.contacts import kdtree
        kdtree.prefetch(); kdtree.prefetch()
        print(sum(t.name == 'ncopt-import-scipy' for t in threading.enumerate()) <= 1)
        kdtree._started.join()
        import sys
        print('scipy.spatial' in sys.modules)
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True"]


@pytest.mark.slow
@pytest.mark.parametrize("slow, first", [("interpret", "ncopt-mesh"),
                                         ("MeshIndex", "MainThread")])
def test_a_rewrite_with_a_mesh_imports_the_tree_where_a_thread_is_idle(slow, first):
    # no third thread beside the parse and the mesh's (an import holds the GIL): the
    # mesh's thread imports it when the program is still being read, the main thread
    # when it has to wait for the mesh anyway
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = _run(f"""
        import sys, threading, time
        from ncopt import api
        from ncopt.contacts import geometry
        from ncopt.contacts import kdtree
        from ncopt.model import Cutter, Machine
        where = []
        load = kdtree.load
        kdtree.load = lambda: (where.append(threading.current_thread().name), load())
        def slowly(f):
            return lambda *a, **k: (time.sleep(1.5), f(*a, **k))[1]
        if {slow!r} == "interpret":
            api.interpret = slowly(api.interpret)
        else:
            api.MeshIndex = slowly(api.MeshIndex)
        job = api.Job(cutter=Cutter(16.0, 2), machine=Machine(accel_rad_s2=227.0,
                                                              max_rpm=15000.0))
        api.rewrite_file({root!r} + '/samples/bowl.mpf', job,
                         mesh_path={root!r} + '/samples/bowl.stl')
        print(where[0].split('_')[0], kdtree._started is None, 'scipy.spatial' in sys.modules)
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == [first, "True", "True"]
