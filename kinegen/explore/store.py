"""An exploration on disk: a Parquet dataset written partition by partition.

``<out>/`` (e.g. ``out/explore.parquet/``) holds one file per partition, ``part-000042.parquet``,
each written whole or not at all (a temporary file in the folder, then ``os.replace``), and
``_provenance.json``: the model (name, file, source hash), the study, kinegen's version, the
sampler, its seed, the number of variants and the partition size -- everything that fixes which
variants exist and what they measure. Each part carries the same provenance in its Parquet
schema metadata (key ``kinegen``). Readers that skip files beginning with ``_`` (pyarrow, pandas,
Dask, DuckDB) read the folder as one table.

A run that stops (interrupted, a crash, the machine gone) leaves the finished partitions;
``--resume`` checks that the provenance is the same and computes only the partitions with no file.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from kinegen.errors import ExitCode, KinegenError
from kinegen.explore.variants import PartitionResult
from kinegen.files import write_atomic

PROVENANCE = "_provenance.json"
_PART = re.compile(r"^part-(\d{6,})\.parquet$")
#: provenance fields that may differ between a run and its resumption: when, where the model file
#: is (its source hash must match), which kinegen, the nominal design's quantities (for the plot)
_INCIDENTAL = ("created", "kinegen_version", "model_file", "nominal")


class ExplorationError(KinegenError):
    """An exploration's output folder cannot be used as asked (it holds another run, or is not one)."""

    exit_code = ExitCode.EXPLORATION


def part_name(partition: int) -> str:
    return f"part-{partition:06d}.parquet"


class Store:
    """The Parquet dataset of one exploration at ``path`` (a folder)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    @property
    def provenance_file(self) -> Path:
        return self.path / PROVENANCE

    def exists(self) -> bool:
        return self.path.exists() and any(self.path.iterdir()) if self.path.is_dir() else self.path.exists()

    def provenance(self) -> dict:
        """The provenance of the run held here."""
        try:
            return json.loads(self.provenance_file.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ExplorationError(f"{self.path}: not a kinegen exploration (no {PROVENANCE})") from None

    def start(self, provenance: dict, resume: bool) -> list[int]:
        """Open the store for a run with ``provenance``; the partitions already done (resume).

        A new run needs an empty or missing folder; a resumed one the same provenance (but for
        the fields in ``_INCIDENTAL``). Leftover temporary files of an
        interrupted write are removed."""
        if self.path.exists() and not self.path.is_dir():
            raise ExplorationError(f"{self.path} is a file: an exploration is written to a folder")
        if self.exists():
            if not resume:
                done = len(self.done())
                raise ExplorationError(
                    f"{self.path} already holds an exploration ({done} partitions written): add --resume to continue it, "
                    "or choose another --out (nothing is overwritten)"
                )
            held = self.provenance()
            changed = sorted(k for k in set(held) | set(provenance) if k not in _INCIDENTAL and held.get(k) != provenance.get(k))
            if changed:
                shown = "; ".join(f"{k}: {held.get(k)!r} there, {provenance.get(k)!r} now" for k in changed)
                raise ExplorationError(f"{self.path} holds another exploration ({shown}): resume it with the same settings, or choose another --out")
            for leftover in self.path.glob(".part-*.tmp"):
                leftover.unlink()
            return self.done()
        self.path.mkdir(parents=True, exist_ok=True)
        write_atomic(self.provenance_file, (json.dumps(provenance, indent=2, sort_keys=True) + "\n").encode())
        return []

    def done(self) -> list[int]:
        """The partitions with a file, in order."""
        if not self.path.is_dir():
            return []
        return sorted(int(m.group(1)) for m in map(_PART.match, os.listdir(self.path)) if m)

    def write(self, result: PartitionResult, provenance: dict) -> Path:
        """One partition's variants as ``part-NNNNNN.parquet``, atomically."""
        table = to_table(result).replace_schema_metadata({"kinegen": json.dumps(provenance, sort_keys=True)})
        target = self.path / part_name(result.partition)
        sink = pa.BufferOutputStream()
        pq.write_table(table, sink, compression="zstd")
        write_atomic(target, sink.getvalue().to_pybytes())
        return target

    def read(self, columns: list[str] | None = None) -> pa.Table:
        """Every variant written so far (``columns`` of them, or all), sorted by variant index."""
        wanted = None if columns is None else list(dict.fromkeys(["variant", *columns]))
        parts = [pq.read_table(self.path / part_name(i), columns=wanted) for i in self.done()]
        if not parts:
            raise ExplorationError(f"{self.path}: no partition written yet")
        table = pa.concat_tables(parts).replace_schema_metadata(None)
        return table.sort_by("variant")


def to_table(result: PartitionResult) -> pa.Table:
    """A partition's columns: variant, the parameters, status, message, the quantities, feasible."""
    columns: dict[str, pa.Array] = {"variant": pa.array(result.variant, pa.int64())}
    columns.update({name: pa.array(values, pa.float64()) for name, values in result.parameters.items()})
    columns["status"] = pa.array(result.status, pa.string())
    columns["message"] = pa.array(result.message, pa.string())
    columns.update({label: pa.array(values, pa.float64()) for label, values in result.quantities.items()})
    columns["feasible"] = pa.array(np.asarray(result.feasible, dtype=bool), pa.bool_())
    return pa.table(columns)
