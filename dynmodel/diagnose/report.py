"""The diagnosis as files: a Markdown report with PNG figures (opens offline), the extended spec as
YAML (runnable with ``dynmodel fit``) and the JSON summary."""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..paths import umask
from . import figures
from .context import segments_of
from .gain import test_key
from .runner import Diagnosis, fitted_family

REPORT = "index.md"
EXTENDED = "extended.yaml"
#: every file a report may hold (a previous report's files that the new one does not write are removed)
FIGURES = ("fit.png", "residual.png", "correlation.png", "spectrum.png", "loops.png", "before_after.png")


def jsonable(obj: Any) -> Any:
    """Plain JSON: numpy scalars and arrays converted, non-finite numbers as null."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def write_json(result: Diagnosis, path: Path) -> Path:
    """The diagnosis as JSON (NaN and inf as null), through a temporary file and a rename."""
    from ..paths import write_json as write_payload

    return write_payload(path, jsonable(result.to_json()), allow_nan=False)


def extended_spec(result: Diagnosis, folder: Path) -> dict[str, Any] | None:
    """The extended spec mapping, named ``<name>-extended`` and writing its model next to the YAML."""
    raw = result.extended_spec
    if raw is None:
        return None
    from ..paths import safe_name

    out = dict(raw)
    name = f"{safe_name(result.name)}-extended"
    out["name"] = name
    out["output"] = str((folder / f"{name}.h5").resolve())
    return out


def write_extended(result: Diagnosis, folder: Path, place: Path) -> Path | None:
    """``extended.yaml`` in ``folder``; ``place``: the folder the report ends up in (where the spec's model
    goes), when ``folder`` is a temporary one."""
    spec = extended_spec(result, place)
    if spec is None:
        return None
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / EXTENDED
    head = (
        f"# written by dynmodel diagnose: {result.name} extended for "
        f"{', '.join(c.cause for c in result.applied)}\n# run it with: dynmodel fit {path.name}\n"
    )
    path.write_text(head + yaml.safe_dump(jsonable(spec), sort_keys=False))
    return path


def _fmt(v: Any, digits: int = 4) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        if not math.isfinite(v):
            return "diverged" if v > 0 else "–"
        return f"{v:.{digits}g}"
    return str(v)


def _metrics_rows(metrics: dict[str, Any]) -> list[str]:
    rows = []
    for split in ("train", "validation", "test"):
        m = metrics.get(split)
        if m is None:
            continue
        if m.get("unstable_from"):
            u = m["unstable_from"]
            rows.append(
                f"| {split} | {m['samples']} | unstable from t = {u['time']:.6g} s (sample {u['sample']}) | – | "
                f"{_fmt(m.get('nmse_1'))} |"
            )
        else:
            rows.append(
                f"| {split} | {m['samples']} | {_fmt(m.get('nmse'))} | {_fmt(m.get('max'))} | {_fmt(m.get('nmse_1'))} |"
            )
    return rows


def _p(evidence: dict[str, Any]) -> str:
    p = evidence.get("p_value")
    return "–" if p is None else f"{p:.2g}"


def _gain_lines(gain: dict[str, Any] | None) -> list[str]:
    if not gain:
        return ["No extension was measured."]
    before, after = gain.get("test_nmse_before"), gain.get("test_nmse_after")
    red = gain.get("relative_reduction")
    lines = [
        "| | baseline | extended |",
        "|---|---|---|",
        f"| test NMSE % | {'diverged' if gain.get('baseline_diverged_on_test') else _fmt(before)} | "
        f"{'diverged' if gain.get('extended_diverged_on_test') else _fmt(after)} |",
        f"| test MAX | {_fmt(gain.get('test_max_before'))} | {_fmt(gain.get('test_max_after'))} |",
        "",
    ]
    if red is not None:
        lines.append(f"Relative reduction of the test NMSE: **{100 * red:.1f} %**.")
    elif gain.get("baseline_diverged_on_test") and not gain.get("extended_diverged_on_test"):
        lines.append("The baseline's free run diverges on the test split; the extended model's stays finite.")
    elif gain.get("extended_diverged_on_test"):
        lines.append("The extended model's free run diverges on the test split too: no gain.")
    unc = gain.get("uncertainty") or {}
    if "per_output" in unc:
        unc = unc["per_output"][0]
    if unc.get("relative_reduction"):
        rr = unc["relative_reduction"]
        text = f"Uncertainty ({unc.get('method')}): reduction {_pct(rr.get('mean'))} ± {_pct(rr.get('std'))}"
        if rr.get("interval_95"):
            lo, hi = rr["interval_95"]
            text += f", 95 % interval [{_pct(lo)}, {_pct(hi)}]"
        if rr.get("values"):
            text += f", per seed {', '.join(_pct(v) for v in rr['values'])}"
        tb, ta = unc.get("test_nmse_before") or {}, unc.get("test_nmse_after") or {}
        text += (
            f"; test NMSE {_fmt(tb.get('mean'))} ± {_fmt(tb.get('std'))} % before, "
            f"{_fmt(ta.get('mean'))} ± {_fmt(ta.get('std'))} % after."
        )
        lines.append(text)
    elif unc.get("method"):
        lines.append(f"Uncertainty: {unc['method']}.")
    if gain.get("note"):
        lines.append(gain["note"])
    return lines


def _pct(v: Any) -> str:
    return "–" if v is None else f"{100 * v:.1f} %"


def write_report(result: Diagnosis, folder: Path, place: Path) -> Path:
    """index.md and the figures in ``folder``; returns the index path. ``place``: the folder the report ends
    up in, when ``folder`` is a temporary one (:func:`write_report_folder`)."""
    folder.mkdir(parents=True, exist_ok=True)
    base = result.baseline
    checks = {f.cause: f for f in result.checks if f.applicable}
    alpha = result.settings.alpha
    memory = result.rounds[0].memory
    drift = checks.get("sensor-drift")
    delay = checks.get("missing-delay")
    osc = checks.get("unmodeled-oscillation")
    curve = checks.get("static-nonlinearity")
    windows = figures.overview(folder / "fit.png", base, f"{result.name}: baseline free run")
    figures.residual(
        folder / "residual.png",
        base,
        drift.evidence if drift and drift.significant else None,
        "residual of the baseline's free run",
    )
    longest = max((s.n for s in segments_of(base)), default=10)
    max_lag = int(result.settings.max_lag or max(1, min(1000, longest // 5)))
    figures.correlations(folder / "correlation.png", base, max_lag, alpha, delay.evidence if delay else None, memory)
    figures.spectrum(folder / "spectrum.png", base, alpha, osc.evidence if osc and osc.significant else None)
    figures.loops(folder / "loops.png", base, curve.evidence if curve and curve.significant else None)
    final = result.final
    if final is not None and result.gain:
        figures.before_after(folder / "before_after.png", base, final, result.gain)

    spec = base.spec
    lines = [f"# Diagnosis of `{result.name}`", ""]
    if result.findings:
        top = result.findings[0]
        lines += [f"**Named cause: `{top.cause}`** (score {top.score:.3g}) — {top.summary}.", ""]
    else:
        lines += ["**Adequate**: no cause is significant; nothing is proposed.", ""]
    lines += [
        f"Model `{fitted_family(base)}`, cost `{base.model.spec.get('cost') or spec.cost}`, {base.ds.n_loaded} "
        "recording(s), inputs "
        f"{base.model.input_names}, output {base.model.output_names}, sampling time {base.ds.sampling_time:g} s; "
        f"model memory {memory if memory is not None else '–'} samples. Diagnosis took {result.seconds:.1f} s.",
        "",
        *([f"**Warning:** {result.extended_warning()}", ""] if result.extended_warning() else []),
        "## Baseline",
        "",
        "| split | samples | NMSE % | MAX | NMSE one-step % |",
        "|---|---|---|---|---|",
    ]
    lines += _metrics_rows(base.metrics)
    lines += ["", "![measured vs free run, worst windows marked](fit.png)", ""]
    if windows:
        lines.append(
            "Worst windows (largest mean squared error): "
            + ", ".join(f"[{a:.6g}, {b:.6g}] s" for a, b in windows)
            + "."
        )
        lines.append("")
    ref = (result.reference or {}).get("linear")
    if ref:
        nm = ", ".join(f"{k} {_fmt(v)} %" for k, v in ref["nmse"].items())
        lines += [
            f"Adequacy reference: a linear {ref['method']} model (output lags 1..{ref['output_order']}, input lags "
            f"0..{ref['input_order'] - 1}) runs free with NMSE {nm}; the training mean gives "
            + ", ".join(f"{k} {_fmt(v)} %" for k, v in (result.reference or {}).get("mean", {}).get("nmse", {}).items())
            + ".",
            "",
        ]
    lines += ["## Findings", ""]
    if result.findings:
        lines += ["| # | cause | score | p | evidence | extension |", "|---|---|---|---|---|---|"]
        for i, f in enumerate(result.findings, 1):
            ext = f.extension.summary if f.extension else "–"
            lines.append(f"| {i} | `{f.cause}` | {f.score:.3g} | {_p(f.evidence)} | {f.summary} | {ext} |")
    else:
        lines.append("None significant.")
    if len(result.rounds) > 1 or result.rounds[0].chosen is not None:
        lines += [
            "",
            "## Rounds",
            "",
            "| round | named | extension applied | comparison NMSE % | test NMSE % |",
            "|---|---|---|---|---|",
        ]
        for rnd in result.rounds:
            g = rnd.gain()
            named = ", ".join(f"`{f.cause}`" for f in rnd.significant) or "adequate"
            ext = f"{g['extension']} (for `{g['cause']}`)" if g.get("extension") and rnd.accepted else "–"
            cmp_ = f"{_fmt(g.get('nmse_before'))} → {_fmt(g.get('nmse_after'))}" if g.get("extension") else "–"
            test = (
                f"{_fmt(g.get('test_nmse_before'))} → {_fmt(g.get('test_nmse_after'))}" if g.get("extension") else "–"
            )
            lines.append(f"| {rnd.index} | {named} | {ext} | {cmp_} | {test} |")
    lines += [
        "",
        "Score: the share of the free-run residual's mean square the cause accounts for (1: the free run "
        "as a whole is invalid). A cause is named when p < alpha "
        f"({alpha:g}), its score is at least {result.settings.min_share:g} and it accounts for at least "
        f"{100 * result.settings.min_effect:g} % of the output variance.",
        "",
        "### Every check",
        "",
        "| cause | named | score | p | why (not) named | summary |",
        "|---|---|---|---|---|---|",
    ]
    for f in result.checks:
        p = f.gates.get("p_value", f.evidence.get("p_value"))
        lines.append(
            f"| `{f.cause}` | {'yes' if f.significant else 'no'} | {f.score:.3g} | "
            f"{'–' if p is None else f'{p:.2g}'} | {f.reason} | {f.summary if f.applicable else '–'} |"
        )
    lines += [
        "",
        "![residual over time](residual.png)",
        "",
        "![residual auto- and cross-correlation with 99 % bounds](correlation.png)",
        "",
        "![residual spectrum](spectrum.png)",
        "",
        "![output against input](loops.png)",
        "",
    ]
    if result.rounds[0].candidates:
        lines += ["## Extensions measured", ""]
        for rnd in result.rounds:
            if not rnd.candidates:
                continue
            split = "validation" if "validation" in rnd.fit.metrics else "train"
            lines += [
                f"Round {rnd.index} ({rnd.verdict}; chosen on the {split} NMSE): {rnd.outcome}.",
                "",
                f"| extension | {split} NMSE % | test NMSE % | test MAX |",
                "|---|---|---|---|",
            ]
            for c in rnd.candidates:
                mark = " **(chosen)**" if c is rnd.chosen else ""
                if c.fit is None:
                    lines.append(f"| {c.extension.summary}{mark} | failed: {c.error} | – | – |")
                else:
                    scores = c.fit.metrics.get(test_key(c.fit.metrics) or "test") or {}
                    lines.append(
                        f"| {c.extension.summary}{mark} | {_fmt(c.score(split))} | "
                        f"{_fmt(scores.get('nmse')) if scores.get('nmse') is not None else 'diverged'} | "
                        f"{_fmt(scores.get('max'))} |"
                    )
            lines.append("")
        lines += ["## Gain on the held-out test split", ""] + _gain_lines(result.gain) + [""]
        if final is not None and result.gain:
            lines += ["![before and after](before_after.png)", ""]
        extended = extended_spec(result, place)
        if extended is not None:
            lines += [
                f"## Extended spec (`{EXTENDED}`, run with `dynmodel fit {EXTENDED}`)",
                "",
                "```yaml",
                yaml.safe_dump(jsonable(extended), sort_keys=False).rstrip(),
                "```",
                "",
            ]
    if result.notes:
        lines += ["## Notes", ""] + [f"- {n}" for n in result.notes] + [""]
    path = folder / REPORT
    path.write_text("\n".join(lines))
    return path


def write_report_folder(result: Diagnosis, folder: Path) -> tuple[Path, Path | None]:
    """The report (index.md, figures, extended.yaml) written into a temporary sibling of ``folder`` and moved
    into place at the end, so that an interrupted write (Ctrl-C, a full disk) leaves ``folder`` as it was: a
    new or empty ``folder`` is replaced by the finished report in one rename; into an existing one (a previous
    report, or any folder with ``--force``, as :func:`dynmodel.paths.check_output` allowed) each file is moved,
    ``index.md`` last, and a previous report's files that this one does not write are removed (other files
    stay). Returns (index path, extended spec path or None)."""
    folder = Path(folder)
    final = folder.resolve()
    parent = final.parent
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name[:100]}.", suffix=".tmp", dir=parent))
    try:
        os.chmod(tmp, 0o777 & ~umask())  # the permissions of any new folder, not mkdtemp's private 0700
        write_report(result, tmp, final)
        extended = write_extended(result, tmp, final)
        written = sorted(p.name for p in tmp.iterdir())
        placed = False
        if not final.exists() or (final.is_dir() and not any(final.iterdir())):
            try:
                os.replace(tmp, final)  # onto a missing or empty folder: one rename
                placed = True
            except OSError:
                placed = False  # e.g. a file appeared in it meanwhile: move the files one by one
        if not placed:
            final.mkdir(parents=True, exist_ok=True)
            previous = (final / REPORT).is_file()
            for name in [n for n in written if n != REPORT] + [REPORT]:
                os.replace(tmp / name, final / name)
            if previous:  # the previous report's figures and extended spec that this report does not have
                for name in (*FIGURES, EXTENDED):
                    if name not in written and (final / name).is_file():
                        (final / name).unlink()
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return folder / REPORT, (folder / EXTENDED if extended is not None else None)
