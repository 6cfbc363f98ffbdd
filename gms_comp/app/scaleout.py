"""Running many independent jobs (sweep points, fleet traces) on Dask.

A local cluster (one single-threaded worker process per core, listening on
127.0.0.1 only) is the default; a scheduler address such as ``tls://host:8786``
runs the same work on an existing cluster. Without a client the same function
runs serially in this process: the serial path and the distributed path call
one function on one item, so their results are identical.

Dask moves pickled functions: whoever can reach a scheduler runs code on its
workers and in the client, and the client unpickles what the scheduler sends. So the
scheduler comes only from the command line (``--scheduler``, or the ``[scaleout]``
section of the user's own config named with ``--cluster-config``), never from an input
file, and is reached over TLS with certificates (:class:`TlsFiles`, Dask's
``Security``); a plain ``tcp://`` address is refused unless the user says
``--insecure-scheduler`` (then one warning line on stderr for a remote host).

Each job runs inside :func:`_guarded`, which turns a :class:`GmsCompError` or
any other exception into an error row instead of failing the whole run. A
worker that dies is replaced by Dask and its jobs rescheduled (Dask's
``allowed-failures``); a job that keeps killing workers is reported as an error.
"""

from __future__ import annotations

import argparse
import ipaddress
import logging
import os
import sys
import traceback
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar
from urllib.parse import urlsplit

from threadpoolctl import threadpool_limits
from tqdm import tqdm

from gms_comp.arguments import input_file, int_in_range, scheduler_address
from gms_comp.config import parse_section, read_toml
from gms_comp.errors import ConfigError, GmsCompError, InputError
from gms_comp.validation import MAX_WORKERS

#: Printed (one line, stderr) when a remote scheduler is reached over plain tcp.
PLAIN_TCP_WARNING = (
    "warning: the Dask scheduler at {address} is reached over plain tcp: anyone who can "
    "reach it runs any code on its workers and in this client; use tls:// with "
    "--tls-ca-file/--tls-cert/--tls-key"
)
#: The refusal of a plain tcp scheduler without ``--insecure-scheduler``.
PLAIN_TCP_REFUSAL = (
    "{address} is plain tcp: whoever answers there runs any code in this client and on "
    "the workers; use tls:// with --tls-ca-file/--tls-cert/--tls-key, or say "
    "--insecure-scheduler on a network you trust"
)

T = TypeVar("T")
R = TypeVar("R")

#: The only interface a local cluster's scheduler and workers listen on.
LOCAL_HOST = "127.0.0.1"


@dataclass(frozen=True)
class JobResult(Generic[R]):
    """Outcome of one job: ``value`` when ``error`` is empty."""

    index: int
    value: R | None
    error: str = ""

    @property
    def ok(self) -> bool:
        """True when the job raised nothing."""
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


@dataclass(frozen=True)
class TlsFiles:
    """The PEM files of a TLS connection to a Dask scheduler.

    ``ca_file`` is the certificate authority that signed the scheduler's and
    workers' certificates; ``cert``/``key`` are this client's certificate and key.
    """

    ca_file: Path
    cert: Path
    key: Path

    def security(self) -> Any:
        """Dask's ``Security`` for a client that requires encryption."""
        from distributed.security import Security

        return Security(
            tls_ca_file=str(self.ca_file),
            tls_client_cert=str(self.cert),
            tls_client_key=str(self.key),
            require_encryption=True,
        )


@dataclass(frozen=True)
class ScaleoutConfig:
    """The optional ``[scaleout]`` section: where to run and how to reach the scheduler.

    Read only from the user's own config named with ``--cluster-config`` (a sweep file's
    is refused). Paths are relative to the file that holds the section; command-line
    options override them.
    """

    scheduler: str = ""
    tls_ca_file: str = ""
    tls_cert: str = ""
    tls_key: str = ""

    def problems(self) -> list[tuple[str, str]]:
        """`scheduler`, if set, is a scheduler address (`tcp://` or `tls://` host and port).

        Returns ``(key, reason)`` pairs for values that are wrong together.
        """
        if self.scheduler:
            try:
                scheduler_address(self.scheduler)
            except argparse.ArgumentTypeError as err:
                return [("scheduler", str(err))]
        return []


