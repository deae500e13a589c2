"""Command line: ``dynmodel fit | validate | predict | inspect | reliability-check | diagnose | sweep | control |
plugins | schema | generate``.

Tables go to stdout, progress to stderr, machine output to ``--json FILE``. A user's mistake
gets one line on stderr and exit code 2 (1 when a check ran and failed, e.g. a diverging
free run); ``--debug`` shows tracebacks.
"""

from __future__ import annotations

import functools
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Optional

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from typer.core import TyperGroup

from . import __version__
from .errors import EXIT_INTERNAL, DynmodelError, FreeRunDiverged


class _OneLineErrors(TyperGroup):
    """Usage errors (a missing argument, a bad option value) as one line, like every other error."""

    def main(self, *args: Any, standalone_mode: bool = True, **kwargs: Any) -> Any:
        if not standalone_mode:
            return super().main(*args, standalone_mode=False, **kwargs)
        try:
            rv = super().main(*args, standalone_mode=False, **kwargs)
        except typer.TyperException as exc:  # click's usage errors, vendored by typer
            if type(exc).__name__ == "NoArgsIsHelpError":
                print(exc.format_message())
                sys.exit(0)
            ctx = getattr(exc, "ctx", None)
            where = ctx.command_path if ctx is not None else "dynmodel"
            message = " ".join(exc.format_message().split()).rstrip(".")
            print(f"error: {where}: {message}. Fix: see `{where} --help`", file=sys.stderr)
            sys.exit(getattr(exc, "exit_code", 2))
        except typer.Abort:
            print("error: aborted. Fix: rerun the command", file=sys.stderr)
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)


app = typer.Typer(
    cls=_OneLineErrors,
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Black-box models of driven dynamical systems from measured input/output data.",
)
out = Console(soft_wrap=True, highlight=False)
err = Console(stderr=True, soft_wrap=True, highlight=False)
_state = {"debug": False}


def _version(value: bool) -> None:
    if value:
        print(f"dynmodel {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    debug: bool = typer.Option(False, "--debug", help="show tracebacks for errors"),
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="print the version and exit"
    ),
) -> None:
    _state["debug"] = debug


