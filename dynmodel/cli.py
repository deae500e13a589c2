"""Command line: ``dynmodel fit | validate | predict | inspect | reliability-check | diagnose | control | plugins |
schema | generate``.

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

from . import __version__
from .errors import EXIT_INTERNAL, DynmodelError, FreeRunDiverged

app = typer.Typer(
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
    """Turn DynmodelError into one stderr line and its exit code; other errors into exit 3."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except (typer.Exit, typer.Abort, KeyboardInterrupt):
            raise
        except DynmodelError as exc:
            if _state["debug"]:
                raise
            err.print(f"error: {exc.line()}", markup=False)
            raise typer.Exit(exc.exit_code) from None
        except Exception as exc:  # a bug, not the user's fault
            if _state["debug"]:
                raise
            err.print(
                f"internal error: {type(exc).__name__}: {exc} (rerun with --debug for the traceback and report it)",
                markup=False,
            )
            raise typer.Exit(EXIT_INTERNAL) from None

    return wrapper


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
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload, indent=2) + "\n")


def _warnings_to_stderr():
    import warnings

    def show(message, category, filename, lineno, file=None, line=None):
        err.print(f"warning: {message}", markup=False)

    warnings.showwarning = show


# ------------------------------------------------------------------------------ fit
@app.command()
@handled
def fit(
    spec: Path = typer.Argument(..., help="YAML spec"),
    out_path: Optional[Path] = typer.Option(None, "--out", help="model file (overrides the spec's output)"),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write metrics and model path as JSON"),
    plot: Optional[Path] = typer.Option(None, "--plot", help="PNG of measured vs free-running output"),
    seed: Optional[int] = typer.Option(None, "--seed", help="override the spec's seed"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output"),
) -> None:
    """Fit the spec's model, evaluate free runs on every split, save it to HDF5."""
    from . import engine, store
    from .data import load_dataset
    from .progress import Reporter
    from .spec import load_spec

    _warnings_to_stderr()
    t0 = time.perf_counter()
    s = load_spec(spec)
    if seed is not None:
        s.seed = seed
    with Reporter(enabled=not quiet) as progress:
        progress("data", None, "loading")
        ds = load_dataset(s)
        model, runs = engine.fit_dataset(s, ds, progress)
        target = out_path if out_path is not None else s.output_path()
        model.spec["output"] = str(Path(target).resolve())
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
        _write_json(json_path, {"metrics": model.metrics, "model": str(Path(target).resolve())})
    if plot:
        _plot_fit(plot, ds, runs, model, s.name)
        out.print(f"plot written to {plot}")
    bad = model.unstable
    if bad:
        raise FreeRunDiverged(
            f"the free run diverged on the {bad['split']} split at sample {bad['sample']} "
            f"(t = {bad['time']:.6g}) of recording '{bad['recording']}'",
            str(spec),
            f"{model.family.stability_hint}; the model was saved for inspection",
            sample=bad["sample"],
        )


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
    """Check a spec and its data without fitting: keys, files, columns, NaN, split sizes."""
    import yaml

    from .data import describe, load_dataset
    from .spec import load_spec

    _warnings_to_stderr()
    s = load_spec(spec)
    ds = load_dataset(s)
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
def _read_table(path: Path, names: list[str]) -> dict[str, np.ndarray]:
    from .data.readers import read_columns

    return read_columns(path, names)


@app.command()
@handled
def predict(
    model_path: Path = typer.Argument(..., metavar="MODEL", help="model file written by dynmodel fit"),
    input_path: Path = typer.Option(..., "--input", help="file with the model's input columns"),
    out_path: Optional[Path] = typer.Option(None, "--out", help="CSV for the predictions (default: stdout)"),
    tune_in: Optional[Path] = typer.Option(None, "--tune-in", help="file with measured output columns for the tune-in"),
    plot: Optional[Path] = typer.Option(
        None, "--plot", help="PNG of the prediction (and the measured output when present)"
    ),
) -> None:
    """Replay a saved model (free run) on a new input series."""
    from . import store
    from .data.readers import read_columns
    from .errors import DataError

    model = store.load(model_path)
    cols = read_columns(input_path, model.input_names)
    u = np.column_stack([cols[n] for n in model.input_names])
    if not np.isfinite(u).all():
        row = int(np.flatnonzero(~np.isfinite(u).all(axis=1))[0])
        raise DataError(f"the input has NaN or inf at sample {row}", str(input_path), "fill or remove those samples")
    y_meas = None
    need = model.warmup
    if need:
        source = tune_in or input_path
        try:
            yc = read_columns(source, model.output_names)
        except DataError:
            outs = ", ".join(f"'{n}'" for n in model.output_names)
            raise DataError(
                f"this model tunes in on the first {need} measured samples of output column(s) {outs}, "
                f"and {source.name} has none",
                str(source),
                f"add column(s) {outs} to {input_path.name} (only the first {need} rows are read) or pass "
                "--tune-in FILE",
            ) from None
        y_meas = np.column_stack([yc[n] for n in model.output_names])
        if len(y_meas) < need or not np.isfinite(y_meas[:need]).all():
            raise DataError(
                f"the tune-in needs {need} finite measured output samples, found "
                f"{int(np.isfinite(y_meas[:need]).all(axis=1).sum())}",
                str(source),
                f"provide the first {need} measured values of {model.output_names}",
            )
    try:
        run = model.run(u, y_meas)
    except ValueError as exc:
        raise DataError(str(exc), str(input_path), "check the input file") from exc
    t = np.arange(len(u)) * model.sampling_time
    table = np.column_stack([t, run.y])
    header = ",".join(["t"] + list(model.output_names))
    if out_path is None:
        np.savetxt(sys.stdout, table, delimiter=",", header=header, comments="", fmt="%.10g")
    else:
        out_path.parent.mkdir(parents=True, exist_ok=True)
        np.savetxt(out_path, table, delimiter=",", header=header, comments="", fmt="%.10g")
        err.print(f"{len(u)} predictions written to {out_path}", markup=False)
    if plot:
        from .plots import measured_vs_simulated

        try:
            yc = read_columns(input_path, model.output_names)
            y_true = np.column_stack([yc[n] for n in model.output_names])
        except DataError:
            y_true = np.full_like(run.y, np.nan)
        measured_vs_simulated(
            plot, t, y_true, run.y, model.output_names, f"{model_path.name} on {input_path.name}", tune_in=model.warmup
        )
    if run.diverged_at is not None:
        raise FreeRunDiverged(
            f"the free run diverged at sample {run.diverged_at} (t = {run.diverged_at * model.sampling_time:.6g}); "
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
) -> None:
    """Summarize a saved model: family, data, preprocessing, metrics, provenance."""
    import yaml

    from . import store

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
    seed: int = typer.Option(0, "--seed", help="seed of initial states and noise inputs"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output"),
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
    settings = Settings(
        replicas=replicas,
        scan_replicas=scan_replicas,
        length=length,
        levels=levels,
        seed=seed,
        tolerance=tolerance,
        sines=tuple(_parse_sine(x) for x in sine),
    )
    _warnings_to_stderr()
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
    rounds: int = typer.Option(1, "--rounds", min=1, help="diagnose and extend again until adequate or no gain"),
    seeds: int = typer.Option(3, "--seeds", min=1, help="fits per spec for random families (gain uncertainty)"),
    alpha: float = typer.Option(0.001, "--alpha", min=1e-12, max=0.5, help="significance level of each detector"),
    min_share: float = typer.Option(
        0.05, "--min-share", min=0.0, max=1.0, help="a cause must account for this share of the residual mean square"
    ),
    min_effect: float = typer.Option(
        0.001, "--min-effect", min=0.0, help="... and for this fraction of the output variance"
    ),
    max_lag: Optional[int] = typer.Option(None, "--max-lag", min=1, help="largest lag searched for delays (samples)"),
    candidates: int = typer.Option(4, "--candidates", min=1, help="extensions measured per round"),
    seed: int = typer.Option(0, "--seed", help="seed of the gain's block bootstrap"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output"),
) -> None:
    """Show what the model's free run gets wrong, name the cause, extend the model and measure the gain
    on the held-out test split (exit 0 when the diagnosis ran, adequate or not)."""
    from .diagnose import Settings, diagnose
    from .diagnose.report import write_extended, write_json, write_report
    from .progress import Reporter
    from .spec import load_spec, parse_yaml

    _warnings_to_stderr()
    s = load_spec(spec)  # one-line errors for a bad spec before any work
    raw = parse_yaml(spec.read_text(encoding="utf-8"), str(spec))
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
        folder = report if report is not None else spec.resolve().parent / f"{s.name}-diagnosis"
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
    base = result.baseline
    out.print(
        f"[bold]{result.name}[/]: {base.spec.model.family} (cost {base.spec.cost}) diagnosed in "
        f"{result.seconds:.1f} s; model memory {result.rounds[0].memory} samples"
    )
    out.print(metrics_table(base.metrics, "baseline free run"))
    table = Table(
        title="checks (significant first, by score: share of the residual's mean square)", title_justify="left"
    )
    for col, kw in (("cause", {}), ("significant", {}), ("score", {"justify": "right"}), ("p", {"justify": "right"})):
        table.add_column(col, **kw)
    for f in result.checks:
        p = f.evidence.get("p_value")
        table.add_row(
            f.cause,
            "yes" if f.significant else "",
            f"{f.score:.3g}",
            "-" if p is None else ("<1e-16" if p < 1e-16 else f"{p:.2g}"),
        )
    out.print(table)
    if not result.findings:
        out.print("[green]adequate[/]: no cause is significant; nothing to extend")
        return
    for i, f in enumerate(result.findings, 1):
        out.print(f"{i}. [bold]{f.cause}[/]: {escape(f.summary)}")
    top = result.findings[0]
    out.print(f"named cause: [bold]{top.cause}[/]")
    for rnd in result.rounds:
        if rnd.chosen is not None:
            out.print(f"round {rnd.index}: {escape(rnd.chosen.extension.summary)}; {rnd.outcome}")
        elif rnd.outcome:
            out.print(f"round {rnd.index}: {rnd.outcome}")
    g = result.gain
    if g:
        before = g.get("test_nmse_before")
        after = g.get("test_nmse_after")
        red = g.get("relative_reduction")
        unc = g.get("uncertainty") or {}
        unc = unc["per_output"][0] if "per_output" in unc else unc
        rr = unc.get("relative_reduction") or {}
        spread = f" ± {100 * rr['std']:.1f} %" if rr.get("std") is not None else ""

        def shown(v, diverged):
            return "diverged" if diverged else f"{_fmt(v)} %"

        out.print(
            f"test NMSE {shown(before, g.get('baseline_diverged_on_test'))} -> "
            f"{shown(after, g.get('extended_diverged_on_test'))}"
            + (f" (reduction {100 * red:.1f} %{spread})" if red is not None else "")
            + f"; test MAX {_fmt(g.get('test_max_before'))} -> {_fmt(g.get('test_max_after'))}"
        )


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
    seed: int = typer.Option(0, "--seed", help="seed of the reference and the noise realizations"),
    hold: str = typer.Option("linear", "--hold", help="feed-forward between samples: linear or zero (constant)"),
    workers: int = typer.Option(0, "--workers", min=0, help="threads for the realizations (0: one per core)"),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write every criterion and realization as JSON"),
    plot: Optional[Path] = typer.Option(
        None, "--plot", help="PNG of the tracking error before and after the switch (fig. 6.25)"
    ),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output"),
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
    _warnings_to_stderr()
    t0 = time.perf_counter()
    model = store.load(model_path)
    described = None
    if plant is not None:
        if not plant.is_file():
            raise SpecError("plant description not found", str(plant), "check the path")
        try:
            described = yaml.safe_load(plant.read_text(encoding="utf-8"))
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
def schema(out_path: Optional[Path] = typer.Option(None, "--out", help="write to a file instead of stdout")) -> None:
    """Print the JSON Schema of the spec (every installed family's and generator's parameters)."""
    from .spec import spec_json_schema

    text = json.dumps(spec_json_schema(), indent=2)
    if out_path:
        out_path.write_text(text + "\n")
    else:
        print(text)


@app.command()
@handled
def generate(
    generator: str = typer.Argument(..., help="generator name (see `dynmodel plugins`)"),
    n: int = typer.Option(10000, "--n", min=1, help="number of samples"),
    seed: int = typer.Option(0, "--seed", help="seed of the realization"),
    out_path: Path = typer.Option(..., "--out", help="CSV file to write"),
    param: list[str] = typer.Option([], "--param", "-p", help="generator parameter as key=value (repeatable)"),
    plot: Optional[Path] = typer.Option(
        None,
        "--plot",
        help="PNG of the recording: signals against time and every output against the first input (hysteresis loops)",
    ),
) -> None:
    """Write a generated input/output recording as CSV (for trying file-based specs)."""
    import yaml

    from . import registry
    from .errors import SpecError
    from .spec import validation_summary

    gen = registry.source(generator)
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
    header = ",".join(["t", *gen.input_names, *gen.output_names])
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