def load_scaleout(doc: dict[str, Any], path: str | Path) -> ScaleoutConfig:
    """The ``[scaleout]`` section of a parsed file, TLS paths made absolute."""
    cfg = parse_section(doc, path, "scaleout", ScaleoutConfig)
    folder = Path(path).resolve().parent
    resolved = {
        name: str(folder / value) if value else ""
        for name, value in (
            ("tls_ca_file", cfg.tls_ca_file),
            ("tls_cert", cfg.tls_cert),
            ("tls_key", cfg.tls_key),
        )
    }
    for name, value in resolved.items():
        if value and not Path(value).is_file():
            raise ConfigError(str(path), f"scaleout.{name}", f"{value!r} is not a file")
    return ScaleoutConfig(scheduler=cfg.scheduler, **resolved)


def tls_files(
    ca_file: str | Path | None,
    cert: str | Path | None,
    key: str | Path | None,
    source: str = "--tls-ca-file/--tls-cert/--tls-key",
) -> TlsFiles | None:
    """All three TLS files, or None when none is given; a partial set is refused."""
    given = [v for v in (ca_file, cert, key) if v]
    if not given:
        return None
    if len(given) != 3:
        raise InputError(source, "", "give all three: the CA file, the certificate and the key")
    files = TlsFiles(Path(str(ca_file)), Path(str(cert)), Path(str(key)))
    for name, path in (("CA file", files.ca_file), ("certificate", files.cert), ("key", files.key)):
        if not path.is_file():
            raise InputError(source, name, f"{str(path)!r} is not a file")
    return files


def _is_loopback(address: str) -> bool:
    host = urlsplit(address).hostname or ""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _check_remote(scheduler: str, tls: TlsFiles | None, insecure: bool = False) -> None:
    """Refuse a malformed address, a transport that does not match the TLS files, and a
    plain tcp one unless ``insecure`` (the user's ``--insecure-scheduler``)."""
    try:
        scheduler_address(scheduler)
    except argparse.ArgumentTypeError as err:
        raise InputError("--scheduler", "", str(err)) from None
    scheme = urlsplit(scheduler).scheme
    if scheme == "tls" and tls is None:
        raise InputError(
            "--scheduler", "", "a tls:// scheduler needs --tls-ca-file, --tls-cert and --tls-key"
        )
    if scheme == "tcp" and tls is not None:
        raise InputError(
            "--scheduler", "", f"TLS files were given but {scheduler} is plain tcp; use tls://"
        )
    if scheme == "tcp" and not insecure:
        raise InputError("--scheduler", "", PLAIN_TCP_REFUSAL.format(address=scheduler))
    if scheme == "tcp" and not _is_loopback(scheduler):
        print(PLAIN_TCP_WARNING.format(address=scheduler), file=sys.stderr)


