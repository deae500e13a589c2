"""Command line: ``dynmodel fit | validate | predict | inspect | reliability-check | diagnose | sweep | control |
plugins | schema | generate``.

Tables go to stdout, progress to stderr, machine output to ``--json FILE``. A user's mistake
gets one line on stderr and exit code 2 (1 when a check ran and failed, e.g. a diverging
free run); ``--debug`` shows tracebacks.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from typer.core import TyperGroup

from . import __version__
from .errors import EXIT_INTERNAL, EXIT_TERMINATED, Interrupted, Terminated, how_interrupted, interruption_line


class _OneLineErrors(TyperGroup):
    """Usage errors (a missing argument, a bad option value) as one line, like every other error."""

    def main(self, *args: Any, standalone_mode: bool = True, **kwargs: Any) -> Any:
        # (mypy: *args could hold click's positional standalone_mode; callers pass it by keyword)
        if not standalone_mode:
            return super().main(*args, standalone_mode=False, **kwargs)  # type: ignore[misc]
        try:
            rv = super().main(*args, standalone_mode=False, **kwargs)  # type: ignore[misc]
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

    def make_context(self, *args: Any, **kwargs: Any) -> Any:
        with _interrupt_as_line():
            return super().make_context(*args, **kwargs)

    def invoke(self, ctx: Any) -> Any:
        with _interrupt_as_line():
            return super().invoke(ctx)

    def get_help_option(self, ctx: Any) -> Any:
        return _flag(super().get_help_option(ctx))

    def get_command(self, ctx: Any, cmd_name: str) -> Any:
        command = super().get_command(ctx, cmd_name)
        if command is not None:
            _flag(command.get_help_option(ctx))
        return command


@contextlib.contextmanager
def _interrupt_as_line():
    """A Ctrl-C (or SIGTERM) outside a command's own handling (:func:`handled`: while the command line is parsed, or
    the command's modules load) ends with one line and its exit code too; typer would exit 130 silently."""
    try:
        yield
    except KeyboardInterrupt as exc:
        print(interruption_line(exc), file=sys.stderr)
        raise typer.Exit(how_interrupted(exc)[1]) from None


def _flag(option: Any) -> Any:
    """--help as a flag in the help text (typer would show "<bool>", as if it took a value)."""
    if option is not None:
        option.metavar = FLAG
    return option


app = typer.Typer(
    cls=_OneLineErrors,
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Black-box models of driven dynamical systems from measured input/output data.",
)
# no emoji codes: a named test set prints as 'test:b:rec_b.csv', which rich would turn into a picture
out = Console(soft_wrap=True, highlight=False, emoji=False)
err = Console(stderr=True, soft_wrap=True, highlight=False, emoji=False)
_state = {"debug": False, "json_stdout": False}
#: the metavar of a flag: none (typer would show "<bool>", as if it took a value)
FLAG = " "


def _version(value: bool) -> None:
    if value:
        print(f"dynmodel {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    debug: bool = typer.Option(False, "--debug", help="show tracebacks for errors", metavar=FLAG),
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="print the version and exit", metavar=FLAG
    ),
) -> None:
    _state["debug"] = debug