def handled(fn: Callable) -> Callable:
    """Run a command: expected errors (see dynmodel.explain) become one stderr line and their exit
    code, anything else (a bug) the internal-error line; warnings are shown once, after the
    command succeeded (an error line stands alone)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        import warnings

        from .explain import explain, internal_error_line

        with warnings.catch_warnings(record=True) as caught:  # the default filters stay in force
            try:
                result = fn(*args, **kwargs)
            except (typer.Exit, typer.Abort, SystemExit):
                _show_warnings(caught)
                raise
            except BaseException as exc:  # noqa: BLE001 - the one place that explains failures
                mapped = explain(exc)
                if _state["debug"] and not isinstance(exc, KeyboardInterrupt):
                    raise
                if mapped is None:
                    err.print(internal_error_line(exc), markup=False)
                    raise typer.Exit(EXIT_INTERNAL) from None
                err.print(f"error: {mapped.line()}", markup=False)
                raise typer.Exit(mapped.exit_code) from None
        _show_warnings(caught)
        return result

    return wrapper


def _show_warnings(caught) -> None:
    shown: set[str] = set()
    for w in caught:
        text = " ".join(str(w.message).split())
        if text not in shown:
            shown.add(text)
            err.print(f"warning: {text}", markup=False)


def _fmt(v: Any, digits: int = 4) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def metrics_table(metrics: dict[str, Any], title: str | None = None) -> Table:
    table = Table(title=title, title_justify="left")
    table.add_column("split", min_width=max((len(k) for k in metrics), default=5))
    table.add_column("samples", justify="right")
    shown = [k for k in ("nmse", "max", "rmse", "fit") if k in ("nmse", "max") or any(k in m for m in metrics.values())]
    units = {m.get("rmse_units") for m in metrics.values()}
    rmse = f"RMSE ({units.pop()})" if len(units) == 1 and None not in units else "RMSE"
    for k in shown:
        table.add_column({"nmse": "NMSE %", "max": "MAX", "rmse": rmse, "fit": "fit %"}[k], justify="right")
    has_one = any("nmse_1" in m for m in metrics.values())
    if has_one:
        table.add_column("NMSE one-step %", justify="right")
    for split, m in metrics.items():
        if m.get("unstable_from"):
            u = m["unstable_from"]
            cell = f"unstable from t = {u['time']:.6g} (sample {u['sample']})"
            row = [split, str(m["samples"]), cell] + ["-"] * (len(shown) - 1)
        else:
            row = [split, str(m["samples"])] + [_fmt(m.get(k)) for k in shown]
        if has_one:
            row.append(_fmt(m.get("nmse_1")))
        table.add_row(*row)
    return table


def _write_json(path: Path, payload: dict[str, Any]) -> None:
    from .paths import write_text

    write_text(path, json.dumps(payload, indent=2) + "\n")


# ------------------------------------------------------------------------------ fit
_FORCE = typer.Option(False, "--force", help="replace an existing file that is not a previous output of this kind")


@app.command()
@handled
def fit(
    spec: Path = typer.Argument(..., help="YAML spec"),
    out_path: Optional[Path] = typer.Option(None, "--out", help="model file (overrides the spec's output)"),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write metrics and model path as JSON"),
    plot: Optional[Path] = typer.Option(None, "--plot", help="PNG of measured vs free-running output"),
    seed: Optional[int] = typer.Option(None, "--seed", min=0, help="override the spec's seed"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output"),
    force: bool = _FORCE,
) -> None:
    """Fit the spec's model, evaluate free runs on every split, save it to HDF5."""
    from . import engine, store
    from .data import load_dataset
    from .paths import check_outputs, spec_inputs
    from .progress import Reporter
    from .spec import load_spec
    from .usefulness import assess, stability_fix, summary_line

    t0 = time.perf_counter()
    s = load_spec(spec)
    if seed is not None:
        s.seed = seed
    target = out_path if out_path is not None else s.output_path()
    check_outputs(
        [
            (target, "model", "--out" if out_path is not None else "output:"),
            (json_path, "json", "--json"),
            (plot, "plot", "--plot"),
        ],
        spec_inputs(s, spec),
        force,
    )
    with Reporter(enabled=not quiet) as progress:
        progress("data", None, "loading")
        ds = load_dataset(s)
        model, runs = engine.fit_dataset(s, ds, progress)
        model.spec["output"] = str(Path(target).resolve())
        notes = assess(model, ds, runs)
        store.save(model, target)
    elapsed = time.perf_counter() - t0
    recs = ", ".join(ds.source_names())
    out.print(f"[bold]{s.name}[/]: {s.model.family} fitted with cost {s.cost} on {recs} in {elapsed:.1f} s")
    out.print(metrics_table(model.metrics))
    if s.data.noise is not None and s.data.noise.std > 0:
        out.print(
            f"note: noise of std {s.data.noise.std:g} x the output std was added to the "
            f"{', '.join(s.data.noise.splits)} outputs; those splits are scored against the noisy outputs"
        )
    for note in ds.excursion_notes():
        out.print(f"note: {note}", markup=False, soft_wrap=True)
    out.print(f"model written to {Path(target).resolve()}")
    if json_path:
        _write_json(
            json_path,
            {
                "metrics": model.metrics,
                "model": str(Path(target).resolve()),
                "assessment": [n.to_json() for n in notes],
            },
        )
    if plot:
        _plot_fit(plot, ds, runs, model, s.name)
        out.print(f"plot written to {plot}")
    bad = model.unstable
    if bad:
        raise FreeRunDiverged(
            f"the free run diverged on the {bad['split']} split at sample {bad['sample']} "
            f"(t = {bad['time']:.6g}) of recording '{bad['recording']}'",
            str(spec),
            f"{stability_fix(model.family.stability_hint, s.cost)}; the model was saved for inspection",
            sample=bad["sample"],
        )
    line = summary_line(notes, str(spec), s.cost)
    if line:
        err.print(f"warning: {line}", markup=False, soft_wrap=True)


def _plot_fit(path: Path, ds, runs, model, name: str) -> None:
    from .plots import measured_vs_simulated

    # the recording holding the test split (else the first), whole, with the splits shaded
    rec = next((r for s in ds.test_splits() for r, _, _ in ds.ranges[s]), 0)
    r = ds.recordings[rec]
    t = np.arange(r.n) * ds.sampling_time
    spans = [
        (split, a * ds.sampling_time, b * ds.sampling_time)
        for split in ds.splits()
        for rr, a, b in ds.ranges[split]
        if rr == rec
    ]
    scored = [
        a
        for split in (*ds.test_splits(), "validation", "train")
        for rr, a, _ in ds.scored(split, model.warmup)
        if rr == rec
    ]
    start = scored[0] if scored else 0
    measured_vs_simulated(
        path,
        t,
        r.y,
        runs[rec].y,
        model.output_names,
        f"{name}: {r.name}",
        spans,
        zoom=(start, min(r.n, start + 400)),
        tune_in=model.warmup,
    )


