"""Run many ``gms-comp`` command lines fast, each in its own process, under a memory cap.

Used by the fuzz tests: this process imports gms-comp once, then forks one child per
command line. The child sets ``RLIMIT_AS``, points stdout/stderr at files, and runs
``python -m gms_comp`` exactly as the interpreter would (``runpy`` on the package's
``__main__``; an uncaught exception prints its traceback and exits 1). A child that
outlives its time bound is killed and reported as a hang.

    python tests/cli_runner.py CASES.json RESULTS.json

CASES.json is a list of ``{"id", "argv", "cwd", "timeout_s"}``; RESULTS.json gets one
``{"id", "rc", "stdout", "stderr", "seconds", "timed_out"}`` per case.
"""

from __future__ import annotations

import json
import os
import resource
import runpy
import signal
import sys
import tempfile
import time
import traceback
from typing import IO, Any

MEMORY_CAP_BYTES = 3 << 30
PARALLEL = 2


def limit_memory() -> None:
    """Cap this process's address space (a ``preexec_fn`` for subprocesses too)."""
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP_BYTES, MEMORY_CAP_BYTES))


def _child(case: dict[str, Any], out: IO[bytes], err: IO[bytes]) -> None:
    """Run one command line in this (forked) process and exit with its code."""
    code = 1
    try:
        limit_memory()
        devnull = os.open(os.devnull, os.O_RDONLY)
        os.dup2(devnull, 0)
        os.dup2(out.fileno(), 1)
        os.dup2(err.fileno(), 2)
        os.chdir(case["cwd"])
        sys.argv = ["gms-comp", *case["argv"]]
        try:
            runpy.run_module("gms_comp", run_name="__main__", alter_sys=True)
            code = 0
        except SystemExit as exc:
            if exc.code is None or isinstance(exc.code, int):
                code = exc.code or 0
            else:
                print(exc.code, file=sys.stderr)
                code = 1
        except BaseException:
            traceback.print_exc()
            code = 1
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(code)


def run_cases(cases: list[dict[str, Any]], parallel: int = PARALLEL) -> list[dict[str, Any]]:
    """Run every case (``parallel`` at a time); results in the order of ``cases``."""
    from gms_comp.app.cli import build_parser

    build_parser()  # import every command module once, before forking
    pending = list(enumerate(cases))
    running: dict[int, tuple[int, IO[bytes], IO[bytes], float]] = {}
    results: list[dict[str, Any]] = [{} for _ in cases]
    while pending or running:
        while pending and len(running) < parallel:
            index, case = pending.pop(0)
            out: IO[bytes] = tempfile.TemporaryFile()  # noqa: SIM115 - closed when reaped
            err: IO[bytes] = tempfile.TemporaryFile()  # noqa: SIM115
            sys.stdout.flush()
            sys.stderr.flush()
            pid = os.fork()
            if pid == 0:
                _child(case, out, err)
            running[pid] = (index, out, err, time.monotonic())
        time.sleep(0.01)
        for pid, (index, out_file, err_file, start) in list(running.items()):
            done, status = os.waitpid(pid, os.WNOHANG)
            timed_out = False
            if not done:
                if time.monotonic() - start < cases[index].get("timeout_s", 30.0):
                    continue
                os.kill(pid, signal.SIGKILL)
                _, status = os.waitpid(pid, 0)
                timed_out = True
            del running[pid]
            out_file.seek(0)
            err_file.seek(0)
            results[index] = {
                "id": cases[index]["id"],
                "rc": os.waitstatus_to_exitcode(status),
                "stdout": out_file.read().decode("utf-8", "replace"),
                "stderr": err_file.read().decode("utf-8", "replace"),
                "seconds": time.monotonic() - start,
                "timed_out": timed_out,
            }
            out_file.close()
            err_file.close()
    return results


if __name__ == "__main__":
    with open(sys.argv[1], encoding="utf-8") as fh:
        todo = json.load(fh)
    with open(sys.argv[2], "w", encoding="utf-8") as fh:
        json.dump(run_cases(todo), fh)