def json_stdout(fn: Callable) -> Callable:
    """``--json -`` writes the JSON to standard output, as ``predict --out -`` does with its table: the command
    writes it to a temporary file, its own lines go to standard error, and the JSON follows on stdout (also
    when the command ends with an exit code after writing it, e.g. an unreliable model)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if str(kwargs.get("json_path")) != "-":
            return fn(*args, **kwargs)
        import shutil
        import sys
        import tempfile

        global out
        folder = Path(tempfile.mkdtemp(prefix="dynmodel-json-"))
        kwargs["json_path"] = folder / "summary.json"
        screen, out = out, err  # the command's own lines go to stderr
        _state["json_stdout"] = True
        try:
            return fn(*args, **kwargs)
        finally:
            out, _state["json_stdout"] = screen, False
            if kwargs["json_path"].exists():
                sys.stdout.write(kwargs["json_path"].read_text(encoding="utf-8"))
                sys.stdout.flush()
            shutil.rmtree(folder, ignore_errors=True)

    return wrapper


def handled(fn: Callable) -> Callable:
    """Run a command: expected errors (see dynmodel.explain) become one stderr line and their exit
    code, anything else (a bug) the internal-error line; warnings are shown once, after the
    command succeeded (an error line stands alone)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        import warnings

        from .explain import explain, internal_error_line

        with warnings.catch_warnings(record=True) as caught, _sigterm_as_interrupt():  # default filters in force
            try:
                result = fn(*args, **kwargs)
            except (typer.Exit, typer.Abort, SystemExit):
                _show_warnings(caught)
                raise
            except BrokenPipeError:  # the reader of stdout stopped (| head): main() ends quietly
                raise
            except BaseException as exc:  # noqa: BLE001 - the one place that explains failures
                mapped = explain(exc)
                if _state["debug"] and not isinstance(exc, KeyboardInterrupt):
                    raise
                if mapped is None:
                    err.print(internal_error_line(exc), markup=False)
                    raise typer.Exit(EXIT_INTERNAL) from None
                line, code = mapped.line(), mapped.exit_code
                if _state.get("terminated") and isinstance(mapped, Interrupted):  # say what stopped it
                    line, code = _as_sigterm(line), EXIT_TERMINATED
                err.print(f"error: {line}", markup=False)
                raise typer.Exit(code) from None
        _show_warnings(caught)
        return result

    return wrapper


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """SIGTERM (``timeout``, SLURM, ``docker stop``) handled like Ctrl-C: raised in the main thread as
    :class:`~dynmodel.errors.Terminated` (a KeyboardInterrupt), so that worker processes are stopped, a sweep's
    finished points are kept and the command ends with one line; exit 143. Left alone when SIGTERM is
    ignored, or outside the main thread."""
    import signal

    _state["terminated"] = False
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGTERM)
    if previous == signal.SIG_IGN:
        yield
        return

    def terminate(signum, frame):
        _state["terminated"] = True
        raise Terminated()

    hook = sys.unraisablehook

    def swallowed(args) -> None:
        # the handler's exception landed in a finalizer or a weakref callback, where Python only prints it (under
        # load a sweep then ran to its end and exited 0): send the signal again, to land in the code around it
        if isinstance(args.exc_value, Terminated):
            threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGTERM)).start()
            return
        hook(args)

    signal.signal(signal.SIGTERM, terminate)
    sys.unraisablehook = swallowed
    try:
        yield
    finally:
        sys.unraisablehook = hook
        signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)


def _as_sigterm(line: str) -> str:
    """An interruption's line, when SIGTERM (not Ctrl-C) stopped the command."""
    return line.replace("interrupted (Ctrl-C)", "terminated (SIGTERM)").replace("Ctrl-C", "SIGTERM")


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
    from .metrics import split_label

    label = {k: split_label(k, m) for k, m in metrics.items()}
    table.add_column("split", min_width=max((len(v) for v in label.values()), default=5))
    table.add_column("samples", justify="right")
    shown = [k for k in ("nmse", "max", "rmse", "fit") if k == "nmse" or any(k in m for m in metrics.values())]
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
            row = [label[split], str(m["samples"]), cell] + ["-"] * (len(shown) - 1)
        else:
            row = [label[split], str(m["samples"])] + [_fmt(m.get(k)) for k in shown]
        if has_one:
            row.append(_fmt(m.get("nmse_1")))
        table.add_row(*row)
        per = m.get("per_output") or {}
        if len(per) > 1 and not m.get("unstable_from"):  # each output: a mean must not hide a useless one
            for name, values in per.items():
                table.add_row(*[escape(f"  output {name}"), ""] + [_fmt(values.get(k)) for k in shown] + [""] * has_one)
    return table


# ------------------------------------------------------------------------------ fit
_FORCE = typer.Option(
    False, "--force", help="replace an existing file that is not a previous output of this kind", metavar=FLAG
)


