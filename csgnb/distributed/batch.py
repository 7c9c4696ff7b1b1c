"""Batches of milling jobs on Dask: each job simulated on a worker, its report, STL and workpiece written here.

>>> from csgnb.distributed import MillingJob
>>> job = MillingJob.example("pocket.nc", resolution=1.0)
>>> job.stock, job.tools
((50.0, 40.0, 10.0), ('flat:6',))

A :class:`MillingJob` is what ``python -m csgnb.mill`` takes -- the G-code text, the stock, tool
specs (:func:`csgnb.apps.tools.parse_tool`), the grid step -- as plain data, so it travels to a
worker as a few strings and floats. :func:`run_job` runs one job in this process;
:func:`run_batch` runs many on a Dask cluster (:func:`csgnb.distributed.cluster.connect`: an
embedded ``LocalCluster`` by default, or a scheduler address) with a ``tqdm`` bar, and returns one
:class:`JobResult` per job, in the order given.

What travels back from a worker is plain data too: exact volumes as text
(:func:`csgnb.exact.rational.fraction_text`), the STL file and the saved workpiece as bytes. The
client writes them under ``out_dir/<job name>/`` (``part.stl``, ``part.wp``, ``report.json``), so
workers need no shared file system. ``report.json`` carries the job's :attr:`MillingJob.digest`
(SHA-256 over every input and the csgnb version) and the SHA-256 of both files: a re-run skips a
job whose report has the same digest and whose files are intact, and redoes the others.

Failures: a job whose input is wrong (unparsable G-code, a tool off the grid, a stock that does
not fit) comes back as a result with ``error`` set, and the others go on; nothing about such an
error changes on a second try. A worker that dies (killed, out of memory) loses its task: the
scheduler gives it to another worker, up to Dask's ``distributed.scheduler.allowed-failures``
times; any other exception raised by a task is retried ``retries`` times (a flaky file system,
say) before it is reported.
"""

from __future__ import annotations

import hashlib
import json
import re
import tempfile
import time
import traceback
from dataclasses import asdict, dataclass, field, fields
from fractions import Fraction
from pathlib import Path

import numpy as np

import csgnb
from csgnb._files import write_atomic
from csgnb.apps.milling import CHORD_TOLERANCE, RAPID_RATE
from csgnb.errors import CsgnbError
from csgnb.exact.rational import fraction_text, parse_fraction

__all__ = ["JobResult", "MillingJob", "load_jobs", "run_batch", "run_job", "run_job_data"]

REPORT_FORMAT = 1
"""Version of ``report.json`` (part of every job's digest)."""

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,99}$")

#: Errors that come from the job's input: reported at once, never retried.
INPUT_ERRORS = (CsgnbError, ValueError, KeyError, TypeError, UnicodeDecodeError)