# ------------------------------------------------------------------------------ validate
@app.command()
@handled
def validate(
    spec: Path = typer.Argument(..., help="YAML spec"),
    resolved: bool = typer.Option(False, "--resolved", help="print the full resolved spec as YAML"),
) -> None:
    """Check a spec and its data without fitting: keys, files, columns, values, split sizes, the output path."""
    import yaml

    from .data import describe, load_dataset
    from .engine import check_plan
    from .paths import check_outputs, spec_inputs
    from .spec import load_spec

    s = load_spec(spec)
    check_outputs([(s.output_path(), "model", "output:")], spec_inputs(s, spec))  # what `fit` would refuse
    ds = load_dataset(s)
    check_plan(s, ds)
    out.print(
        f"[green]ok[/]: {spec} ({s.model.family}, cost {s.cost}, {len(ds.recordings)} recording(s), "
        f"inputs {ds.input_names}, outputs {ds.output_names}, sampling time {ds.sampling_time:g})"
    )
    table = Table()
    for col in ("split", "samples", "scored", "segments"):
        table.add_column(col)
    for row in describe(ds):
        table.add_row(row["split"], str(row["samples"]), str(row["scored"]), escape(", ".join(row["segments"])))
    out.print(table)
    if resolved:
        print(yaml.safe_dump(s.resolved(), sort_keys=False))


# ------------------------------------------------------------------------------ predict
@app.command()
@handled
def predict(
    model_path: Path = typer.Argument(..., metavar="MODEL", help="model file written by dynmodel fit"),
    input_path: Path = typer.Option(..., "--input", help="file with the model's input columns"),
    out_path: Optional[Path] = typer.Option(None, "--out", help="CSV for the predictions (default or '-': stdout)"),
    tune_in: Optional[Path] = typer.Option(None, "--tune-in", help="file with measured output columns for the tune-in"),
    plot: Optional[Path] = typer.Option(
        None, "--plot", help="PNG of the prediction (and the measured output when present)"
    ),
    skip_tune_in: bool = typer.Option(
        False,
        "--skip-tune-in",
        help="leave out the tune-in rows (by default they hold the measured outputs the model was fed, "
        "marked 1 in a 'measured' column)",
    ),
    force: bool = _FORCE,
) -> None:
    """Replay a saved model (free run) on a new input series; the table keeps the input file's time column."""
    from . import prediction, store
    from .errors import DataError
    from .paths import check_outputs

    if out_path is not None and str(out_path) == "-":
        out_path = None
    model = store.load(model_path)
    inp = prediction.read_inputs(model, input_path, tune_in)
    columns = prediction.header(model, inp.time_name, skip_tune_in)
    check_outputs(
        [(out_path, "csv", "--out"), (plot, "plot", "--plot")],
        {"model": model_path, "input file": input_path, "tune-in file": tune_in},
        force,
        columns={"--out": [prediction.header(model, inp.time_name, skip) for skip in (False, True)]},
    )
    try:
        run = model.run(inp.u, inp.y_tune)
    except ValueError as exc:
        raise DataError(str(exc), str(input_path), "check the input file") from None
    rows = prediction.table(model, inp, run, skip_tune_in)
    prediction.write_table(out_path, columns, rows)
    if out_path is not None:
        skipped = f" (the {model.warmup} tune-in rows left out)" if skip_tune_in and model.warmup else ""
        marked = f" (the first {model.warmup} rows are the measured tune-in, marked in column 'measured')"
        err.print(
            f"{len(rows)} predictions written to {out_path}{skipped or (marked if model.warmup else '')}",
            markup=False,
        )
    if plot:
        from .plots import measured_vs_simulated

        y_true = inp.y_measured if inp.y_measured is not None else np.full_like(run.y, np.nan)
        measured_vs_simulated(
            plot,
            inp.time,
            y_true,
            run.y,
            model.output_names,
            f"{model_path.name} on {input_path.name}",
            tune_in=model.warmup,
        )
        err.print(f"plot written to {plot}", markup=False)
    if run.diverged_at is not None:
        raise FreeRunDiverged(
            f"the free run diverged at sample {run.diverged_at} ({inp.time_name} = {inp.time[run.diverged_at]:.6g}); "
            "later predictions are NaN",
            str(input_path),
            "check that the input stays within the training range",
        )