@app.command()
@handled
@json_stdout
def fit(
    spec: Path = typer.Argument(..., metavar="SPEC", help="YAML spec"),
    out_path: Optional[Path] = typer.Option(None, "--out", help="model file (overrides the spec's output)"),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write metrics and model path as JSON"),
    plot: Optional[Path] = typer.Option(None, "--plot", help="PNG of measured vs free-running output"),
    seed: Optional[int] = typer.Option(None, "--seed", min=0, help="override the spec's seed"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output", metavar=FLAG),
    force: bool = _FORCE,
    workers: Optional[int] = typer.Option(
        None, "--workers", min=1, help="family auto: parallel fits (default one per core; 1: in this process)"
    ),
    scheduler: Optional[str] = typer.Option(
        None, "--scheduler", help="family auto: run the candidates on Dask (local:N or a scheduler address)"
    ),
) -> None:
    """Fit the spec's model, evaluate free runs on every split, save it to HDF5 (family auto, or no
    model section: search every family's candidates and keep the best on validation, docs/auto.md)."""
    from .commands.fit import fit_and_save
    from .progress import Reporter

    with Reporter(enabled=not quiet) as progress:
        result = fit_and_save(spec, out_path, json_path, plot, seed, force, workers, scheduler, progress)
    s, model, ds = result.spec, result.model, result.dataset
    recs = ", ".join(ds.source_names())
    out.print(
        f"[bold]{escape(s.name)}[/]: {result.family_label} fitted with cost {result.cost} on {escape(recs)} in "
        f"{result.seconds:.1f} s"
    )
    if model.search is not None:
        _print_search(model.search)
    out.print(metrics_table(model.metrics))
    for note in result.data_notes():
        out.print(f"note: {note}", markup=False, soft_wrap=True)
    out.print(f"model written to {result.path}", markup=False)
    if result.plot_path is not None:
        out.print(f"plot written to {result.plot_path}", markup=False)
    problem = result.problem()
    if problem is not None:
        raise problem
    line = result.warning()
    if line:
        err.print(f"warning: {line}", markup=False, soft_wrap=True)


def _print_search(record: dict[str, Any]) -> None:
    """The search's headline, leaderboard and notes (family auto)."""
    from .search.report import SCREENED, TABLE_HEADERS, headline, leaderboard, table_cells

    out.print(headline(record), markup=False, soft_wrap=True)
    table = Table(title_justify="left")
    for h in TABLE_HEADERS:
        numeric = h in ("val. NMSE %", "fits", "fit s")
        table.add_column(h, justify="right" if numeric else "left", no_wrap=numeric, overflow="fold")
    rows = leaderboard(record)
    for row in rows:
        table.add_row(*[escape(c) for c in table_cells(row)])
    out.print(table)
    measured = sum(1 for c in record["candidates"] if c.get("levels"))
    if measured > len(rows):
        out.print(
            f"... and {measured - len(rows)} more candidates: every one, with its parameters and verdict, is in "
            "the record (fit --json, the model file's /search, dynmodel inspect --json)",
            markup=False,
            soft_wrap=True,
        )
    if any(r["level"] != "full" for r in rows):
        out.print(SCREENED, markup=False)
    for note in record.get("notes") or []:
        out.print(f"note: {note}", markup=False, soft_wrap=True)


# ------------------------------------------------------------------------------ validate
@app.command()
@handled
def validate(
    spec: Path = typer.Argument(..., metavar="SPEC", help="YAML spec"),
    resolved: bool = typer.Option(False, "--resolved", help="print the full resolved spec as YAML", metavar=FLAG),
) -> None:
    """Check a spec and its data without fitting: keys, files, columns, values, split sizes, the output path."""
    import yaml

    from .commands.fit import validate_spec_file

    result = validate_spec_file(spec)
    s, ds, plan = result.spec, result.dataset, result.plan
    out.print(
        "[green]ok[/]: "
        + escape(
            f"{spec} ({s.model.family}, cost {s.cost or 'per family'}, {ds.n_loaded} recording(s), "
            f"inputs {ds.input_names}, outputs {ds.output_names}, sampling time {ds.sampling_time:g})"
        )
    )
    table = Table()
    for col in ("split", "samples", "scored", "segments"):
        table.add_column(col)
    for row in result.splits:
        table.add_row(row["split"], str(row["samples"]), str(row["scored"]), escape(", ".join(row["segments"])))
    out.print(table)
    for note in ds.small_split_notes() + ds.overlap_notes() + ds.training_input_notes() + ds.artifact_notes():
        out.print(f"note: {note}", markup=False, soft_wrap=True)
    if isinstance(plan, list):  # family auto: what the search will do
        for line in plan:
            out.print(f"auto: {line}", markup=False, soft_wrap=True)
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
        metavar=FLAG,
    ),
    force: bool = _FORCE,
) -> None:
    """Replay a saved model (free run) on a new input series; the table keeps the input file's time column."""
    from .commands.predict import predict_file
    from .prediction import write_table

    if out_path is not None and str(out_path) == "-":
        out_path = None
    result = predict_file(model_path, input_path, out_path, tune_in, plot, skip_tune_in, force)
    if out_path is None:
        write_table(None, result.columns, result.rows)
    else:
        err.print(result.written_line(), markup=False)
    if result.plot_path is not None:
        err.print(f"plot written to {result.plot_path}", markup=False)
    for note in result.excursion_notes():
        err.print(f"note: {note}", markup=False, soft_wrap=True)
    problem = result.problem()
    if problem is not None:
        raise problem


