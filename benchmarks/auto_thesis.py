"""family: auto on the thesis experiments' data, next to the model the thesis chose for each by hand.

    python benchmarks/auto_thesis.py                          # every case (about 15 min on 2 cores)
    python benchmarks/auto_thesis.py --only thesis-6.3-sliding-esn --families narx esn annealed-rnn

Each case is one of the ``specs/thesis-*.yaml`` specs (one per data set): its data section as written (the
generator, the splits, the noise added to the training outputs, the separate test recording), with the
expert's data-side choices removed (``delay_lines``, ``delay_form``, ``derived_inputs``, ``scaling``: a new
user does not know them; the search offers its own), and ``model: {family: auto}`` with the default budget
instead of the spec's pinned model. The pinned model is the expert's: a NARX model with the system's own
terms (3.2), a network sized and scaled as the thesis did (4.4, 5.3, 6.x), often with delay lines chosen for
the data.

Printed per case: the test NMSE (%) of the expert's spec as written and of ``family: auto``, their ratio, the
wall times and the model auto chose. A ratio near or below 1 means that one command gave the expert's model
(or better) on that data. Asserts nothing; the data come from fixed seeds.
"""

from __future__ import annotations

import argparse
import copy
import json
from pathlib import Path
from typing import Any

import yaml
from auto_small_data import fit_timed

ROOT = Path(__file__).resolve().parents[1]
SPECS = ROOT / "specs"

#: one spec per data set (the others of a section share its data)
CASES = (
    "thesis-3.2.2-linear",
    "thesis-3.2.3-logistic",
    "thesis-3.2.4-narx",
    "thesis-3.2.4-narx-noise",
    "thesis-4.4.2-parallel",
    "thesis-5.3.2-external",
    "thesis-5.3.2-noise",
    "thesis-5.3.3-fos",
    "thesis-5.3.4-random-esn",
    "thesis-6.2-presliding-esn",
    "thesis-6.3-sliding-esn",
    "thesis-6.4.5-esn",
)
#: data-side choices of the expert, not given to the search
EXPERT_DATA = ("delay_lines", "delay_form", "derived_inputs", "scaling")


def auto_spec(raw: dict[str, Any], families: list[str] | None, budget: float | None) -> dict[str, Any]:
    """``raw`` with ``family: auto`` and without the expert's model, cost and data-side choices."""
    out = copy.deepcopy(raw)
    for key in EXPERT_DATA:
        out["data"].pop(key, None)
    params: dict[str, Any] = {}
    if families:
        params["families"] = families
    if budget is not None:
        params["budget"] = budget
    out["model"] = {"family": "auto", **({"params": params} if params else {})}
    out.pop("cost", None)
    return out


def _test(model) -> float | None:
    return (model.metrics.get("test") or {}).get("nmse")


def _fmt(value: float | None) -> str:
    """A figure for the table; "-" where a model has no test figure."""
    return "-" if value is None else f"{value:.4g}"


def run_case(name: str, args) -> dict[str, Any]:
    raw = yaml.safe_load((SPECS / f"{name}.yaml").read_text())  # generated data: no path to resolve
    raw.pop("output", None)
    expert, expert_s = fit_timed(copy.deepcopy(raw), 1)
    auto, auto_s = fit_timed(auto_spec(raw, args.families, args.budget), args.workers)
    return {
        "case": name,
        "expert": _test(expert),
        "expert_model": raw["model"]["family"],
        "expert_seconds": expert_s,
        "auto": _test(auto),
        "auto_validation": (auto.metrics.get("validation") or {}).get("nmse"),
        "auto_seconds": auto_s,
        "chosen": (auto.search or {}).get("winner_summary") or auto.family.name,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="*", choices=list(CASES), help="cases (default: all)")
    ap.add_argument("--budget", type=float, help="search budget in seconds (default: auto's own, 300)")
    ap.add_argument("--workers", type=int, help="parallel fits of the search (default: one per core)")
    ap.add_argument("--families", nargs="*", help="families auto searches (default: every installed one)")
    ap.add_argument("--json", type=Path, help="write every figure as JSON")
    args = ap.parse_args()
    rows = []
    print(f"{'case':26s} {'expert':>10s} {'auto':>10s} {'x expert':>8s} {'expert s':>8s} {'auto s':>7s}  chosen")
    for name in args.only or CASES:
        row = run_case(name, args)
        rows.append(row)
        ratio = row["auto"] / row["expert"] if row["auto"] is not None and row["expert"] else float("nan")
        print(
            f"{name:26s} {_fmt(row['expert']):>10s} {_fmt(row['auto']):>10s} {ratio:8.2f} "
            f"{row['expert_seconds']:8.0f} {row['auto_seconds']:7.0f}  {row['chosen']}",
            flush=True,
        )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
