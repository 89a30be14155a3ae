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


        if __name__ == "__main__":
            import os
            from distributed import Client
            from bondem.parallel import local_cluster, single_threaded
            with local_cluster(1) as cluster, Client(cluster) as client:
                bare = client.submit(threads, pure=False).result()
                wrapped = client.submit(single_threaded, threads, pure=False).result()
            print(os.cpu_count(), *bare, *wrapped)
    """))
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    cores, bare_config, bare, _, wrapped = map(int, out.stdout.split()[-5:])
    # the trap (with this Dask: Numba in the worker read the core count, not the env's
    # one thread) does not matter: the task runs on one thread
    assert bare == bare_config and wrapped == 1


def test_local_cluster_settings(monkeypatch):
    import distributed
    made = []
    monkeypatch.setattr(distributed, "LocalCluster", lambda **kwargs: made.append(kwargs))
    local_cluster(3)
    assert made == [{"n_workers": 3, "threads_per_worker": 1, "processes": True,
                     "dashboard_address": None,
                     "env": {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}}]