def _triple(name: str, value, positive: bool = False) -> tuple[float, float, float]:
    try:
        t = tuple(float(v) for v in value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be three numbers (mm), got {value!r}") from exc
    if len(t) != 3 or not all(np.isfinite(t)):
        raise ValueError(f"{name} must be three finite numbers (mm), got {value!r}")
    if positive and min(t) <= 0:
        raise ValueError(f"{name} sizes must be positive, got {list(t)}")
    return t


@dataclass(frozen=True)
class MillingJob:
    """One simulation, as ``python -m csgnb.mill`` runs it, in plain data.

    Attributes
    ----------
    name : str
        Folder name of the job's outputs (letters, digits, ``_ . -``; unique in a batch).
    program : str
        The G-code text (:meth:`from_file` and :meth:`example` read it).
    stock : (3,) float
        Stock size in mm: the box ``[0, X] x [0, Y] x [-Z, 0]``, or from ``stock_origin``.
    tools : tuple of str
        Tool specs as ``--tool`` takes them: ``"flat:6"`` for every move, ``"2=ball:3"`` for tool 2.
    stock_origin : (3,) float or None
        Lower corner of the stock (default ``(0, 0, -Z)``).
    resolution : float or None
        Grid step in mm (default: fitted, the finest in the 128-bit budget).
    segments, chord_tolerance, rapid_rate, start, skip_unsupported
        As the options of ``python -m csgnb.mill``.
    """

    name: str
    program: str
    stock: tuple[float, float, float]
    tools: tuple[str, ...] = ("flat:6",)
    stock_origin: tuple[float, float, float] | None = None
    resolution: float | None = None
    segments: int = 32
    chord_tolerance: float = CHORD_TOLERANCE
    rapid_rate: float = RAPID_RATE
    start: tuple[float, float, float] | None = None
    skip_unsupported: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise ValueError(f"job name {self.name!r}: use 1-100 letters, digits, '_', '.' or '-' "
                             "(it names the job's output folder)")
        if not isinstance(self.program, str):
            raise TypeError(f"job {self.name}: program is the G-code text, got {type(self.program).__name__} "
                            "(MillingJob.from_file reads a file)")
        set_ = object.__setattr__  # frozen: normalise once, here
        set_(self, "stock", _triple(f"job {self.name}: stock", self.stock, positive=True))
        if self.stock_origin is not None:
            set_(self, "stock_origin", _triple(f"job {self.name}: stock_origin", self.stock_origin))
        if self.start is not None:
            set_(self, "start", _triple(f"job {self.name}: start", self.start))
        tools = (self.tools,) if isinstance(self.tools, str) else tuple(self.tools)
        if not tools or not all(isinstance(t, str) and t.strip() for t in tools):
            raise ValueError(f"job {self.name}: tools must be tool specs such as 'flat:6' or '2=ball:3', "
                             f"got {self.tools!r}")
        set_(self, "tools", tools)
        if self.resolution is not None and not (np.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"job {self.name}: resolution must be a positive number of mm, got {self.resolution!r}")

    @classmethod
    def from_file(cls, path, *, name: str | None = None, **kw) -> MillingJob:
        """A job for the G-code file at ``path`` (or a shipped example's name); ``name`` defaults to its stem."""
        from csgnb.apps.examples import EXAMPLES, example_path

        p = Path(path)
        if not p.exists() and p.name == str(path) and p.name in EXAMPLES:
            p = example_path(p.name)
        return cls(name=p.stem if name is None else name, program=p.read_text(encoding="utf-8"), **kw)

    @classmethod
    def example(cls, program: str, **kw) -> MillingJob:
        """A shipped program (``"pocket.nc"``, ``"relief.nc"``) with its stock, tool and segments; ``kw`` override."""
        from csgnb.apps.examples import EXAMPLES, example_path

        ex = EXAMPLES[example_path(program).name]
        kw = dict(dict(stock=ex.stock, tools=(ex.tool,)), **({"segments": ex.segments} if ex.segments else {}), **kw)
        return cls.from_file(ex.path, **kw)

    def as_dict(self) -> dict:
        """The job as JSON-ready plain data (tuples as lists)."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: dict) -> MillingJob:
        """The job of :meth:`as_dict` (or of a ``[[job]]`` table of a batch file); unknown keys are refused."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"job {data.get('name', '?')}: unknown key(s) {unknown}; a job takes {sorted(known)}")
        return cls(**data)

    @property
    def digest(self) -> str:
        """SHA-256 (hex) over every input of the job, the csgnb version and the report format."""
        blob = json.dumps({"job": self.as_dict(), "csgnb": csgnb.__version__, "format": REPORT_FORMAT},
                          sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(blob.encode()).hexdigest()


@dataclass
class JobResult:
    """What a job produced (volumes in mm³, exact), or why it failed (``error``); pandas-free plain fields.

    ``skipped``: the outputs of an earlier run with the same digest were kept. ``stl_sha256`` and
    ``workpiece_sha256`` identify the files; ``removed_per_move`` holds each move's exact removal.
    """

    name: str
    digest: str
    error: str | None = None
    skipped: bool = False
    moves: int = 0
    stock_volume: Fraction | None = None
    removed: Fraction | None = None
    part_volume: Fraction | None = None
    removed_per_move: list[Fraction] = field(default_factory=list)
    collisions: list[str] = field(default_factory=list)
    cut_time_s: float = 0.0
    wall_s: float = 0.0
    grid_resolution: float | None = None
    stl: dict | None = None
    stl_path: Path | None = None
    workpiece_path: Path | None = None
    report_path: Path | None = None
    stl_sha256: str | None = None
    workpiece_sha256: str | None = None
    worker: str | None = None

    @property
    def ok(self) -> bool:
        """The job ran to the end (collisions are results, not failures)."""
        return self.error is None

    def report(self) -> dict:
        """The JSON-ready report (exact volumes as text, paths as file names)."""
        d = asdict(self)
        for k in ("stock_volume", "removed", "part_volume"):
            d[k] = None if d[k] is None else fraction_text(d[k])
        d["removed_per_move"] = [fraction_text(v) for v in self.removed_per_move]
        for k in ("stl_path", "workpiece_path", "report_path"):
            d[k] = None if d[k] is None else Path(d[k]).name
        d["format"] = REPORT_FORMAT
        return d

    @classmethod
    def from_report(cls, data: dict, folder: Path | None = None) -> JobResult:
        """The result of :meth:`report` (or of the plain data a worker sends), paths under ``folder``."""
        d = {k: v for k, v in data.items() if k in {f.name for f in fields(cls)}}
        for k in ("stock_volume", "removed", "part_volume"):
            d[k] = None if d.get(k) is None else parse_fraction(d[k])
        d["removed_per_move"] = [parse_fraction(v) for v in d.get("removed_per_move", [])]
        for k in ("stl_path", "workpiece_path", "report_path"):
            d[k] = None if d.get(k) is None or folder is None else folder / d[k]
        return cls(**d)

    def summary(self) -> str:
        """One line: the job, and its exact volumes or its error."""
        if not self.ok:
            return f"{self.name}: FAILED: {self.error.splitlines()[0] if self.error else ''}"
        state = "kept" if self.skipped else f"{self.wall_s:.1f} s"
        return (f"{self.name}: {self.moves} moves, removed {float(self.removed):.6g} mm³, part "
                f"{float(self.part_volume):.6g} mm³, {len(self.collisions)} collisions ({state})")


def load_jobs(path) -> tuple[list[MillingJob], Path]:
    """The jobs of a batch file (TOML) and its output folder.

    ::

        out_dir = "pocket-study"      # optional, relative to this file (default: <file stem>-out beside it)
        [defaults]                    # optional: keys every job takes unless it sets them
        resolution = 1.0
        [[job]]
        name = "flat6"
        program = "pocket.nc"         # a G-code file relative to this file, or a shipped example
        tools = ["flat:6"]            # stock and tools default to a shipped example's own
        [[job]]
        name = "flat6-fast"
        program = "parts/pocket_fast.nc"
        stock = [50, 40, 10]

    Keys of a job: the fields of :class:`MillingJob`, with ``program`` a file name instead of the text.
    """
    import tomllib

    from csgnb.apps.examples import EXAMPLES

    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML: {exc}") from exc
    unknown = sorted(set(doc) - {"out_dir", "defaults", "job"})
    if unknown:
        raise ValueError(f"{path}: unknown top-level key(s) {unknown}; a batch file has out_dir, [defaults], [[job]]")
    tables = doc.get("job")
    if not isinstance(tables, list) or not tables:
        raise ValueError(f"{path}: no jobs; write one [[job]] table per job")
    defaults = doc.get("defaults", {})
    if not isinstance(defaults, dict):
        raise ValueError(f"{path}: [defaults] must be a table")
    jobs = []
    for k, table in enumerate(tables, 1):
        spec = dict(defaults, **table)
        extra = sorted(set(spec) - {f.name for f in fields(MillingJob)})
        if extra:
            raise ValueError(f"{path}: job {k}: unknown key(s) {extra}; a job takes "
                             f"{sorted(f.name for f in fields(MillingJob))}")
        program = spec.pop("program", None)
        if not isinstance(program, str):
            raise ValueError(f"{path}: job {k} ({spec.get('name', 'no name')}) needs program = \"FILE.nc\"")
        file = path.parent / program
        if not file.exists() and program in EXAMPLES:
            jobs.append(MillingJob.example(program, **spec))
        elif not file.exists():
            raise ValueError(f"{path}: job {k}: no G-code file {file} (and {program!r} is not a shipped example: "
                             f"{sorted(EXAMPLES)})")
        else:
            jobs.append(MillingJob.from_dict(dict(spec, program=file.read_text(encoding="utf-8"),
                                                  name=spec.get("name", file.stem))))
    out_dir = doc.get("out_dir", f"{path.stem}-out")
    return _check_jobs(jobs), path.parent / out_dir


# -- one job, in any process ------------------------------------------------------


def _simulate(job: MillingJob):
    """Set up stock, grid and tools exactly as ``python -m csgnb.mill`` does (:func:`csgnb.mill.prepare`, one
    code path for both), and simulate; return the MillingResult."""
    from csgnb import mill
    from csgnb.apps import milling

    argv = [f"{job.name}.nc", "--stock", *map(str, job.stock), "--segments", str(job.segments),
            "--chord-tolerance", repr(job.chord_tolerance), "--rapid-rate", repr(job.rapid_rate)]
    for spec in job.tools:
        argv += ["--tool", spec]
    if job.stock_origin is not None:
        argv += ["--stock-origin", *map(repr, job.stock_origin)]
    if job.start is not None:
        argv += ["--start", *map(repr, job.start)]
    if job.resolution is not None:
        argv += ["--resolution", repr(job.resolution)]
    if job.skip_unsupported:
        argv.append("--skip-unsupported")
    args = mill.build_parser().parse_args(argv)
    setup = mill.prepare(args, program_text=job.program)
    return milling.simulate(setup.workpiece, setup.program, setup.tools, chord_tolerance=job.chord_tolerance,
                            rapid_rate=job.rapid_rate, progress=False)


def run_job_data(job: dict) -> dict:
    """Run the job of :meth:`MillingJob.as_dict`; return plain data: the report fields and the files as bytes.

    This is the Dask task: a plain function of plain data, importing the kernels where it runs.
    Input errors come back as ``{"error": ...}``; anything else is raised (and retried by Dask).
    """
    from csgnb.apps.milling import export_stl

    t0 = time.perf_counter()
    try:
        spec = MillingJob.from_dict(job)
    except INPUT_ERRORS as exc:
        return {"name": str(job.get("name", "?")), "digest": "", "error": _error_text(exc)}
    out = {"name": spec.name, "digest": spec.digest, "worker": _worker_address()}
    try:
        result = _simulate(spec)
        with tempfile.TemporaryDirectory(prefix="csgnb-job-") as tmp:
            stl = export_stl(result.workpiece, Path(tmp) / "part.stl")
            result.workpiece.save(Path(tmp) / "part.wp")
            stl_bytes = (Path(tmp) / "part.stl").read_bytes()
            wp_bytes = (Path(tmp) / "part.wp").read_bytes()
    except INPUT_ERRORS as exc:
        return dict(out, error=_error_text(exc), wall_s=time.perf_counter() - t0)
    except Exception as exc:
        # Raised to Dask (retried, then reported): without the half-milled workpiece simulate attaches,
        # which is no plain data.
        if hasattr(exc, "partial_result"):
            del exc.partial_result
        raise
    stl_report = stl.as_dict()
    stl_report.pop("path")
    return dict(out, moves=len(result.records), stock_volume=fraction_text(result.stock_volume),
                removed=fraction_text(result.removed), part_volume=fraction_text(result.part_volume),
                removed_per_move=[fraction_text(r.removed) for r in result.records],
                collisions=[f"line {r.line}: {r.collision}" for r in result.collisions],
                cut_time_s=result.cut_time_s, wall_s=time.perf_counter() - t0,
                grid_resolution=float(result.workpiece.grid.resolution), stl=stl_report,
                stl_bytes=stl_bytes, workpiece_bytes=wp_bytes, stl_sha256=_sha256(stl_bytes),
                workpiece_sha256=_sha256(wp_bytes))


def _error_text(exc: BaseException) -> str:
    return "".join(traceback.format_exception_only(type(exc), exc)).strip() + "\n" + "".join(
        traceback.format_exception(exc)).strip()


def _worker_address() -> str | None:
    try:
        from distributed import get_worker

        return get_worker().address
    except ValueError:  # not on a Dask worker
        return None


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _store(data: dict, out_dir: Path) -> JobResult:
    """Write a worker's answer under ``out_dir/<name>/`` (files first, the report last); return its result."""
    folder = out_dir / data["name"]
    folder.mkdir(parents=True, exist_ok=True)
    data = dict(data)
    stl_bytes, wp_bytes = data.pop("stl_bytes", None), data.pop("workpiece_bytes", None)
    if stl_bytes is not None:
        write_atomic(folder / "part.stl", stl_bytes)
        write_atomic(folder / "part.wp", wp_bytes)
        data.update(stl_path="part.stl", workpiece_path="part.wp")
    data["report_path"] = "report.json"
    result = JobResult.from_report(data, folder)
    write_atomic(folder / "report.json", json.dumps(result.report(), indent=1).encode())
    return result


def _finished(job: MillingJob, out_dir: Path) -> JobResult | None:
    """The result of an earlier run of ``job`` whose digest and files are intact, else None."""
    folder = out_dir / job.name
    try:
        data = json.loads((folder / "report.json").read_text())
        if data.get("digest") != job.digest or data.get("error") is not None:
            return None
        if (_sha256((folder / "part.stl").read_bytes()) != data.get("stl_sha256")
                or _sha256((folder / "part.wp").read_bytes()) != data.get("workpiece_sha256")):
            return None
        result = JobResult.from_report(data, folder)
    except (OSError, ValueError, TypeError, KeyError):
        return None
    result.skipped = True
    return result


def run_job(job: MillingJob, out_dir=None) -> JobResult:
    """Run ``job`` in this process (no Dask); with ``out_dir`` write its files as :func:`run_batch` does."""
    if not isinstance(job, MillingJob):
        raise TypeError(f"job must be a MillingJob, got {type(job).__name__}")
    data = run_job_data(job.as_dict())
    if out_dir is not None:
        return _store(data, Path(out_dir))
    data.pop("stl_bytes", None)
    data.pop("workpiece_bytes", None)
    return JobResult.from_report(data)


def _check_jobs(jobs) -> list[MillingJob]:
    jobs = list(jobs)
    bad = [type(j).__name__ for j in jobs if not isinstance(j, MillingJob)]
    if bad:
        raise TypeError(f"jobs must be MillingJob objects, got {sorted(set(bad))}")
    seen: set[str] = set()
    for j in jobs:
        if j.name in seen:
            raise ValueError(f"two jobs are named {j.name!r}: a job's name names its output folder")
        seen.add(j.name)
    return jobs


def run_batch(jobs, client=None, out_dir="csgnb-batch", *, scheduler: str | None = None, progress: bool = True,
              retries: int = 1, n_workers: int | None = None) -> list[JobResult]:
    """Run milling ``jobs`` on Dask; return one :class:`JobResult` per job, in order, and write their files.

    Parameters
    ----------
    jobs : iterable of MillingJob
        Names must be unique (each names a folder under ``out_dir``).
    client : distributed.Client, optional
        Use this client's cluster. Default: a new ``LocalCluster`` of one single-threaded worker per
        core (``n_workers`` to choose), closed at the end; or the scheduler at ``scheduler``.
    out_dir : path
        Where ``<name>/part.stl``, ``part.wp`` and ``report.json`` go. A job whose report there has
        its digest and intact files is not run again (``skipped=True``).
    progress : bool
        A ``tqdm.auto`` bar (a widget in a notebook), one step per job.
    retries : int
        Dask retries of a task that raised something other than an input error.
    """
    from distributed import as_completed
    from tqdm.auto import tqdm

    from csgnb.distributed.cluster import close, connect

    jobs = _check_jobs(jobs)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    results: list[JobResult | None] = [_finished(j, out) for j in jobs]
    todo = [i for i, r in enumerate(results) if r is None]
    bar = tqdm(total=len(jobs), initial=len(jobs) - len(todo), disable=not progress, unit="job", desc="milling jobs")
    if not todo:
        bar.close()
        return results
    client, owned = connect(client, scheduler, n_workers)
    try:
        futures = {}
        for i in todo:
            job = jobs[i]
            # The key names the job and its inputs: a resubmitted identical job reuses a running task.
            f = client.submit(run_job_data, job.as_dict(), key=f"csgnb-mill-{job.name}-{job.digest[:16]}",
                              retries=retries, pure=False)
            futures[f] = i
        for f in as_completed(futures):
            i = futures[f]
            try:
                data = f.result()
            except Exception as exc:  # a task that kept failing, or a KilledWorker: reported, the others go on
                data = {"name": jobs[i].name, "digest": jobs[i].digest, "error": _error_text(exc)}
            results[i] = _store(data, out)
            bar.update(1)
            bar.set_postfix_str(results[i].name, refresh=False)
            f.release()
    finally:
        bar.close()
        if owned:
            close(client)
    return results
