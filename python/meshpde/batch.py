"""Cohort jobs: one meshpde operation over many mesh files on a Dask cluster.

    import meshpde.batch
    table = meshpde.batch.run("fair", files, "faired/", options={"fixed": "boundary"})
    table = meshpde.batch.run("fair", files, "faired/", options=..., scheduler="tcp://head:8786")

One task a mesh. Each task reads its file, runs the operation, and writes, atomically,
the output mesh (positions and vertex fields) and a JSON report beside it. The run
gathers the reports in a table, also written as ``batch.json`` and ``batch.csv`` in
the output folder. A file that fails, whether it raises or kills its worker, is a
failed row; the other files go on. Run the same call again to skip the files already
done (same input, operation, options and meshpde version) and retry the failed ones.
Without ``scheduler`` or ``client`` the run starts a ``LocalCluster`` of ``workers``
processes on this machine. ``python3 -m meshpde.batch`` is the same as a command.

Needs Debian's ``python3-distributed`` (``dask.distributed``) for ``run``; ``process``
runs one file in this process without it. docs/batch.md has a worked example.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import hashlib
import json
import math
import os
import pathlib
import sys
import tempfile
import time
import traceback
import uuid
import warnings
from typing import Any, Callable, Mapping, Sequence

import numpy as np

import meshpde

__all__ = ["Output", "BatchResult", "OPERATIONS", "run", "process", "main"]

# Formats that hold vertex fields; an operation whose output has fields writes .ply
# when the input's format (OBJ, OFF, STL) would drop them.
_FIELD_FORMATS = {".ply", ".vtp", ".vtk"}


@dataclasses.dataclass
class Output:
    """What an operation gives back for one mesh, as the batch writes it.

    V, F: the output mesh (None: no mesh is written, only the report);
    fields: vertex fields by name, (n,) or (n, k) arrays, written with the mesh;
    report: JSON-able values for the file's report and the table.
    A callable operation may return an Output, or any result of a meshpde function.
    """

    V: np.ndarray | None = None
    F: np.ndarray | None = None
    fields: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    report: dict[str, Any] = dataclasses.field(default_factory=dict)


# The named operations: a meshpde function and the name of the field its per-vertex
# result is written under. Each takes (V, F, **options) as the function of that name.
def _self_intersections(V, F):
    return {"self_intersections": int(len(meshpde.self_intersections(V, F)))}


def _intrinsic_delaunay(V, F, **options):
    _, _, stats = meshpde.intrinsic_delaunay(V, F, **options)
    return dict(stats)


OPERATIONS: dict[str, Callable[..., Any]] = {
    "fair": meshpde.fair,
    "correct": meshpde.correct,
    "interpolate": meshpde.interpolate,
    "curvature": meshpde.curvature,
    "heat": meshpde.heat,
    "wave": meshpde.wave,
    "vertex_normals": meshpde.vertex_normals,
    "info": meshpde.info,
    "check_units": meshpde.check_units,
    "self_intersections": _self_intersections,
    "intrinsic_delaunay": _intrinsic_delaunay,
}
_FIELD_NAME = {"curvature": "mean_curvature", "interpolate": "interpolated", "vertex_normals": "normal"}


def _jsonable(value):
    """value as JSON data (numpy scalars and small arrays to Python), or None if it
    isn't (NaN and infinities included: JSON has no such numbers)."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, (str, bool, int)) or value is None:
        return value
    if isinstance(value, np.ndarray):
        return [_jsonable(v) for v in value.tolist()] if value.size <= 16 else None
    if isinstance(value, Mapping):
        out = {str(k): _jsonable(v) for k, v in value.items()}
        return {k: v for k, v in out.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return None


def _outcome(name: str, result, V: np.ndarray, F: np.ndarray) -> Output:
    """Any meshpde function's result as an Output: a (n, ...) array is a vertex field,
    an object's V is the new positions and its other per-vertex arrays fields."""
    if isinstance(result, Output):
        return result
    n = len(V)
    if isinstance(result, Mapping):
        return Output(report=_jsonable(result))
    if isinstance(result, np.ndarray):
        if result.shape[:1] == (n,):
            return Output(V=V, F=F, fields={_FIELD_NAME.get(name, name): result})
        return Output(report={f"{name}_rows": int(len(result))})
    if isinstance(result, tuple) and len(result) == 2 and all(isinstance(a, np.ndarray) for a in result):
        return Output(V=result[0], F=result[1])  # a new mesh, as generate and subdivide give
    if isinstance(result, meshpde.CorrectionResult):
        return Output(V=result.V, F=F, fields={"displacement": result.displacement}, report=_jsonable(result.to_dict()))
    attributes = dict(vars(result)) if hasattr(result, "__dict__") else {}
    out = Output(V=V, F=F)
    if isinstance(attributes.get("V"), np.ndarray) and attributes["V"].shape == V.shape:
        out.V = attributes.pop("V")
    for key, value in attributes.items():
        if isinstance(value, np.ndarray) and value.shape[:1] == (n,):
            out.fields[key] = value
        elif (v := _jsonable(value)) is not None:
            out.report[key] = v
    return out


def _operation_name(operation) -> str:
    if isinstance(operation, str):
        return operation
    return f"{getattr(operation, '__module__', '?')}.{getattr(operation, '__qualname__', repr(operation))}"


def _resolve(operation) -> tuple[str, Callable[..., Any]]:
    if callable(operation):
        return _operation_name(operation), operation
    if operation not in OPERATIONS:
        raise meshpde.InputError(f"meshpde.batch: unknown operation {operation!r}; "
                                 f"give a callable or one of {', '.join(sorted(OPERATIONS))}")
    return operation, OPERATIONS[operation]


def _digest(*parts) -> str:
    """A stable hash of JSON-like data with numpy arrays in it (the re-run check)."""
    h = hashlib.sha256()

    def feed(x):
        if isinstance(x, np.ndarray):
            h.update(f"array{x.dtype.str}{x.shape}".encode())
            h.update(np.ascontiguousarray(x).tobytes())
        elif isinstance(x, Mapping):
            h.update(b"{")
            for k in sorted(x, key=str):
                feed(str(k))
                feed(x[k])
            h.update(b"}")
        elif isinstance(x, (list, tuple)):
            h.update(b"[")
            for v in x:
                feed(v)
            h.update(b"]")
        else:
            h.update(repr(x).encode())
            h.update(b";")

    for p in parts:
        feed(p)
    return h.hexdigest()


def _fingerprint(path: pathlib.Path, name: str, options: Mapping[str, Any], output_format, picture) -> str:
    """What decides whether a file is done already: the input (size and modification
    time), the operation, its options, what is written and the meshpde version."""
    st = path.stat()
    return _digest(name, dict(options), output_format, bool(picture), meshpde.__version__, st.st_size,
                   st.st_mtime_ns)


def _write_json(path: pathlib.Path, data) -> None:
    """Atomically: a temporary file in the same folder, renamed over the target."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(data, f, indent=2, allow_nan=False, default=lambda o: None)
            f.write("\n")
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _targets(path: pathlib.Path, output_dir: pathlib.Path):
    """(the output mesh's path less its suffix, the report's path) of one input."""
    return output_dir / path.stem, output_dir / f"{path.stem}.json"


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return "local"


def process(operation, path, output_dir, options: Mapping[str, Any] | None = None, *,
            output_format: str | None = None, picture: bool = False) -> dict[str, Any]:
    """Runs ``operation`` on one mesh file in this process and writes its output and
    report into ``output_dir``, as one task of :func:`run` does. Returns the table row.
    Arguments as in :func:`run`.

    Never raises for a bad file: the row's status is "failed" and its error says why.
    """
    path, output_dir = pathlib.Path(path), pathlib.Path(output_dir)
    options = dict(options or {})
    name, function = _resolve(operation)
    base, report_path = _targets(path, output_dir)
    row = {"input": str(path), "status": "failed", "output": None, "report_file": str(report_path),
           "seconds": 0.0, "worker": _worker_name(), "error": None, "note": None, "report": {}}
    start = time.perf_counter()
    try:
        fingerprint = _fingerprint(path, name, options, output_format, picture)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            V, F, given = meshpde.read_mesh(path)
            units = meshpde.check_units(V, F, options.get("units", "mm"))
            if units["warning"]:
                row["note"] = units["warning"]  # a model that looks like another unit
            call = dict(options)
            if name == "correct" and "face_labels" not in call:
                # The file's face labels: its flat labelled caps are held (correct's caps rule).
                for key in ("ModelFaceID", "CellEntityIds", "MaterialIds"):
                    if key in given.cells and np.ndim(given.cells[key]) == 1:
                        call["face_labels"] = given.cells[key]
                        break
            out = _outcome(name, function(V, F, **call), V, F)
            if out.V is not None:
                suffix = (output_format or path.suffix).lower()
                if not suffix.startswith("."):
                    suffix = "." + suffix
                if out.fields and suffix not in _FIELD_FORMATS:
                    suffix = ".ply"  # OBJ, OFF and STL would drop the fields
                target = base.with_name(base.name + suffix)
                meshpde.write_mesh(target, out.V, out.F if out.F is not None else F,
                                   _kept_fields(given, out, V, F))
                row["output"] = str(target)
            if picture:
                row["picture"] = _picture(base.with_name(base.name + ".png"), out, V, F, f"{path.name}: {name}")
        row["report"] = out.report
        if caught:
            row["report"]["warnings"] = [str(w.message) for w in caught]
        row["status"] = "ok"
        row["fingerprint"] = fingerprint
    except Exception as e:  # a bad file is a failed row, never the end of the batch
        row["error"] = f"{type(e).__name__}: {e}"
        row["traceback"] = traceback.format_exc(limit=4)
    row["seconds"] = round(time.perf_counter() - start, 6)
    row["operation"] = name
    row["options"] = _jsonable(options)
    _write_json(report_path, row)
    return row


def _kept_fields(given, out: Output, V, F):
    """What the output mesh carries: on the input's triangles, everything the input file
    carried (its vertex fields and cell arrays in their types, its frame and field data;
    normals recomputed where the vertices moved) under the operation's fields; on new
    triangles, the operation's fields alone."""
    if out.F is not None and (out.F is not F and not np.array_equal(out.F, F)):
        return out.fields
    kept = given.copy()
    if out.V is not V and not np.array_equal(out.V, V) and (given or given.cells):
        fields, cells, _ = meshpde._meshpde._refresh_normals(out.V, F, dict(given), given.cells)
        kept = meshpde.MeshFields(fields, cells, given.space, given.field_data)
    kept.update(out.fields)
    return kept


def _picture(target: pathlib.Path, out: Output, V, F, title: str) -> str:
    """A PNG of the output mesh (the input's when there is none), coloured by its first
    field (a vector field by its length) from its 2nd to its 98th percentile, so that a
    few sliver values do not wash the rest out: a cohort checked at a glance."""
    shown_V = out.V if out.V is not None else V
    shown_F = out.F if out.F is not None else F
    field_name, field = next(iter(out.fields.items()), (None, None))
    shown_range = None
    if field is not None:
        field = np.linalg.norm(field, axis=1) if np.ndim(field) == 2 else np.asarray(field, float)
        lo, hi = np.percentile(field[np.isfinite(field)], [2, 98]) if np.isfinite(field).any() else (0, 0)
        shown_range = (float(lo), float(hi)) if hi > lo else None
    meshpde.render(shown_V, shown_F, field=field, path=str(target), width=480, height=360, title=title,
                   field_name=field_name or "", range=shown_range)
    return str(target)


def _done_before(path: pathlib.Path, report_path: pathlib.Path, name: str, options, output_format,
                 picture) -> dict | None:
    """The earlier report of a file that needs no re-run, or None."""
    try:
        row = json.loads(report_path.read_text(encoding="utf-8"))
        if (row.get("status") == "ok"
                and row.get("fingerprint") == _fingerprint(path, name, options, output_format, picture)
                and all(row.get(k) is None or pathlib.Path(row[k]).exists() for k in ("output", "picture"))):
            row["status"] = "skipped"
            return row
    except (OSError, ValueError, TypeError, AttributeError):
        pass
    return None


class BatchResult(list):
    """The table of a batch: one row (a dict) per input file, in the order given.

    Columns: input, status ("ok", "failed" or "skipped": done by an earlier run),
    output (the mesh written, or None), report_file, seconds, worker, error, report
    (the operation's report: the keys of the matching ``meshpde ... --json``).
    """

    @property
    def ok(self) -> list[dict]:
        return [r for r in self if r["status"] == "ok"]

    @property
    def failed(self) -> list[dict]:
        return [r for r in self if r["status"] == "failed"]

    @property
    def skipped(self) -> list[dict]:
        return [r for r in self if r["status"] == "skipped"]

    def summary(self) -> str:
        return f"{len(self)} files: {len(self.ok)} ok, {len(self.failed)} failed, {len(self.skipped)} skipped"

    def to_csv(self, path) -> None:
        """One line a file; the report's scalar values as report.KEY columns."""
        keys = ["input", "status", "output", "seconds", "worker", "error", "note"]
        keys += ["picture"] if any(r.get("picture") for r in self) else []
        extra = sorted({k for r in self for k, v in r.get("report", {}).items() if not isinstance(v, (dict, list))})
        path = pathlib.Path(path)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            w.writerow(keys + [f"report.{k}" for k in extra])
            for r in self:
                w.writerow([r.get(k) for k in keys] + [r.get("report", {}).get(k) for k in extra])
        os.replace(tmp, path)


def _check_inputs(files: Sequence, output_dir: pathlib.Path) -> list[pathlib.Path]:
    paths = [pathlib.Path(os.path.abspath(f)) for f in files]
    by_stem: dict[str, pathlib.Path] = {}
    # (A file that is not a mesh, or a folder, is a failed row of its own, not a bad
    # argument: the rest of the run goes on.)
    for p in paths:
        if p.stem in by_stem and by_stem[p.stem] != p:
            raise meshpde.InputError(f"meshpde.batch: {by_stem[p.stem]} and {p} would both write "
                                     f"{output_dir / p.stem}.*; give files with distinct names")
        by_stem[p.stem] = p
    return paths


def run(operation, files: Sequence, output_dir, *, options: Mapping[str, Any] | Callable[[pathlib.Path], Mapping]
        | None = None, client=None, scheduler: str | None = None, workers: int = 2, threads_per_worker: int = 1,
        output_format: str | None = None, picture: bool = False, resume: bool = True,
        progress: bool = True) -> BatchResult:
    """Runs ``operation`` on every file of ``files`` on a Dask cluster; returns the table.

    operation: the name of a meshpde function (see ``OPERATIONS``: "fair", "correct",
    "interpolate", "curvature", "heat", "wave", "info", ...) or a callable
    ``f(V, F, **options)`` returning an :class:`Output` or any meshpde result
    (importable on the workers: a module's function, or a closure cloudpickle ships).
    options: the operation's keyword arguments, the same for every file, or a callable
    ``options(path) -> dict`` for per-file ones (handles read from a table, say).
    output_dir: created if missing; each input writes ``STEM.EXT`` (its own format,
    or ``output_format``; ``.ply`` when the output has vertex fields its format would
    drop) and ``STEM.json``, and the run writes ``batch.json`` and ``batch.csv``.
    picture: also render each output to ``STEM.png``, coloured by its first field.
    client: a ``distributed.Client`` to use; or scheduler: its address
    ("tcp://host:8786"); neither: a LocalCluster of ``workers`` processes, each with
    ``threads_per_worker`` threads, closed at the end.
    resume: skip files an earlier run did (report "ok" with the same fingerprint).
    progress: a line on stderr as each file ends.
    """
    # Absolute paths: a worker's working directory is not the caller's.
    output_dir = pathlib.Path(os.path.abspath(output_dir))
    paths = _check_inputs(files, output_dir)
    name, _ = _resolve(operation)  # an unknown name fails here, before any task
    output_dir.mkdir(parents=True, exist_ok=True)
    per_file = {p: dict((options(p) if callable(options) else options) or {}) for p in paths}

    rows: dict[pathlib.Path, dict] = {}
    todo = []
    for p in paths:
        earlier = (_done_before(p, _targets(p, output_dir)[1], name, per_file[p], output_format, picture)
                   if resume else None)
        if earlier is not None:
            rows[p] = earlier
        elif not p.exists():  # no task needed to say so
            rows[p] = {"input": str(p), "status": "failed", "output": None, "report_file": None, "seconds": 0.0,
                       "worker": None, "error": f"FileNotFoundError: {p}: no such file", "report": {}}
        else:
            todo.append(p)

    start = time.perf_counter()
    if todo:
        with _client(client, scheduler, workers, threads_per_worker, progress) as c:
            _run_tasks(c, operation, todo, output_dir, per_file, dict(output_format=output_format, picture=picture),
                       rows, len(paths) - len(todo), len(paths), progress, start)

    table = BatchResult(rows[p] for p in paths)
    _write_json(output_dir / "batch.json", list(table))
    table.to_csv(output_dir / "batch.csv")
    if progress:
        print(f"meshpde.batch: {name}: {table.summary()} in {time.perf_counter() - start:.1f} s; "
              f"table {output_dir / 'batch.csv'}", file=sys.stderr)
    return table


@contextlib.contextmanager
def _client(client, scheduler, workers, threads_per_worker, progress):
    if client is not None:
        yield client
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError as e:
        raise ImportError("meshpde.batch.run needs dask.distributed: apt-get install python3-distributed "
                          "(or run meshpde.batch.process on each file)") from e
    if scheduler:
        with Client(scheduler) as c:
            if progress:
                print(f"meshpde.batch: scheduler {scheduler}, {len(c.scheduler_info()['workers'])} workers",
                      file=sys.stderr)
            yield c
        return
    if workers < 1 or threads_per_worker < 1:
        raise meshpde.InputError("meshpde.batch: workers and threads_per_worker must be at least 1")
    with LocalCluster(n_workers=workers, threads_per_worker=threads_per_worker, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as c:
        if progress:
            print(f"meshpde.batch: local cluster of {workers} worker processes", file=sys.stderr)
        yield c


def _run_tasks(client, operation, todo, output_dir, per_file, writing, rows, done, total, progress, start):
    from distributed import as_completed

    def submit(p):
        # A fresh key a submission: a re-run of the same file is new work, not a cached result.
        return client.submit(process, operation, str(p), str(output_dir), per_file[p], **writing,
                             key=f"meshpde-batch-{p.name}-{uuid.uuid4().hex[:12]}")

    failed = 0

    def finished(p, row):
        nonlocal done, failed
        rows[p] = row
        done += 1
        failed += row["status"] == "failed"
        if progress:
            line = f"meshpde.batch: {done}/{total} {p.name}: {row['status']}"
            if row["status"] == "failed":
                line += f" ({row['error']})"
            print(f"{line}  [{failed} failed, {time.perf_counter() - start:.1f} s]", file=sys.stderr)

    futures = {submit(p): p for p in todo}
    died = []
    for f in as_completed(futures):
        try:
            finished(futures[f], f.result())
        except Exception:  # process() catches every error: the task's worker died (KilledWorker)
            died.append(futures[f])
    # A dying worker takes the files queued on it down with the one that killed it, and
    # dask gives up on a file after a few deaths: run each such file again on its own,
    # so that only a file that kills its worker by itself is reported failed.
    for p in died:
        if progress:
            print(f"meshpde.batch: {p.name}: its worker died; running it again on its own", file=sys.stderr)
        try:
            finished(p, submit(p).result())
        except Exception as e:
            finished(p, {"input": str(p), "status": "failed", "output": None, "report_file": None, "seconds": None,
                         "worker": None, "error": f"{type(e).__name__}: {e}", "report": {}})


def main(argv: Sequence[str] | None = None) -> int:
    """``python3 -m meshpde.batch OPERATION OUTDIR FILE... [--options JSON] [--scheduler ADDR]``."""
    ap = argparse.ArgumentParser(prog="python3 -m meshpde.batch",
                                 description="Runs one meshpde operation over many mesh files on a Dask cluster.")
    ap.add_argument("operation", choices=sorted(OPERATIONS))
    ap.add_argument("output_dir")
    ap.add_argument("files", nargs="+")
    ap.add_argument("--options", default="{}", help="the operation's keyword arguments as a JSON object")
    ap.add_argument("--scheduler", help="a dask scheduler's address (default: a local cluster)")
    ap.add_argument("--workers", type=int, default=2, help="local cluster: worker processes (default 2)")
    ap.add_argument("--threads-per-worker", type=int, default=1, help="local cluster: threads each (default 1)")
    ap.add_argument("--format", dest="output_format", help="output mesh format, e.g. .vtp (default: the input's)")
    ap.add_argument("--pictures", action="store_true", help="render each output to STEM.png")
    ap.add_argument("--no-resume", action="store_true", help="redo files an earlier run finished")
    args = ap.parse_intermixed_args(argv)
    try:
        options = json.loads(args.options)
        if not isinstance(options, dict):
            raise ValueError("not an object")
    except ValueError as e:
        print(f"meshpde.batch: --options: expected a JSON object ({e})", file=sys.stderr)
        return 2
    try:
        table = run(args.operation, args.files, args.output_dir, options=options, scheduler=args.scheduler,
                    workers=args.workers, threads_per_worker=args.threads_per_worker,
                    output_format=args.output_format, picture=args.pictures, resume=not args.no_resume)
    except meshpde.InputError as e:
        print(e, file=sys.stderr)
        return 2
    return 1 if table.failed else 0


if __name__ == "__main__":
    # Through the package's module, so that the workers unpickle meshpde.batch.process.
    from meshpde import batch as _batch

    sys.exit(_batch.main())
