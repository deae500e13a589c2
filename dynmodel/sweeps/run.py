"""``dynmodel sweep``: validate everything, check the output folder and the data, then run the points
through an executor, recording each result as it finishes, and write the tables and the figure.

Order of the checks (each failure is one line and exit 2, before anything is written or fitted):
spec, grid keys and values, every point's spec, the output folder, the executor (scheduler reachable,
dask installed), the data of every point (loaded once per distinct data section, preprocessing fitted).
"""

from __future__ import annotations

import copy
import json
import time
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Literal

from .. import __version__
from ..batch import ModelArrays, PointResult, Variant, cached_dataset, data_key, run_specs
from ..errors import DynmodelError, SpecError
from ..family import Progress, no_progress
from ..paths import write_text
from ..spec import Spec, load_spec, parse_yaml, validate_spec
from .folder import SweepFolder
from .grid import Grid, Point, build_points, identity, load_grid, parse_grid
from .results import SweepResult, choose_sort, score

Keep = Literal["best", "all", "none"]
#: seconds between rewrites of results.csv / results.json while a sweep runs
RESULTS_INTERVAL = 10.0


@dataclass
class Plan:
    """A validated sweep: the base spec (mapping and folder), the grid and its points."""

    name: str
    source: str
    base_dir: Path
    base_raw: dict[str, Any]
    grid: Grid
    points: list[Point]
    identity: str
    metrics: list[str]
    stochastic: bool


def plan(spec: Spec | Mapping[str, Any] | str | Path, grid: Any) -> Plan:
    """Validate a spec (path, mapping or loaded spec) and a grid (path or mapping) into a Plan;
    SpecError (one line) on the first problem."""
    if isinstance(spec, (str, Path)):
        path = Path(spec)
        loaded = load_spec(path)  # the spec's own errors, against the spec file
        raw = parse_yaml(path.read_text(encoding="utf-8"), str(path))
        raw.setdefault("name", path.stem)
        source, base_dir = str(path), path.resolve().parent
    elif isinstance(spec, Mapping):
        raw = copy.deepcopy(dict(spec))
        source, base_dir = "<spec>", Path.cwd()
        loaded = validate_spec(raw, source, base_dir)
    elif isinstance(spec, Spec):
        loaded = spec
        raw = spec.resolved()
        source, base_dir = spec.source, spec.base_dir
    else:
        raise TypeError("spec must be a path, a mapping or a loaded spec (dynmodel.load_spec)")
    the_grid = load_grid(grid) if isinstance(grid, (str, Path)) else parse_grid(grid, "<grid>")
    points = build_points(raw, base_dir, the_grid, loaded.name)
    from .. import registry
    from ..search import AUTO

    families = {p.raw["model"]["family"] for p in points}
    # family auto draws its random candidates' seeds from the spec's seed
    stochastic = any(f == AUTO or getattr(registry.family(f), "stochastic", True) for f in families)
    return Plan(
        loaded.name,
        source,
        base_dir,
        raw,
        the_grid,
        points,
        identity(points),
        list(loaded.evaluation.metrics),
        stochastic,
    )


def check_data(the_plan: Plan, points: list[Point], keep_loaded: bool, progress: Progress = no_progress) -> None:
    """Load the data of every point (once per distinct data section, one at a time) and fit its
    preprocessing, so that a missing file or column fails in one line before any fit. ``keep_loaded``:
    leave the recordings in this process's cache (in-process runs reuse them)."""
    from .. import engine
    from ..data import load_dataset

    groups: dict[str, list[Any]] = {}
    for p in points:
        spec = validate_spec(p.raw, f"{the_plan.grid.source}: point {p.key} ({p.label()})", the_plan.base_dir)
        groups.setdefault(data_key(spec), []).append((p, spec))
    for members in groups.values():
        first, spec = members[0]
        progress("data", None, f"checking the data of {first.key}")
        ds = cached_dataset(spec)[0] if keep_loaded else load_dataset(spec)
        seen: set[str] = set()
        for _, spec in members:
            pre = json.dumps(spec.resolved()["data"], sort_keys=True, default=str)
            if pre not in seen:
                engine.preprocessor(spec, ds)
                seen.add(pre)