# ------------------------------------------------------------------------------ inspect
@app.command()
@handled
def inspect(
    model_path: Path = typer.Argument(..., metavar="MODEL"),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write the summary as JSON"),
    spec: bool = typer.Option(False, "--spec", help="also print the resolved spec"),
    force: bool = _FORCE,
) -> None:
    """Summarize a saved model: family, data, preprocessing, metrics, provenance."""
    import yaml

    from . import store
    from .paths import check_outputs
    from .usefulness import assess, summary_line

    check_outputs([(json_path, "json", "--json")], {"model": model_path}, force)
    model = store.load(model_path)
    pre = model.preprocessor
    summary = {
        "file": str(model_path),
        "name": model.spec.get("name"),
        "family": model.family.name,
        "cost": model.spec.get("cost"),
        "inputs": pre.input_names,
        "outputs": pre.output_names,
        "delay_lines": pre.delay_lines,
        "delay_form": pre.delay_form,
        "scaling": pre.scaling,
        "sampling_time": pre.sampling_time,
        "tune_in_samples": model.warmup,
        "model": model.family.summary(),
        "metrics": model.metrics,
        "provenance": model.provenance,
    }
    out.print(f"[bold]{model_path}[/]  family [bold]{model.family.name}[/]  ({model.spec.get('name')})")
    facts = Table(show_header=False, box=None)
    facts.add_column(style="dim")
    facts.add_column()
    for key in (
        "cost",
        "inputs",
        "outputs",
        "delay_lines",
        "delay_form",
        "scaling",
        "sampling_time",
        "tune_in_samples",
    ):
        facts.add_row(key, escape(str(summary[key])))
    for key, value in summary["model"].items():
        facts.add_row(key, escape(str(value)))
    prov = model.provenance
    for key in ("dynmodel_version", "created", "seed", "training_data_sha256", "spec_file"):
        if key in prov:
            facts.add_row(key, escape(str(prov[key])))
    out.print(facts)
    out.print(metrics_table(model.metrics, "free-run metrics"))
    line = summary_line(assess(model), model.spec.get("spec_file") or model.provenance.get("spec_file"))
    if line:
        out.print(f"note: {line}", markup=False, soft_wrap=True)
    if spec:
        print(yaml.safe_dump(model.spec, sort_keys=False))
    if json_path:
        _write_json(json_path, summary)


# ------------------------------------------------------------------------------ reliability-check
def _parse_params(items: list[str]) -> dict[str, Any]:
    import yaml

    from .errors import SpecError

    values: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise SpecError(f"'{item}' is not key=value", "--param", "write e.g. --param a=3.5")
        key, raw = item.split("=", 1)
        try:
            values[key.strip()] = yaml.safe_load(raw)
        except yaml.YAMLError:
            raise SpecError(
                f"cannot read the value of '{item}'", "--param", "write e.g. --param C=[[0.3,2],[-0.5,-1.9]]"
            ) from None
    return values


def _parse_sine(text: str):
    from .errors import SpecError
    from .reliability import Sine

    parts = text.split(":")
    try:
        if len(parts) not in (2, 3):
            raise ValueError
        nums = [float(p) for p in parts]
    except ValueError:
        raise SpecError(f"'{text}' is not AMPLITUDE:OMEGA[:OFFSET]", "--sine", "write e.g. --sine 27:1.4") from None
    return Sine(nums[0], nums[1], nums[2] if len(nums) == 3 else None)


