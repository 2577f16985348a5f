"""
The Dask client of the fleet and the benches, and the map of independent tasks over it.

:func:`dask_client` opens a client: on an embedded ``LocalCluster`` by default (``workers``
processes, one thread each, each with a memory limit — nothing to set up), or on a running
scheduler (``tcp://host:8786``: the same tasks on a real cluster; its workers must import this
package and read the recordings at the same paths).  :func:`map_tasks` submits one task per
argument tuple and hands each result to a callback as it completes; a task that raises, or whose
worker died (killed at its memory limit, lost), comes back as an error with its reason: one
failure never stops the others.

One thread per worker process means one task at a time per worker: a task's memory is bounded
by its worker's limit (Dask's nanny restarts a worker that passes 95 % of it; the task is then
an error).  The workers run numpy with one BLAS thread (Dask's nanny sets ``OMP_NUM_THREADS``,
``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS`` to 1 before a worker starts).
"""
from __future__ import annotations

from contextlib import contextmanager
import logging

from strapdown_ros.text import bounded

__all__ = ['dask_client', 'map_tasks', 'TaskError', 'worker_memory', 'DEFAULT_MEMORY_MIB']

#: memory limit of one worker (one task at a time) by default, MiB
DEFAULT_MEMORY_MIB = 2048.0
#: seconds to wait for a scheduler's answer, or for the workers of a LocalCluster to start
CONNECT_TIMEOUT_S = 60


class TaskError(RuntimeError):
    """A task that raised, or whose worker was lost; ``str()`` is its reason in one line."""


@contextmanager
def dask_client(scheduler: str | None = None, workers: int = 2,
                memory_mib: float = DEFAULT_MEMORY_MIB):
    """
    Open a Dask client: on a scheduler address, or on an embedded LocalCluster.

    Parameters
    ----------
    scheduler : str or None
        ``tcp://host:port`` of a running scheduler; None: a LocalCluster on this machine.
    workers : int
        LocalCluster: worker processes (one thread each).
    memory_mib : float
        LocalCluster: memory limit of each worker, MiB.

    Yields
    ------
    distributed.Client
        The client (closed on exit, with the LocalCluster).

    Raises
    ------
    OSError
        The scheduler does not answer (one line), or the workers cannot start.

    """
    from distributed import Client, LocalCluster          # optional extra (fleet)
    cluster = None
    try:
        if scheduler:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        else:
            cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                                   memory_limit=int(memory_mib * 2 ** 20),
                                   dashboard_address=None, silence_logs=logging.ERROR)
            client = Client(cluster, timeout=CONNECT_TIMEOUT_S)
    except Exception as exc:  # noqa: BLE001 - no scheduler, or workers that cannot start
        if cluster is not None:
            cluster.close()
        where = scheduler or 'a LocalCluster'
        raise OSError(f'cannot reach the Dask scheduler of {bounded(where)}: '
                      f'{bounded(str(exc) or type(exc).__name__, 200)}') from None
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _reason(exc) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ''
    name = type(exc).__name__
    if name == 'KilledWorker':
        text = ('its worker died (killed at its memory limit, or lost) every time it ran; '
                + text)
    return bounded(f'{name}: {text}' if text else name, 300)


def map_tasks(client, fn, args: list, on_done=None, keys: list | None = None) -> list:
    """
    Run ``fn(*a)`` for every ``a`` of ``args`` as Dask tasks; collect the results in order.

    Parameters
    ----------
    client : distributed.Client
        The client.
    fn : callable
        A module-level function (the workers import it).
    args : list of tuple
        The arguments of each task.
    on_done : callable, optional
        ``on_done(index, result_or_TaskError, done, total)`` as each task completes.
    keys : list of str, optional
        Dask keys of the tasks (default: unique).

    Returns
    -------
    list
        Each task's result, or a :class:`TaskError` with its reason.

    """
    from distributed import as_completed                    # optional extra (fleet)
    if not args:
        return []
    futures = [client.submit(fn, *a, pure=False, **({'key': keys[i]} if keys else {}))
               for i, a in enumerate(args)]
    index = {f.key: i for i, f in enumerate(futures)}
    out: list = [None] * len(args)
    for done, fut in enumerate(as_completed(futures), 1):
        i = index[fut.key]
        if fut.status == 'finished':
            out[i] = fut.result()
        else:
            try:
                exc = fut.exception()
            except Exception as e:  # noqa: BLE001 - the future itself is lost
                exc = e
            out[i] = TaskError(_reason(exc))
        fut.release()
        if on_done is not None:
            on_done(i, out[i], done, len(args))
    return out


def worker_memory(client) -> dict:
    """
    Return each worker's peak resident memory so far (``ru_maxrss``), bytes.

    Parameters
    ----------
    client : distributed.Client
        The client.

    Returns
    -------
    dict
        Worker address → bytes.

    """
    return client.run(_maxrss)


def _maxrss() -> int:
    import resource                                         # POSIX only
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024