def data_files(points: list[Point]) -> dict[str, str]:
    """SHA-256 of every data file the points read (path -> hex digest): the identity covers the specs, not the
    files' contents, so a resume compares these to know its finished points were scored on the same data."""
    import hashlib

    from ..paths import spec_inputs

    files: set[Path] = set()
    for p in points:
        try:
            spec = validate_spec(p.raw, "<point>", Path.cwd())
        except DynmodelError:
            continue  # the data check names it
        files.update(spec_inputs(spec).get("data file", []))
    out = {}
    for f in sorted(files):
        if f.is_file():
            h = hashlib.sha256()
            with open(f, "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):
                    h.update(block)
            out[str(f)] = h.hexdigest()
    return out


def _manifest(the_plan: Plan, created: str, data: dict[str, str] | None = None) -> dict[str, Any]:
    return {
        "identity": the_plan.identity,
        "data_sha256": data or {},
        "name": the_plan.name,
        "spec": the_plan.source,
        "grid": the_plan.grid.source,
        "keys": the_plan.grid.keys,
        "n_points": len(the_plan.points),
        "seeds": "swept (as given)"
        if the_plan.grid.sweeps_seed
        else "derived: SeedSequence([spec seed, sha256(values)])",
        "created": created,
        "dynmodel_version": __version__,
        "grid_axes": the_plan.grid.to_json()["axes"],
        "points": [{"key": p.key, "values": p.values, "seed": p.seed} for p in the_plan.points],
    }


class _Recorder:
    """Turns point results into records, keeps models as asked, writes files as results arrive."""

    def __init__(self, the_plan: Plan, folder: SweepFolder | None, keep: Keep, records: dict[str, dict[str, Any]]):
        self.plan = the_plan
        self.points = {p.key: p for p in the_plan.points}
        self.folder = folder
        self.keep = keep
        self.records = records
        self.models: dict[str, ModelArrays] = {}
        self.warnings: dict[str, int] = {}
        self._last_write = 0.0
        self._unwritten: set[str] = set()  # records counted whose point file is not written yet
        self.sort_key = choose_sort(list(records.values()), the_plan.metrics)
        self.best_key = self._rank_best()

    def _rank_best(self) -> str | None:
        ranked = sorted((score(r, self.sort_key), r["key"]) for r in self.records.values() if r.get("status") == "ok")
        ranked = [x for x in ranked if x[0] == x[0]]  # drop NaN
        return ranked[0][1] if ranked else None

    def _beats_best(self, record: dict[str, Any]) -> bool:
        new = score(record, self.sort_key)
        if new != new:  # NaN
            return False
        if self.best_key is None:
            return True
        return (new, record["key"]) < (score(self.records[self.best_key], self.sort_key), self.best_key)

    def add(self, result: PointResult, run_id: str) -> None:
        point = self.points[result.key]
        record = result.to_json()
        record.update(values=point.values, finished=_now(), run=run_id, model=None)
        for text in result.warnings:
            self.warnings[text] = self.warnings.get(text, 0) + 1
        self.records[result.key] = record
        self._unwritten.add(result.key)
        if result.status == "ok" and "validation" not in record["metrics"] and not self.sort_key.note:
            self.sort_key = choose_sort(list(self.records.values()), self.plan.metrics)  # falls back to train
            self.best_key = self._rank_best()
        better = result.status == "ok" and self._beats_best(record)
        if result.model is not None and self.keep == "all":
            record["model"] = self._store(result.key, result.model)
        elif result.model is not None and self.keep == "best" and better:
            record["model"] = self._store(result.key, result.model)
        if better:
            previous, self.best_key = self.best_key, result.key
            if self.keep == "best" and previous and previous != result.key:
                self._drop(previous)
        if self.folder is not None:
            self.folder.write_record(record)
        self._unwritten.discard(result.key)

    def _store(self, key: str, payload: ModelArrays) -> str | None:
        if self.folder is None:
            self.models[key] = payload
            return None
        from .. import store

        path = self.folder.model_path(key)
        model = payload.to_model()
        model.spec["output"] = str(path)
        store.save(model, path)
        return str(path.relative_to(self.folder.path))

    def _drop(self, key: str) -> None:
        self.models.pop(key, None)
        record = self.records.get(key)
        if self.folder is None or record is None or not record.get("model"):
            return
        path = self.folder.model_path(key)
        if path.exists():
            path.unlink()
        record["model"] = None
        self.folder.write_record(record)

    def result(self) -> SweepResult:
        res = SweepResult(
            self.plan.grid.keys,
            self.plan.points,
            dict(self.records),
            self.sort_key,
            self.folder.path if self.folder else None,
        )
        if self.sort_key.note:
            res.notes.append(self.sort_key.note)
        return res

    def write(self, force: bool = False) -> None:
        """Rewrite results.csv / results.json (at most every RESULTS_INTERVAL seconds unless forced); forced, first
        the point file of every record counted but not yet written (a Ctrl-C or SIGTERM between the two: the
        summary said "2 of 6 points finished" over one point file, and --resume would fit the other again)."""
        if force and self.folder is not None:
            for key in sorted(self._unwritten):
                self.folder.write_record(self.records[key])
            self._unwritten.clear()
        now = time.monotonic()
        if self.folder is not None and (force or now - self._last_write >= RESULTS_INTERVAL):
            res = self.result()
            write_text(self.folder.path / "results.csv", res.to_csv())
            write_text(self.folder.path / "results.json", json.dumps(res.to_json(), indent=1, default=str) + "\n")
            self._last_write = now


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def sweep(
    spec: Any,
    grid: Any,
    executor: Any = None,
    *,
    out: str | Path | None = None,
    keep: Keep = "best",
    resume: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Progress | None = None,
    cancel: Callable[[], bool] | Any = None,
) -> SweepResult:
    """Fit ``spec`` at every point of ``grid`` and return the results table.

    ``spec``: a YAML path, a spec mapping or a loaded spec; ``grid``: a YAML path or a mapping of
    dotted keys to value lists. ``executor``: a ``concurrent.futures.Executor`` (kept running), or
    None to make one from ``workers`` / ``scheduler`` (default: one local worker process per core).
    ``out``: a folder for results.csv/json, the figure, point results (``resume`` continues it) and
    kept models; None keeps everything in memory (``result.best_model`` with ``keep='best'``).
    KeyboardInterrupt (Ctrl-C) stops the workers and keeps every finished point (in ``out``)."""
    from ..executors import InProcessExecutor, make_executor

    if keep not in ("best", "all", "none"):
        raise SpecError(f"--keep {keep} is not best, all or none", "--keep", "use --keep best (default), all or none")
    if executor is not None and (workers is not None or scheduler):
        raise SpecError("give an executor or workers/scheduler, not both", "sweep()", "pass one of them")
    progress = progress or no_progress
    the_plan = plan(spec, grid)
    folder = SweepFolder(out) if out is not None else None
    if folder is not None and not folder.path.is_file():  # (a file is refused by folder.check)
        from ..paths import check_output

        # a folder in which no file can be created (permissions, a read-only mount) fails now, in one line,
        # before the data are read; whether an existing folder may be used is the folder check's business
        check_output(folder.path, "report", force=True, option="--out")
    data = data_files(the_plan.points) if folder else {}
    done = folder.check(the_plan.identity, resume, len(the_plan.points), data) if folder else {}
    todo = [p for p in the_plan.points if p.key not in done]
    own = executor is None and bool(todo)
    if own:  # before the data check: an unreachable scheduler fails at once
        if not scheduler and workers is None:
            from ..executors import available_cores

            workers = min(available_cores(), len(todo))
        executor = make_executor(workers, scheduler)
    try:
        if todo:
            check_data(the_plan, todo, keep_loaded=isinstance(executor, InProcessExecutor), progress=progress)
    except BaseException:
        if own:
            executor.shutdown(wait=False)
        raise
    records = folder.records() if folder else {}
    created = _now()
    if folder is not None:
        folder.create(
            _manifest(the_plan, created, data),
            {p.key: {**p.raw, "output": str(folder.model_path(p.key))} for p in the_plan.points},
        )
    recorder = _Recorder(the_plan, folder, keep, records)
    run_id = uuid.uuid4().hex[:12]
    t0 = time.monotonic()
    variants = [Variant(p.key, p.raw, str(the_plan.base_dir), f"{the_plan.source} [{p.key}]") for p in todo]
    counts = {"ok": 0, "diverged": 0, "error": 0}
    interrupted = clean = False
    results = None
    first = 0.0
    where = describe_safe(executor) if todo else None
    try:
        if todo:
            progress("sweep", 0.0, f"{len(todo)} point(s) on {where}" + (f", {len(done)} done earlier" if done else ""))
            results = run_specs(variants, executor, keep_models=keep != "none", cancel=cancel)
            for i, res in enumerate(results, 1):
                recorder.add(res, run_id)
                counts[res.status] += 1
                recorder.write()
                best = recorder.best_key
                col = recorder.sort_key.column
                best_text = ""
                if best is not None:
                    value = ((recorder.records[best]["metrics"].get(recorder.sort_key.split)) or {}).get(
                        recorder.sort_key.metric
                    )
                    best_text = f"; best {col} {value:.4g} ({best})" if value is not None else ""
                now = time.monotonic()
                first = first or now  # the first point also waited for the workers to start
                eta = f", about {(now - first) / (i - 1) * (len(todo) - i):.0f} s left" if i > 1 else ""
                progress(
                    "sweep",
                    i / len(todo),
                    f"{i}/{len(todo)} points ({counts['ok']} ok, {counts['diverged']} diverged, "
                    f"{counts['error']} errors){best_text}; {now - t0:.0f} s{eta}",
                )
        clean = True
    except KeyboardInterrupt:
        interrupted = True
    finally:
        if results is not None:
            results.close()
        if own and executor is not None:
            executor.shutdown(wait=clean, cancel_futures=True)  # else stop running fits at once
        recorder.write(force=True)
        result = recorder.result()
        result.info.update(
            name=the_plan.name,
            spec=the_plan.source,
            grid=the_plan.grid.source,
            executor=where,
            seconds=time.monotonic() - t0,
            ran=sum(counts.values()),
            resumed=len(done),
            interrupted=interrupted,
            warnings=recorder.warnings,
            stochastic=the_plan.stochastic,
        )
        if folder is not None:
            from .plot import metric_vs_values

            figure = metric_vs_values(folder.path / "sweep.png", result, f"{the_plan.name}: {result.sort_key.column}")
            result.info["figure"] = None if figure is None else str(figure)
    if folder is None and recorder.best_key in recorder.models:
        result.best_model = recorder.models[recorder.best_key].to_model()
    result.models = recorder.models
    if interrupted:
        raise SweepInterrupted(result)
    return result


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep: ``result`` holds the points finished so far (also kept in the folder)."""

    def __init__(self, result: SweepResult):
        super().__init__("sweep interrupted")
        self.result = result


def default_out(spec_path: str | Path) -> Path:
    """``<name>-sweep`` next to the spec file."""
    path = Path(spec_path)
    return path.resolve().parent / f"{load_spec(path).name}-sweep"


def describe_safe(executor: Any) -> str | None:
    from ..executors import describe

    try:
        return describe(executor)
    except Exception:
        return None
