"""Running many independent jobs (sweep points, fleet traces) on Dask.

A local cluster (one single-threaded worker process per core) is the default;
a scheduler address such as ``tcp://host:8786`` runs the same work on an
existing cluster. Without a client the same function runs serially in this
process: the serial path and the distributed path call one function on one
item, so their results are identical.

Each job runs inside :func:`_guarded`, which turns a :class:`GmsCompError` or
any other exception into an error row instead of failing the whole run. A
worker that dies is replaced by Dask and its jobs rescheduled (Dask's
``allowed-failures``); a job that keeps killing workers is reported as an error.
"""

from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from threadpoolctl import threadpool_limits
from tqdm import tqdm

from .errors import GmsCompError

T = TypeVar("T")
R = TypeVar("R")


@dataclass(frozen=True)
class JobResult(Generic[R]):
    """Outcome of one job: ``value`` when ``error`` is empty."""

    index: int
    value: R | None
    error: str = ""

    @property
    def ok(self) -> bool:
        return not self.error


def _guarded(fn: Callable[[T], R], index: int, item: T) -> JobResult[R]:
    try:
        return JobResult(index, fn(item))
    except GmsCompError as err:
        return JobResult(index, None, f"{type(err).__name__}: {err}")
    except Exception as err:  # a job's bug must not take the fleet down; keep its trace
        last = traceback.extract_tb(err.__traceback__)[-1]
        where = f" ({os.path.basename(last.filename)}:{last.lineno})"
        return JobResult(index, None, f"{type(err).__name__}: {err}{where}")


@contextmanager
def dask_client(scheduler: str | None = None, n_workers: int | None = None) -> Iterator[Any]:
    """A ``distributed.Client``: to ``scheduler`` if given, else on a new local cluster.

    The local cluster has ``n_workers`` single-threaded worker processes
    (default: one per core), so numba kernels are not fighting over cores.
    """
    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as err:
            raise GmsCompError(f"cannot reach the Dask scheduler at {scheduler}: {err}") from err
        with client:
            yield client
        return
    workers = n_workers or os.cpu_count() or 1
    # Dask's nanny gives each worker MALLOC_TRIM_THRESHOLD_, which also freezes glibc's
    # mmap threshold: every large numpy temporary then costs fresh pages, and the
    # reduction runs ~30 % slower in a worker than in this process. Keep the others.
    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ"))
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    with (
        dask.config.set({"distributed.nanny.pre-spawn-environ": environ}),
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def run_jobs(
    fn: Callable[[T], R],
    items: Sequence[T],
    *,
    client: Any | None = None,
    desc: str = "jobs",
    progress: bool | None = None,
) -> Iterator[JobResult[R]]:
    """Run ``fn`` on every item, yielding results as they complete (any order).

    ``client`` is a ``distributed.Client`` or None for the serial path. The
    progress bar goes to stderr and is shown when stderr is a terminal unless
    ``progress`` says otherwise.
    """
    show = sys.stderr.isatty() if progress is None else progress
    bar = tqdm(total=len(items), desc=desc, unit="job", disable=not show, file=sys.stderr)
    with bar:
        if client is None:
            # Single-threaded BLAS, as in a Dask worker: same arithmetic, same bits.
            with threadpool_limits(limits=1):
                for index, item in enumerate(items):
                    result = _guarded(fn, index, item)
                    bar.update()
                    yield result
            return
        from distributed import as_completed

        futures = {
            client.submit(_guarded, fn, index, item, pure=False, retries=1): index
            for index, item in enumerate(items)
        }
        for future in as_completed(futures):
            index = futures[future]
            try:
                result = future.result()
            except Exception as err:  # KilledWorker and the like: the job itself is lost
                result = JobResult(index, None, f"{type(err).__name__}: {err}")
            bar.update()
            yield result