# ------------------------------------------------------------------------------ inspect
@app.command()
@handled
@json_stdout
def inspect(
    model_path: Path = typer.Argument(..., metavar="MODEL"),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write the summary as JSON"),
    spec: bool = typer.Option(False, "--spec", help="also print the resolved spec", metavar=FLAG),
    force: bool = _FORCE,
) -> None:
    """Summarize a saved model: family, data, preprocessing, metrics, provenance."""
    import yaml

    from .commands.predict import inspect_model
    from .inspection import FACTS, PROVENANCE

    result = inspect_model(model_path, json_path, force)
    model, summary = result.model, result.summary
    out.print(
        f"[bold]{escape(str(model_path))}[/]  family [bold]{model.family.name}[/]  ({escape(str(model.spec.get('name')))})"
    )
    facts = Table(show_header=False, box=None)
    facts.add_column(style="dim")
    facts.add_column()
    for key in FACTS:
        facts.add_row(key, escape(str(summary[key])))
    for key, value in summary["model"].items():
        facts.add_row(key, escape(str(value)))
    prov = model.provenance
    for key in PROVENANCE:
        if key in prov:
            value = str(prov[key])
            if key == "seed" and model.search is not None and model.spec.get("seed") not in (None, prov[key]):
                # the search derives each candidate's seed from the spec's; --spec gives the one that refits it
                value = f"{prov[key]} (the search's; this model was fitted with seed {model.spec['seed']})"
            facts.add_row(key, escape(value))
    out.print(facts)
    if model.search is not None:  # the leaderboard the fit printed
        out.print("chosen by family auto:", markup=False)
        _print_search(model.search)
    out.print(metrics_table(model.metrics, "free-run metrics"))
    if result.note:
        out.print(f"note: {result.note}", markup=False, soft_wrap=True)
    if spec:  # without output: a refit of the printed spec writes next to it, never over this model file
        print(yaml.safe_dump({k: v for k, v in model.spec.items() if k != "output"}, sort_keys=False))


# ------------------------------------------------------------------------------ reliability-check
@app.command("reliability-check")
@handled
@json_stdout
def reliability_check(
    model_path: Optional[Path] = typer.Argument(None, metavar="MODEL", help="model file written by dynmodel fit"),
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
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output", metavar=FLAG),
    force: bool = _FORCE,
) -> None:
    """Does the model forget its initial state? Replica test, Lyapunov exponents, constant-input scan
    (thesis 4.4.1, 5.3.1); exit 0 reliable, 1 unreliable or inconclusive."""
    from .commands.reliability import check_reliability
    from .progress import Reporter
    from .reliability import Settings
    from .reliability.report import render

    settings = Settings(
        replicas=replicas, scan_replicas=scan_replicas, length=length, levels=levels, seed=seed, tolerance=tolerance
    )
    with Reporter(enabled=not quiet) as progress:
        result = check_reliability(model_path, system, param, settings, sine, json_path, force, progress)
    render(result.report, out)
    if result.report.exit_code:
        raise typer.Exit(result.report.exit_code)


# ------------------------------------------------------------------------------ diagnose
@app.command("diagnose")
@handled
@json_stdout
def diagnose_cmd(
    spec: Path = typer.Argument(..., metavar="SPEC", help="YAML spec of the model to diagnose"),
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
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output", metavar=FLAG),
    force: bool = _FORCE,
) -> None:
    """Show what the model's free run gets wrong, name the cause, extend the model and measure the gain
    on the held-out test split (exit 0 when the diagnosis ran, adequate or not)."""
    from .commands.diagnose import diagnose_spec_file
    from .diagnose import Settings
    from .progress import Reporter

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
        done = diagnose_spec_file(spec, report, json_path, settings, force, progress)
    result = done.diagnosis
    _print_diagnosis(result)
    for note in result.notes:
        out.print(f"note: {note}", markup=False, soft_wrap=True)
    out.print(f"report written to {done.index}", markup=False)
    if done.extended is not None:
        out.print(f"extended spec written to {done.extended} (run it with: dynmodel fit {done.extended})", markup=False)
    if done.json_path is not None and not _state.get("json_stdout"):
        out.print(f"summary written to {done.json_path}", markup=False)
    line = result.extended_warning()
    if line:
        err.print(f"warning: {line}", markup=False, soft_wrap=True)


def _print_diagnosis(result) -> None:
    from .diagnose.console import print_diagnosis

    print_diagnosis(result, out, metrics_table)