@app.command("reliability-check")
@handled
def reliability_check(
    model_path: Optional[Path] = typer.Argument(None, metavar="[MODEL]", help="model file written by dynmodel fit"),
    system: Optional[str] = typer.Option(
        None, "--system", help="check a built-in test system instead (see dynmodel plugins)"
    ),
    param: list[str] = typer.Option([], "--param", "-p", help="test-system parameter as key=value (repeatable)"),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write the full report as JSON"),
    replicas: int = typer.Option(16, "--replicas", min=2, help="initial states per test input"),
    scan_replicas: int = typer.Option(32, "--scan-replicas", min=2, help="initial states per constant input"),
    length: Optional[int] = typer.Option(None, "--length", min=50, help="steps per test run (default 2000)"),
    levels: int = typer.Option(21, "--levels", min=2, help="constant inputs per channel in the scan"),
    sine: list[str] = typer.Option(
        [],
        "--sine",
        help="extra test drive AMPLITUDE:OMEGA[:OFFSET] on the first input (omega in rad per time unit; repeatable)",
    ),
    tolerance: float = typer.Option(
        1e-6,
        "--tolerance",
        min=0.0,
        help="replicas count as converged within this fraction of the state-space diagonal",
    ),
    seed: int = typer.Option(0, "--seed", min=0, help="seed of initial states and noise inputs"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output"),
    force: bool = _FORCE,
) -> None:
    """Does the model forget its initial state? Replica test, Lyapunov exponents, constant-input scan
    (thesis 4.4.1, 5.3.1); exit 0 reliable, 1 unreliable or inconclusive."""
    from . import registry
    from .errors import SpecError
    from .progress import Reporter
    from .reliability import Settings, check, check_model

    if (model_path is None) == (system is None):
        raise DynmodelError(
            "give either a model file or --system NAME"
            if model_path is None
            else "give a model file or --system, not both",
            "reliability-check",
            "e.g. dynmodel reliability-check model.h5, or dynmodel reliability-check --system duffing",
        )
    if param and system is None:
        raise DynmodelError("--param sets parameters of a --system test system", "--param", "drop it for model files")
    from .paths import check_outputs

    check_outputs([(json_path, "json", "--json")], {"model": model_path}, force)
    settings = Settings(
        replicas=replicas,
        scan_replicas=scan_replicas,
        length=length,
        levels=levels,
        seed=seed,
        tolerance=tolerance,
        sines=tuple(_parse_sine(x) for x in sine),
    )
    with Reporter(enabled=not quiet) as progress:
        if system is not None:
            cls = registry.system(system)
            values = _parse_params(param)
            try:
                target = cls(**values)
            except ValueError as exc:  # pydantic's ValidationError is a ValueError
                errors = getattr(exc, "errors", lambda: [])()
                loc = ".".join(str(p) for p in errors[0]["loc"]) if errors else ""
                detail = f"{loc + ': ' if loc else ''}{errors[0]['msg']}" if errors else str(exc).splitlines()[-1]
                raise SpecError(
                    f"invalid parameter ({detail})", "--param", f"'{system}' takes {', '.join(cls.Params.model_fields)}"
                ) from None
            report = check(target, settings, progress)
            source = {"test_system": system, "params": target.params.model_dump(mode="json")}
        else:
            from . import store

            progress("load", None, str(model_path))
            model = store.load(model_path)
            report = check_model(model, settings, progress, str(model_path))
            source = {"model": str(model_path)}
    from .reliability.report import render

    render(report, out)
    if json_path:
        _write_json(json_path, {**source, **report.to_json()})
    if report.exit_code:
        raise typer.Exit(report.exit_code)


# ------------------------------------------------------------------------------ diagnose
@app.command("diagnose")
@handled
def diagnose_cmd(
    spec: Path = typer.Argument(..., help="YAML spec of the model to diagnose"),
    report: Optional[Path] = typer.Option(
        None,
        "--report",
        help="report folder (default: <name>-diagnosis next to the spec): index.md, figures, extended.yaml",
    ),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write the summary as JSON"),
    rounds: int = typer.Option(
        3, "--rounds", min=1, help="rounds of diagnose, extend, refit (stops earlier when adequate or without gain)"
    ),
    seeds: int = typer.Option(3, "--seeds", min=1, help="fits per spec for random families (gain uncertainty)"),
    alpha: float = typer.Option(0.001, "--alpha", min=1e-12, max=0.5, help="significance level of each detector"),
    min_share: float = typer.Option(
        0.05, "--min-share", min=0.0, max=1.0, help="a cause must account for this share of the residual mean square"
    ),
    min_effect: float = typer.Option(
        0.001, "--min-effect", min=0.0, help="... and for this fraction of the output variance"
    ),
    max_lag: Optional[int] = typer.Option(None, "--max-lag", min=1, help="largest lag searched for delays (samples)"),
    candidates: int = typer.Option(6, "--candidates", min=1, help="extensions measured per round"),
    seed: int = typer.Option(0, "--seed", min=0, help="seed of the gain's block bootstrap"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output"),
    force: bool = _FORCE,
) -> None:
    """Show what the model's free run gets wrong, name the cause, extend the model and measure the gain
    on the held-out test split (exit 0 when the diagnosis ran, adequate or not)."""
    from .diagnose import Settings, diagnose
    from .diagnose.report import write_extended, write_json, write_report
    from .paths import check_outputs, safe_name, spec_inputs
    from .progress import Reporter
    from .spec import load_spec, parse_yaml, read_spec_text

    s = load_spec(spec)  # one-line errors for a bad spec before any work
    folder = report if report is not None else spec.resolve().parent / f"{safe_name(s.name)}-diagnosis"
    check_outputs(
        [
            (folder, "report", "--report"),
            (json_path, "json", "--json"),
        ],
        spec_inputs(s, spec),
        force,
    )
    raw = parse_yaml(read_spec_text(spec), str(spec))
    raw.setdefault("name", spec.stem)
    settings = Settings(
        alpha=alpha,
        min_share=min_share,
        min_effect=min_effect,
        max_lag=max_lag,
        rounds=rounds,
        seeds=seeds,
        candidates=candidates,
        seed=seed,
    )
    with Reporter(enabled=not quiet) as progress:
        result = diagnose(raw, str(spec), spec.resolve().parent, settings, progress)
        progress("report", None, str(folder))
        index = write_report(result, folder)
        extended = write_extended(result, folder)
    _print_diagnosis(result)
    for note in result.notes:
        out.print(f"note: {note}", markup=False, soft_wrap=True)
    out.print(f"report written to {index}")
    if extended is not None:
        out.print(f"extended spec written to {extended} (run it with: dynmodel fit {extended})")
    if json_path:
        write_json(result, json_path)
        out.print(f"summary written to {json_path}")


def _print_diagnosis(result) -> None:
    from .diagnose.console import print_diagnosis

    print_diagnosis(result, out, metrics_table)


# ------------------------------------------------------------------------------ sweep
@app.command("sweep")
@handled
def sweep_cmd(
    spec: Path = typer.Argument(..., help="YAML spec"),
    grid: Path = typer.Option(..., "--grid", help="YAML grid: dotted spec keys and their values (docs/sweep.md)"),
    workers: Optional[int] = typer.Option(
        None, "--workers", min=1, help="local worker processes (default: one per core; 1 runs in-process)"
    ),
    scheduler: Optional[str] = typer.Option(
        None, "--scheduler", help="Dask cluster: tcp://HOST:PORT, a scheduler JSON file, or local:N (N new workers)"
    ),
    out_dir: Optional[Path] = typer.Option(
        None, "--out", help="output folder (default: <name>-sweep next to the spec)"
    ),
    keep: str = typer.Option("best", "--keep", help="models written to the folder: best, all or none"),
    resume: bool = typer.Option(False, "--resume", help="continue the sweep in --out: run only unfinished points"),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write the results (as results.json) here too"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output"),
    force: bool = _FORCE,
) -> None:
    """Fit the spec at every point of a grid of settings, in parallel (local processes or Dask), and rank
    the points by their validation free-run error."""
    from .paths import check_outputs
    from .progress import Reporter
    from .sweeps import run as sweeps

    folder = out_dir if out_dir is not None else sweeps.default_out(spec)
    check_outputs([(json_path, "json", "--json")], {"spec": [spec], "grid": [grid]}, force)
    try:
        with Reporter(enabled=not quiet) as progress:
            result = sweeps.sweep(
                spec,
                grid,
                out=folder,
                keep=keep,
                resume=resume,
                workers=workers,
                scheduler=scheduler,
                progress=progress,
            )
    except KeyboardInterrupt as exc:
        done = getattr(exc, "result", None)
        counts = (
            f"{done.counts()['points'] - done.counts()['not_run']} of {done.counts()['points']} points"
            if done
            else "no point"
        )
        err.print(
            f"interrupted: {counts} finished, kept in {folder}; run the same command with --resume to finish",
            markup=False,
        )
        raise typer.Exit(130) from None
    _print_sweep(result, json_path)


def _print_sweep(result, json_path: Optional[Path]) -> None:
    from .sweeps.report import render

    render(result, out)
    for text, n in result.info.get("warnings", {}).items():
        err.print(f"warning ({n} point{'s' if n > 1 else ''}): {text}", markup=False)
    if json_path:
        _write_json(json_path, result.to_json())
    if result.best is None:
        c = result.counts()
        err.print(
            f"error: no point finished with a stable free run ({c['diverged']} diverged, {c['error']} errors). "
            "Fix: see the messages above",
            markup=False,
        )
        raise typer.Exit(1)


# ------------------------------------------------------------------------------ control
def _pm(stats: dict[str, float], percent_points: bool = False) -> str:
    """mean ± std; alpha / beta with three decimals (99.998 must not print as 100)."""
    mean = f"{stats['mean']:.3f}" if percent_points else f"{stats['mean']:.4g}"
    return f"{mean} ± {stats['std']:.2g}"


@app.command()
@handled
def control(
    model_path: Path = typer.Argument(..., metavar="MODEL", help="model file written by dynmodel fit"),
    plant: Optional[Path] = typer.Option(
        None,
        "--plant",
        help="YAML with 'generator:' and 'params:' of the "
        "plant (or a dynmodel spec); default: the model's training generator",
    ),
    param: list[str] = typer.Option(
        [],
        "--param",
        "-p",
        help="plant parameter as key=value, dotted for nested keys (e.g. law.viscous=0.2; repeatable)",
    ),
    realizations: int = typer.Option(20, "--realizations", min=1, help="noise realizations"),
    duration: float = typer.Option(100.0, "--duration", min=0.0, help="length of a run (s)"),
    switch: float = typer.Option(50.0, "--switch", min=0.0, help="the feed-forward starts here (s)"),
    skip: float = typer.Option(20.0, "--skip", min=0.0, help="seconds not scored after the start and the switch"),
    seed: int = typer.Option(0, "--seed", min=0, help="seed of the reference and the noise realizations"),
    hold: str = typer.Option("linear", "--hold", help="feed-forward between samples: linear or zero (constant)"),
    workers: int = typer.Option(0, "--workers", min=0, help="threads for the realizations (0: one per core)"),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write every criterion and realization as JSON"),
    plot: Optional[Path] = typer.Option(
        None, "--plot", help="PNG of the tracking error before and after the switch (fig. 6.25)"
    ),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output"),
    force: bool = _FORCE,
) -> None:
    """Feed-forward control (thesis 6.4): P-control of a plant, the model's force added from the switch on;
    NMSE / MAX of the tracking error before and after, alpha and beta, and the perfect model's limits."""
    import yaml

    from . import control as ctl
    from . import store
    from .errors import SpecError
    from .progress import Reporter

    if hold not in ("linear", "zero"):
        raise SpecError(f"--hold {hold} is not linear or zero", "--hold", "use --hold linear (default) or --hold zero")
    from .paths import check_outputs

    check_outputs(
        [(json_path, "json", "--json"), (plot, "plot", "--plot")], {"model": model_path, "plant file": plant}, force
    )
    t0 = time.perf_counter()
    model = store.load(model_path)
    described = None
    if plant is not None:
        if not plant.is_file():
            raise SpecError("plant description not found", str(plant), "check the path")
        from .spec import read_spec_text

        try:
            described = yaml.safe_load(read_spec_text(plant))
        except yaml.YAMLError as exc:
            raise SpecError(f"malformed YAML: {str(exc).splitlines()[0]}", str(plant), "check the file") from None
        if not isinstance(described, dict):
            raise SpecError(
                "the plant description must be a mapping", str(plant), "write generator: NAME and params: {...}"
            )
    name, params = ctl.plant_source(model, described)
    the_plant, resolved = ctl.make_plant(name, params, _parse_params(param))
    settings = ctl.Settings(
        duration=duration, switch=switch, skip=skip, realizations=realizations, seed=seed, hold=hold, workers=workers
    )
    with Reporter(enabled=not quiet) as progress:
        report = ctl.run(model, the_plant, settings, progress)
    report.plant.update({"generator": name, "params": resolved})
    elapsed = time.perf_counter() - t0
    st = report.settings
    out.print(
        f"[bold]control[/]: {escape(str(model_path))} ({model.family.name}, inputs "
        f"{escape(str(model.input_names))}, delay lines {model.preprocessor.delay_lines or 'none'}"
        f"{' (differences)' if model.preprocessor.delay_form == 'difference' else ''}) on {name}: "
        f"{escape(the_plant.description)}"
    )
    out.print(
        f"{duration:g} s at {st['sampling_time']:g} s, feed-forward from {switch:g} s ({hold} hold), "
        f"{skip:g} s skipped after the start and the switch; {realizations} noise realization"
        f"{'s' if realizations > 1 else ''} (seed {seed}); {elapsed:.1f} s"
    )
    summary = report.summary()
    table = Table()
    table.add_column("criterion")
    table.add_column("model (mean ± std)", justify="right")
    table.add_column("perfect model", justify="right")
    for c in ctl.CRITERIA:
        pp = c in ("alpha", "beta")
        perf = "(same run)" if c in ("nmse_p", "max_p") else _pm(summary["perfect"][c], pp)
        table.add_row(ctl.LABELS[c], _pm(summary["model"][c], pp), perf)
    out.print(table)
    for note in report.notes:
        out.print(f"note: {escape(note)}")
    if json_path:
        _write_json(json_path, {"model": str(model_path), **report.to_json()})
    if plot:
        from .plots import tracking_error

        s = report.series
        tracking_error(
            plot,
            s["t"],
            s["reference"],
            s["error_model"],
            s["error_perfect"],
            switch,
            skip,
            f"{model_path.name} on {name}: alpha {summary['model']['alpha']['mean']:.4g} %, "
            f"beta {summary['model']['beta']['mean']:.4g} %",
        )
        out.print(f"plot written to {plot}")


# ------------------------------------------------------------------------------ plugins / schema
@app.command()
@handled
def plugins() -> None:
    """List the installed model families, data generators and reliability test systems."""
    from importlib.metadata import entry_points

    from . import registry

    for group, loaded, title in [
        (registry.FAMILIES, registry.families(), "model families"),
        (registry.SOURCES, registry.sources(), "data generators"),
        (registry.SOURCES, registry.benchmarks(), "benchmark sources (data: {benchmark: NAME, root: DIR})"),
        (registry.SYSTEMS, registry.systems(), "test systems for reliability-check --system"),
        (registry.DETECTORS, registry.detectors(), "detectors of dynmodel diagnose"),
    ]:
        eps = {ep.name: ep.value for ep in entry_points(group=group)}
        table = Table(title=f"{title} ({group})", title_justify="left")
        table.add_column("name")
        table.add_column("description")
        table.add_column("provided by", style="dim")
        for name, obj in loaded.items():
            table.add_row(name, getattr(obj, "description", ""), eps.get(name, ""))
        out.print(table)


@app.command()
@handled
def schema(
    out_path: Optional[Path] = typer.Option(None, "--out", help="write to a file instead of stdout"),
    force: bool = _FORCE,
) -> None:
    """Print the JSON Schema of the spec (every installed family's and generator's parameters)."""
    from .paths import check_outputs
    from .spec import spec_json_schema

    check_outputs([(out_path, "json", "--out")], None, force)
    text = json.dumps(spec_json_schema(), indent=2)
    if out_path:
        from .paths import write_text

        write_text(out_path, text + "\n")
    else:
        print(text)


@app.command()
@handled
def generate(
    generator: str = typer.Argument(..., help="generator name (see `dynmodel plugins`)"),
    n: int = typer.Option(10000, "--n", min=1, help="number of samples"),
    seed: int = typer.Option(0, "--seed", min=0, help="seed of the realization"),
    out_path: Path = typer.Option(..., "--out", help="CSV file to write"),
    param: list[str] = typer.Option([], "--param", "-p", help="generator parameter as key=value (repeatable)"),
    plot: Optional[Path] = typer.Option(
        None,
        "--plot",
        help="PNG of the recording: signals against time and every output against the first input (hysteresis loops)",
    ),
    force: bool = _FORCE,
) -> None:
    """Write a generated input/output recording as CSV (for trying file-based specs)."""
    import yaml

    from . import registry
    from .errors import SpecError
    from .paths import check_outputs
    from .spec import validation_summary

    gen = registry.source(generator)
    columns = ["t", *gen.input_names, *gen.output_names]
    check_outputs([(out_path, "csv", "--out"), (plot, "plot", "--plot")], None, force)  # replaces a CSV with --force
    values: dict[str, Any] = {}
    for item in param:
        if "=" not in item:
            raise SpecError(f"'{item}' is not key=value", "--param", "write e.g. --param a0=0.7")
        key, raw = item.split("=", 1)
        values[key.strip()] = yaml.safe_load(raw)
    try:
        params = gen.Params.model_validate(values)
    except ValueError as exc:
        raise SpecError(
            f"invalid parameter ({validation_summary(exc)})",
            "--param",
            f"see the '{generator}' entry of `dynmodel schema`",
        ) from None
    u, y = gen.generate(params, n, np.random.default_rng(seed))
    t = np.arange(n) * gen.sampling_time(params)
    header = ",".join(columns)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(out_path, np.column_stack([t, u, y]), delimiter=",", header=header, comments="", fmt="%.12g")
    err.print(f"{n} samples of {generator} (seed {seed}) written to {out_path}", markup=False)
    if plot:
        from .plots import recording

        recording(plot, t, u, y, list(gen.input_names), list(gen.output_names), f"{generator} (seed {seed})")
        err.print(f"plot written to {plot}", markup=False)


def main() -> None:
    """Console entry point."""
    app()


if __name__ == "__main__":
    main()
