"""The Dask workers of studies, lab series and calibrations run one Numba thread each.

A LocalCluster's ``env`` reaches a spawned worker only after it has re-imported the main
module; when that module imports Numba (the ``bondem`` command does), Numba has already
read the core count. The calibration example's runs were then 4-5x slower on its two
workers than in a plain process. ``single_threaded`` sets the count on the task's thread.
"""
import subprocess
import sys
import textwrap

import numba

from bondem.parallel import local_cluster, single_threaded


def test_single_threaded_runs_on_one_thread_and_restores_the_callers_setting():
    before = numba.get_num_threads()
    assert single_threaded(numba.get_num_threads) == 1
    assert numba.get_num_threads() == before
    # restored after a failing function too
    try:
        single_threaded(divmod, 1, 0)
    except ZeroDivisionError:
        pass
    assert numba.get_num_threads() == before


def test_a_worker_whose_main_module_imported_numba_first_runs_one_thread(tmp_path):
    script = tmp_path / "main.py"
    script.write_text(textwrap.dedent("""
        import numba   # before the nanny's env: as the bondem command does
        import numba.core.config


        def threads():
            return numba.config.NUMBA_NUM_THREADS, numba.get_num_threads()


        def compile_fresh():
            # a kernel compiled in the worker after its threads were launched: Numba
            # re-reads its environment on each compile
            import numpy as np

            @numba.njit(parallel=True)
            def total(x):
                s = 0.0
                for i in numba.prange(x.size):
                    s += x[i]
                return s
            return int(total(np.ones(7)))


        if __name__ == "__main__":
            import os
            from distributed import Client
            from bondem.parallel import local_cluster, single_threaded
            with local_cluster(1) as cluster, Client(cluster) as client:
                bare = client.submit(threads, pure=False).result()
                wrapped = client.submit(single_threaded, threads, pure=False).result()
                compiled = client.submit(single_threaded, compile_fresh, pure=False).result()
            print(os.cpu_count(), *bare, *wrapped, compiled)
    """))
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    cores, bare_config, bare, _, wrapped, compiled = map(int, out.stdout.split()[-6:])
    # the trap (with this Dask: Numba in the worker read the core count, not the env's
    # one thread) does not matter: the task runs on one thread
    assert bare == bare_config and wrapped == 1
    # and a kernel compiled there (a cache that a new bondem made stale): with
    # NUMBA_NUM_THREADS=1 in the cluster's env, Numba's compile found the env's 1 against
    # the 2 threads it had launched and refused ("Cannot set NUMBA_NUM_THREADS to a
    # different value once the threads have been launched")
    assert compiled == 7


def test_local_cluster_settings(monkeypatch):
    import distributed
    made = []
    monkeypatch.setattr(distributed, "LocalCluster", lambda **kwargs: made.append(kwargs))
    local_cluster(3)
    assert made == [{"n_workers": 3, "threads_per_worker": 1, "processes": True,
                     "dashboard_address": None,
                     "env": {"OMP_NUM_THREADS": "1"}}]
