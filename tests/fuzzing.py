"""The fuzzer's worker: loads (and, for fuzzed time functions, builds and checks) one model
file at a time in a separate process whose address space is limited, and reports how it
ended, the CPU time and the peak memory it took.

A memory blow-up is then a failure of that one model (``MemoryError`` in the worker, or the
worker dying), not a machine brought down by the test; a model that hangs is killed after
:data:`WALL_LIMIT` seconds. Used by ``tests/test_fuzz.py``.
"""

from __future__ import annotations

import multiprocessing
import os
import re
import shutil
import tempfile
import time
import traceback
import warnings
from pathlib import Path

#: Address space a worker may use beyond what it holds after importing kinegen.
MEMORY_LIMIT = 1 << 30
#: Wall-clock seconds after which a model counts as hung and its worker is killed.
WALL_LIMIT = 30.0


def _status(key: str) -> int:
    """A field of /proc/self/status in kB (VmRSS, VmHWM, VmSize)."""
    return int(re.search(rf"{key}:\s+(\d+)", Path("/proc/self/status").read_text()).group(1))


def _reset_peak() -> None:
    """Start VmHWM (the peak resident size) afresh (Linux: write 5 to clear_refs)."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        pass


def _serve(connection, limit: int, work: Path) -> None:
    """Worker loop: receive (kind, bytes), answer with a report dict, until None arrives."""
    import resource

    warnings.simplefilter("ignore")
    # what the checks compile (the modules' code, kinegen.runtime.bytecode) is kept in the worker's folder,
    # removed with it: thousands of fuzzed modules are not the user's cache
    os.environ["KINEGEN_CACHE"] = str(work / "cache")
    from kinegen.codegen import generate_source
    from kinegen.errors import KinegenError, ModelError
    from kinegen.model import load
    from kinegen.rotations import get
    from kinegen.runtime import check_source

    ceiling = _status("VmSize") * 1024 + limit
    resource.setrlimit(resource.RLIMIT_AS, (ceiling, ceiling))
    path = work / "fuzzed.yaml"
    while True:
        job = connection.recv()
        if job is None:
            break
        kind, data = job
        path.write_bytes(data)
        _reset_peak()
        before = _status("VmRSS")
        start = time.process_time()
        report: dict = {"outcome": "accepted"}
        try:
            model = load(path)
            if kind == "expression":  # time functions: build and check on the time grid as `kinegen build` does
                check_source(generate_source(model, get("quaternion")), path)
        except ModelError as error:
            report = {"outcome": "model-error", "file": error.file, "entry": error.entry, "problem": error.problem,
                      "line": error.line, "message": str(error)}  # fmt: skip
        except KinegenError as error:  # e.g. an initial pose that a fuzzed parameter made unassemblable
            report = {"outcome": "kinegen-error", "message": str(error), "type": type(error).__name__}
        except MemoryError:
            report = {"outcome": "memory", "message": "MemoryError: the model exceeded the worker's memory limit"}
        except BaseException as error:
            report = {"outcome": "crash", "message": "".join(traceback.format_exception(error))[-3000:]}
        report["cpu"] = time.process_time() - start
        report["peak_mb"] = max(0, _status("VmHWM") - before) / 1024
        connection.send(report)
    connection.close()


class Worker:
    """One worker process (spawned, so that it starts clean), restarted after it dies."""

    def __init__(self, limit: int = MEMORY_LIMIT) -> None:
        self.limit = limit
        #: the workers' folder, made and removed here: a worker killed mid-model leaves nothing behind
        self.work = Path(tempfile.mkdtemp(prefix="kinegen-fuzz-worker-"))
        self._context = multiprocessing.get_context("spawn")
        self._start()

    def _start(self) -> None:
        self.connection, child = self._context.Pipe()
        self.process = self._context.Process(target=_serve, args=(child, self.limit, self.work), daemon=True)
        self.process.start()
        child.close()

    def run(self, kind: str, data: bytes) -> dict:
        """The report of one model: outcome, message, cpu (s), peak_mb; wall-clock bounded."""
        self.connection.send((kind, data))
        if not self.connection.poll(WALL_LIMIT):
            self.process.kill()
            self.process.join()
            self._start()
            return {"outcome": "timeout", "message": f"no answer within {WALL_LIMIT} s", "cpu": WALL_LIMIT, "peak_mb": 0.0}
        try:
            return self.connection.recv()
        except (EOFError, OSError):
            self.process.join()
            code = self.process.exitcode
            self._start()
            return {"outcome": "died", "message": f"the worker died (exit code {code})", "cpu": 0.0, "peak_mb": 0.0}

    def close(self) -> None:
        try:
            self.connection.send(None)
            self.process.join(5)
        except (OSError, ValueError):
            pass
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        shutil.rmtree(self.work, ignore_errors=True)


def environment_allows_workers() -> bool:
    """True where /proc exists (the peak-memory reading needs it)."""
    return os.path.exists("/proc/self/status")
