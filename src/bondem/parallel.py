"""Dask workers that run one simulation per core.

The studies, the lab's series and the calibration run many small simulations at once: one
single-threaded worker process per core. Setting NUMBA_NUM_THREADS in a LocalCluster's
``env`` is not enough for that. The nanny sets that environment only after the worker
process has started, and a spawned worker first re-imports the main module: the
``bondem`` command imports Numba there, which then reads the core count instead. Each
worker's Numba then runs two OpenMP threads on a 2-core machine, whose spinning threads
took the other worker's core: the calibration example's simulations ran 4-5x slower on
its workers than in a plain process (docs/calibration.md). ``single_threaded`` sets
Numba's thread count on the thread that runs the task, whatever was imported first.

The cluster's env must not set NUMBA_NUM_THREADS either: Numba re-reads its environment
on every compile, and a worker that launched its threads with the core count then found
the env's 1 and refused to compile ("Cannot set NUMBA_NUM_THREADS to a different value
once the threads have been launched"). Every kernel a worker had to compile, because a
new bondem or a fresh machine had no cache of it yet, failed so: `bondem lab envelope`
and the calibration failed on their first run.
"""
import os

SINGLE = {"OMP_NUM_THREADS": "1"}


def single_threaded(function, *args, **kwargs):
    """function(*args, **kwargs) with Numba's parallel kernels on one thread (the calling
    thread's setting is restored after): what a Dask worker runs, one simulation per
    core."""
    import numba
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        return function(*args, **kwargs)
    finally:
        numba.set_num_threads(threads)


def local_cluster(workers=None):
    """A Dask LocalCluster of ``workers`` single-threaded worker processes (default: one
    per core); submit its tasks through ``single_threaded``."""
    from distributed import LocalCluster
    return LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                        processes=True, dashboard_address=None, env=dict(SINGLE))