@contextmanager
def dask_client(
    scheduler: str | None = None,
    n_workers: int | None = None,
    tls: TlsFiles | None = None,
    insecure: bool = False,
) -> Iterator[Any]:
    """A ``distributed.Client``: to ``scheduler`` if given, else on a new local cluster.

    The local cluster has ``n_workers`` single-threaded worker processes
    (default: one per core), so numba kernels are not fighting over cores; its
    scheduler and workers listen on 127.0.0.1 only. A remote ``tls://`` scheduler
    is reached with the certificates of ``tls``; a ``tcp://`` one only when
    ``insecure`` (refused before connecting otherwise).
    """
    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        _check_remote(scheduler, tls, insecure)
        security = tls.security() if tls is not None else None
        try:
            client = Client(scheduler, timeout="10s", security=security)
        except Exception as err:  # whatever answers there is not our scheduler
            reason = " ".join(str(err).split()) or type(err).__name__
            raise GmsCompError(
                f"cannot reach the Dask scheduler at {scheduler}: {reason}"
            ) from None
        with client:
            yield client
        return
    if n_workers is not None and not 1 <= n_workers <= MAX_WORKERS:
        raise InputError("--workers", "", f"must be in [1, {MAX_WORKERS}], got {n_workers}")
    workers = n_workers or os.cpu_count() or 1
    # Dask's nanny gives each worker MALLOC_TRIM_THRESHOLD_, which also freezes glibc's
    # mmap threshold: every large numpy temporary then costs fresh pages, and the
    # reduction runs ~30 % slower in a worker than in this process. Keep the others.
    environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ"))
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    # Interrupted, the workers die holding semaphores, which multiprocessing's resource
    # tracker (a process of its own, started with the cluster, whose warnings filter
    # comes from the environment) frees and reports in a warning: freed is enough.
    os.environ.setdefault("PYTHONWARNINGS", "ignore:resource_tracker:UserWarning")
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}):
        with warnings.catch_warnings():
            # The scheduler's small HTTP server (health routes, on 127.0.0.1) takes another
            # port when 8787 is in use (another cluster's) and says so: that is fine.
            warnings.filterwarnings("ignore", "Port .* is already in use", UserWarning)
            cluster = LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                host=LOCAL_HOST,
                dashboard_address=None,
                # Dask's own log lines (a worker that loses its scheduler when Ctrl-C or
                # SIGTERM closes the cluster logs tracebacks) stay out of the one-line
                # report; a job's failure is reported in its row.
                silence_logs=logging.CRITICAL,
            )
        with cluster, Client(cluster) as client:
            if not _is_loopback(cluster.scheduler_address):  # pragma: no cover - Dask change
                raise GmsCompError(
                    f"local Dask scheduler not on loopback: {cluster.scheduler_address}"
                )
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


def add_cluster_arguments(parser: Any, default_hint: str = "a local cluster") -> None:
    """Add ``--scheduler``, ``--tls-ca-file/--tls-cert/--tls-key``, ``--workers`` and
    ``--serial`` to a subcommand's parser (the same options for every Dask command)."""
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        type=scheduler_address,
        help=f"Dask scheduler, tls://host:8786 with the --tls-* files (default: {default_hint})",
    )
    parser.add_argument(
        "--cluster-config",
        metavar="TOML",
        type=input_file,
        help="your own config whose [scaleout] section names the scheduler and TLS files",
    )
    parser.add_argument(
        "--insecure-scheduler",
        action="store_true",
        help="allow a plain tcp:// scheduler (anyone who can reach it runs code here)",
    )
    for option, what in (
        ("--tls-ca-file", "CA certificate (PEM) that signed the scheduler's certificate"),
        ("--tls-cert", "this client's certificate (PEM)"),
        ("--tls-key", "this client's private key (PEM)"),
    ):
        parser.add_argument(option, type=input_file, metavar="PEM", help=what)
    parser.add_argument(
        "--workers",
        type=int_in_range(1, MAX_WORKERS),
        default=None,
        help="local cluster size (default: one per core)",
    )
    parser.add_argument("--serial", action="store_true", help="run in this process, no Dask")


def cli_cluster(args: Any) -> tuple[str | None, TlsFiles | None]:
    """The scheduler and TLS files the command line names: ``--scheduler`` and
    ``--tls-*``, else the ``[scaleout]`` section of ``--cluster-config``; ``(None,
    None)``: a local cluster."""
    cfg = ScaleoutConfig()
    if args.cluster_config is not None:
        cfg = load_scaleout(read_toml(args.cluster_config), args.cluster_config)
    tls = None
    if args.tls_ca_file or args.tls_cert or args.tls_key:
        tls = tls_files(args.tls_ca_file, args.tls_cert, args.tls_key)
    elif cfg.tls_ca_file or cfg.tls_cert or cfg.tls_key:
        source = f"{args.cluster_config}: scaleout"
        tls = tls_files(cfg.tls_ca_file, cfg.tls_cert, cfg.tls_key, source=source)
    return args.scheduler or cfg.scheduler or None, tls


@contextmanager
def cli_client(args: Any) -> Iterator[Any]:
    """:func:`dask_client` as the command line asks (:func:`cli_cluster`,
    ``--workers``, ``--insecure-scheduler``)."""
    scheduler, tls = cli_cluster(args)
    with dask_client(scheduler, args.workers, tls, args.insecure_scheduler) as client:
        yield client