# ------------------------------------------------------------------------------ sweep
@app.command("sweep")
@handled
@json_stdout
def sweep_cmd(
    spec: Path = typer.Argument(..., metavar="SPEC", help="YAML spec"),
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
    resume: bool = typer.Option(
        False, "--resume", help="continue the sweep in --out: run only unfinished points", metavar=FLAG
    ),
    json_path: Optional[Path] = typer.Option(None, "--json", help="write the results (as results.json) here too"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output", metavar=FLAG),
    force: bool = _FORCE,
) -> None:
    """Fit the spec at every point of a grid of settings, in parallel (local processes or Dask), and rank
    the points by their validation free-run error."""
    from .commands.sweep import run_sweep
    from .progress import Reporter

    try:
        with Reporter(enabled=not quiet) as progress:
            result = run_sweep(spec, grid, out_dir, keep, resume, workers, scheduler, json_path, force, progress)
    except KeyboardInterrupt as exc:
        done = getattr(exc, "result", None)
        counts = (
            f"{done.counts()['points'] - done.counts()['not_run']} of {done.counts()['points']} points"
            if done
            else "no point"
        )
        how, code = how_interrupted(exc)
        if _state.get("terminated"):
            how, code = "SIGTERM", EXIT_TERMINATED
        err.print(
            f"{'terminated (SIGTERM)' if how == 'SIGTERM' else 'interrupted'}: {counts} finished, kept in "
            f"{getattr(exc, 'folder', out_dir)}; run the same command with --resume to finish",
            markup=False,
        )
        raise typer.Exit(code) from None
    _print_sweep(result)


def _print_sweep(result) -> None:
    from .sweeps.report import render

    render(result, out)
    for text, n in result.info.get("warnings", {}).items():
        err.print(f"warning ({n} point{'s' if n > 1 else ''}): {text}", markup=False)
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
@json_stdout
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
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress output", metavar=FLAG),
    force: bool = _FORCE,
) -> None:
    """Feed-forward control (thesis 6.4): P-control of a plant, the model's force added from the switch on;
    NMSE / MAX of the tracking error before and after, alpha and beta, and the perfect model's limits."""
    from . import control as ctl
    from .commands.control import run_control
    from .progress import Reporter

    settings = ctl.Settings(
        duration=duration, switch=switch, skip=skip, realizations=realizations, seed=seed, hold=hold, workers=workers
    )
    with Reporter(enabled=not quiet) as progress:
        result = run_control(model_path, plant, param, settings, json_path, plot, force, progress)
    model, report = result.model, result.report
    st = report.settings
    out.print(
        f"[bold]control[/]: {escape(str(model_path))} ({model.family.name}, inputs "
        f"{escape(str(model.input_names))}, delay lines {model.preprocessor.delay_lines or 'none'}"
        f"{' (differences)' if model.preprocessor.delay_form == 'difference' else ''}) on {result.name}: "
        f"{escape(result.plant.description)}"
    )
    out.print(
        f"{duration:g} s at {st['sampling_time']:g} s, feed-forward from {switch:g} s ({hold} hold), "
        f"{skip:g} s skipped after the start and the switch; {realizations} noise realization"
        f"{'s' if realizations > 1 else ''} (seed {seed}); {result.seconds:.1f} s"
    )
    summary = result.summary()
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
    if plot:
        out.print(f"plot written to {plot}", markup=False)


# ------------------------------------------------------------------------------ plugins / schema
@app.command()
@handled
def plugins() -> None:
    """List the installed model families, data generators and reliability test systems."""
    from .commands.catalog import installed_plugins

    for group in installed_plugins():
        table = Table(title=f"{group.title} ({group.group})", title_justify="left")
        table.add_column("name")
        table.add_column("description")
        table.add_column("provided by", style="dim")
        for row in group.rows:
            table.add_row(*row)
        out.print(table)


@app.command()
@handled
def schema(
    out_path: Optional[Path] = typer.Option(None, "--out", help="write to a file instead of stdout"),
    force: bool = _FORCE,
) -> None:
    """Print the JSON Schema of the spec (every installed family's and generator's parameters)."""
    from .commands.catalog import schema_text

    text = schema_text(out_path, force)
    if not out_path:
        print(text)


@app.command()
@handled
def generate(
    generator: str = typer.Argument(..., metavar="NAME", help="generator name (see `dynmodel plugins`)"),
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
    from .commands.catalog import generate_recording

    result = generate_recording(generator, out_path, n, seed, param, plot, force)
    err.print(f"{n} samples of {generator} (seed {seed}) written to {out_path}", markup=False)
    if result.plot_path is not None:
        err.print(f"plot written to {result.plot_path}", markup=False)


def main() -> None:
    """Console entry point."""
    app()


if __name__ == "__main__":
    main()
