"""Ablation of thesis 6.4.5 (feed-forward control of the GMS friction plant): first the plant against
the thesis's published P-control and perfect-model figures, then the models, then how good a static
model has to be on this plant.

    python benchmarks/friction_ablation.py --plant [--rows ...] [--seeds 5]
    python benchmarks/friction_ablation.py --models [--rows ...] [--seeds 5] [--realizations 5]
    python benchmarks/friction_ablation.py --scaling [--rows esn] [--realizations 5]
    python benchmarks/friction_ablation.py --list

--plant: for every plant variant and reference seed 0 .. seeds-1, one 100 s tracking run (P-control
up to 50 s, then the perfect model's feed-forward, fig. 6.23), scored as `dynmodel control` does
(eq. 6.32 - 6.37, plain means over [20, 50) and [70, 100) s, MAX by std(P_r)); also max|e| / rms(e)
of the P-controlled error (its shape, independent of any normalisation) and the std of the control
force sigma_F (the thesis's NMSE_s of its perfect model, 1.5e-4 % for noise U[-0.05, 0.05], implies
sigma_F ~ 24 N). Cheap: seconds per run.

--models: every model row is fitted on the spec's data (training seed 1, test seed 2) with the model
seeds 0 .. seeds-1; NMSE_s / MAX_s on the test realization (eq. 6.30 / 6.31) and alpha / beta over
`--realizations` noise realizations on the control reference of seed 0 (as `dynmodel control`).
Slow: minutes per fit.

--scaling: for a fitted model M (seed 0), the feed-forward of M_s = (1 - s) M_perfect + s M for a range
of s: a model with the error structure of M whose static error is s times smaller (NMSE_s ~ s^2
NMSE_s(M)); shows which static accuracy this plant needs for alpha >= 99.5 %, beta >= 90 %.

Results are merged into --out (JSON) as rows finish. Prints figures; asserts nothing. Run with
OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 on a shared machine.
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dynmodel import control as ctl
from dynmodel import engine
from dynmodel.spec import parse_yaml, validate_spec

ROOT = Path(__file__).resolve().parents[1]
SPECS = ROOT / "specs"

#: thesis 6.4.5, friction system 1 (GMS): P-control and the perfect model M_perf^(1)
THESIS_PLANT = {"nmse_p": 0.89651, "max_p": 0.27981, "alpha": 99.992, "beta": 99.65}
THESIS_MODEL = {"nmse_s": 0.302, "max_s": 0.1587, "alpha": 99.76, "beta": 93.68}
PREVIOUS_REFERENCE = {"std": 0.05, "band": [0.05, 0.5]}


@dataclass
class PlantRow:
    key: str
    change: str
    params: dict[str, Any] = field(default_factory=dict)  # friction-plant parameters


PLANT_ROWS = [
    PlantRow("default", "the friction-plant defaults (reference std 6 cm over 0.05 - 1.2 Hz)"),
    PlantRow(
        "reference-0.5Hz-5cm",
        "the previous default reference: std 5 cm over 0.05 - 0.5 Hz",
        {"reference": PREVIOUS_REFERENCE},
    ),
    PlantRow(
        "reference-0.5Hz", "reference band 0.05 - 0.5 Hz (std 6 cm)", {"reference": {"std": 0.06, "band": [0.05, 0.5]}}
    ),
    PlantRow(
        "reference-1Hz", "reference band 0.05 - 1 Hz (std 6 cm)", {"reference": {"std": 0.06, "band": [0.05, 1.0]}}
    ),
    PlantRow(
        "reference-1.5Hz", "reference band 0.05 - 1.5 Hz (std 6 cm)", {"reference": {"std": 0.06, "band": [0.05, 1.5]}}
    ),
    PlantRow("reference-5cm", "reference std 5 cm (0.05 - 1.2 Hz)", {"reference": {"std": 0.05, "band": [0.05, 1.2]}}),
    PlantRow("reference-7cm", "reference std 7 cm (0.05 - 1.2 Hz)", {"reference": {"std": 0.07, "band": [0.05, 1.2]}}),
    PlantRow("noise-0", "no internal noise", {"noise": 0.0}),
    PlantRow(
        "contact-metal", "a metal contact: elements break away after 0.2 - 20 um", {"law": {"presliding": [2e-7, 2e-5]}}
    ),
    PlantRow("contact-1mm", "elements break away after 0.01 - 1 mm", {"law": {"presliding": [1e-5, 1e-3]}}),
    PlantRow("friction-x2", "twice the friction: F_c 40 N, F_s 44 N", {"law": {"coulomb": 40.0, "static": 44.0}}),
    PlantRow("stribeck-25N", "a larger Stribeck peak: F_s 25 N", {"law": {"static": 25.0}}),
    PlantRow("viscous-2", "ten times the viscous friction: sigma2 = 2 N s/m", {"law": {"viscous": 2.0}}),
]


@dataclass
class ModelRow:
    key: str
    change: str
    spec: str  # a spec in specs/
    params: dict[str, Any] = field(default_factory=dict)  # model.params overrides
    data: dict[str, Any] = field(default_factory=dict)  # data overrides ("params": plant parameters)


#: the annealed network's parameters before this ablation (readout without direct input links, input weights of std 1)
RNN_BEFORE = {"input_scale": 1.0, "readout": {"solver": "lstsq", "direct": False}}

MODEL_ROWS = [
    ModelRow(
        "rnn-before",
        "annealed network as shipped before, on the previous plant (reference std 5 cm over 0.05 - 0.5 Hz)",
        "thesis-6.4.5-rnn",
        RNN_BEFORE,
        data={"params": {"reference": PREVIOUS_REFERENCE}},
    ),
    ModelRow("rnn-before-new-plant", "the same network on the calibrated plant", "thesis-6.4.5-rnn", RNN_BEFORE),
    ModelRow(
        "rnn-direct",
        "+ direct input links in the readout (the inertial force m P'' is linear in the delay lines)",
        "thesis-6.4.5-rnn",
        {"input_scale": 1.0},
    ),
    ModelRow("rnn", "+ input weights of std 3 (`thesis-6.4.5-rnn` as shipped)", "thesis-6.4.5-rnn"),
    ModelRow(
        "rnn-copies",
        "the same network fed with the thesis's P, P(t-50), P(t-100) (`thesis-6.4.5-rnn-copies`)",
        "thesis-6.4.5-rnn-copies",
    ),
    ModelRow(
        "esn-previous-plant",
        "echo state network, 400 leaky elements, input weights of std 3 (as shipped before), on the previous plant",
        "thesis-6.4.5-esn",
        {"input_scale": 3.0},
        data={"params": {"reference": PREVIOUS_REFERENCE}},
    ),
    ModelRow("esn-input-3", "the same network on the calibrated plant", "thesis-6.4.5-esn", {"input_scale": 3.0}),
    ModelRow("esn", "+ input weights of std 30 (`thesis-6.4.5-esn` as shipped)", "thesis-6.4.5-esn"),
    ModelRow(
        "esn-input-30-1000",
        "+ 1000 elements",
        "thesis-6.4.5-esn",
        {"input_scale": 30.0, "size": 1000, "connectivity": 0.01},
    ),
    ModelRow(
        "esn-input-10-derived",
        "input weights of std 10, with the direction of motion and the travel since the last reversal as inputs",
        "thesis-6.4.5-esn",
        {"input_scale": 10.0},
        data={"derived_inputs": [{"direction": "position"}, {"since_reversal": "position"}]},
    ),
]
ALL_ROWS = {**{r.key: r for r in PLANT_ROWS}, **{r.key: r for r in MODEL_ROWS}}


DIGITS = {"alpha": 4, "beta": 2, "nmse_p": 3, "max_p": 3, "max_over_rms": 2, "sigma_f": 1, "nmse_ff": 4, "max_s": 3}


def _stats(values: list[float], key: str = "") -> str:
    v = np.asarray(values, dtype=float)
    d = DIGITS.get(key, 3)
    return f"{np.mean(v):.{d}f} ± {np.std(v):.{d}f}"


# ----------------------------------------------------------------------------- plant
def plant_run(params: dict[str, Any], seed: int) -> dict[str, float]:
    """One 100 s tracking run on reference ``seed``: P-control, then the perfect feed-forward."""
    plant, _ = ctl.make_plant("friction-plant", params)
    n, switch, skip = 100_000, 50_000, 20_000
    task = plant.tracking_task(n, np.random.default_rng(seed))
    trk = task.start(switch, np.random.default_rng([seed, 1]))
    pos, _ = trk.resume(task.perfect_feedforward())
    e = np.concatenate([trk.position, pos]) - task.reference
    out = ctl.criteria(task.reference, e, switch, skip)
    before = e[skip:switch]
    out["max_over_rms"] = float(np.max(np.abs(before)) / np.sqrt(np.mean(before**2)))
    out["sigma_f"] = float(np.std(trk.force[skip:switch]))
    return out


def plant_table(results: dict[str, list[dict[str, float]]]) -> str:
    keys = ("nmse_p", "max_p", "max_over_rms", "alpha", "beta", "sigma_f")
    lines = [
        "| plant | NMSE_P % | MAX_P | max/rms of e | perfect alpha % | perfect beta % | sigma_F (N) | command |",
        "|---|---|---|---|---|---|---|---|",
        "| thesis 6.4.5, friction system 1 | 0.8965 ± 0.00005 | 0.2798 ± 0.0004 | 2.95 | 99.992 ± 0.008 | 99.65 ± 0.02 | ~24 | |",
    ]
    for row in PLANT_ROWS:
        if row.key in results:
            runs = results[row.key]
            cells = " | ".join(_stats([r[k] for r in runs], k) for k in keys)
            lines.append(
                f"| `{row.key}`: {row.change} | {cells} | "
                f"`python benchmarks/friction_ablation.py --plant --rows {row.key} --seeds {len(runs)}` |"
            )
    return "\n".join(lines)


# ----------------------------------------------------------------------------- models
def model_spec(row: ModelRow, seed: int):
    path = SPECS / f"{row.spec}.yaml"
    raw = copy.deepcopy(parse_yaml(path.read_text(), str(path)))
    raw["seed"] = seed
    raw["model"].setdefault("params", {}).update(row.params)
    for k, v in row.data.items():
        if k == "params":
            raw["data"].setdefault("params", {}).update(v)
        else:
            raw["data"][k] = v
    return validate_spec(raw, f"ablation:{row.key}", SPECS)


def fit_model(row: ModelRow, seed: int):
    return engine.fit(model_spec(row, seed))


def control_report(model, realizations: int):
    data = model.spec["data"]
    plant, _ = ctl.make_plant(data["generator"], data.get("params") or {})
    return ctl.run(model, plant, ctl.Settings(realizations=realizations, workers=1)).summary()


def model_run(row: ModelRow, seed: int, realizations: int) -> dict[str, float]:
    model = fit_model(row, seed)
    test = model.metrics["test"]
    s = control_report(model, realizations)
    return {
        "nmse_s": float(test["nmse"]) if test["nmse"] is not None else float("inf"),
        "max_s": float(test["max"]) if test["max"] is not None else float("inf"),
        **{k: s["model"][k]["mean"] for k in ("nmse_p", "nmse_ff", "max_ff", "alpha", "beta")},
        "perfect_alpha": s["perfect"]["alpha"]["mean"],
        "perfect_beta": s["perfect"]["beta"]["mean"],
    }


def model_table(results: dict[str, list[dict[str, float]]]) -> str:
    keys = ("nmse_s", "max_s", "nmse_ff", "alpha", "beta")
    lines = [
        "| model | NMSE_s % | MAX_s | NMSE_ff % | alpha % | beta % | command |",
        "|---|---|---|---|---|---|---|",
        "| thesis 6.4.5: RNN, 27 elements | 0.302 | 0.159 | 0.00215 | 99.76 | 93.68 | |",
    ]
    for row in MODEL_ROWS:
        if row.key in results:
            runs = results[row.key]
            cells = " | ".join(_stats([r[k] for r in runs], k) for k in keys)
            lines.append(
                f"| `{row.key}`: {row.change} | {cells} | "
                f"`python benchmarks/friction_ablation.py --models --rows {row.key} --seeds {len(runs)}` |"
            )
    return "\n".join(lines)


# ----------------------------------------------------------------------------- error scaling
SCALES = (1.0, 0.7, 0.5, 0.4, 0.3, 0.2, 0.1)


def scaling(row: ModelRow, realizations: int) -> list[dict[str, float]]:
    """alpha / beta of (1 - s) M_perfect + s M for the model M of ``row`` (seed 0)."""
    model = fit_model(row, 0)
    nmse_s = float(model.metrics["test"]["nmse"])
    data = model.spec["data"]
    plant, _ = ctl.make_plant(data["generator"], data.get("params") or {})
    settings = ctl.Settings(realizations=realizations)
    n, switch, skip = (int(round(x / plant.sampling_time)) for x in (settings.duration, settings.switch, settings.skip))
    seq = np.random.SeedSequence([settings.seed, 0x636F6E74726F6C])  # the reference of `dynmodel control`
    ref_seq, *noise_seqs = seq.spawn(1 + realizations)
    task = plant.tracking_task(n, np.random.default_rng(ref_seq))
    ref = task.reference
    ff_model = model.run(np.repeat(ref[:, None], len(model.input_names), axis=1)).y[:, 0]
    ff_perfect = task.perfect_feedforward()
    runs = [task.start(switch, np.random.default_rng(noise_seqs[r])) for r in range(realizations)]
    out = []
    for s in SCALES:
        ff = ff_perfect + s * (ff_model - ff_perfect)
        crit = []
        for trk in runs:
            pos, _ = trk.resume(ff)
            crit.append(ctl.criteria(ref, np.concatenate([trk.position, pos]) - ref, switch, skip))
        out.append(
            {
                "s": s,
                "nmse_s": s * s * nmse_s,
                "alpha": float(np.mean([c["alpha"] for c in crit])),
                "beta": float(np.mean([c["beta"] for c in crit])),
            }
        )
    return out


def scaling_table(results: dict[str, list[dict[str, float]]]) -> str:
    lines = []
    for key, rows in results.items():
        lines += [
            f"`{key}` (`python benchmarks/friction_ablation.py --scaling --rows {key}`):",
            "",
            "| s | NMSE_s % (s² NMSE_s of the model) | alpha % | beta % |",
            "|---|---|---|---|",
        ]
        lines += [f"| {r['s']:g} | {r['nmse_s']:.3g} | {r['alpha']:.2f} | {r['beta']:.1f} |" for r in rows]
        lines.append("")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- main
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    what = ap.add_mutually_exclusive_group()
    what.add_argument("--plant", action="store_true")
    what.add_argument("--models", action="store_true")
    what.add_argument("--scaling", action="store_true")
    what.add_argument("--list", action="store_true")
    ap.add_argument("--rows", nargs="*", default=None)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--realizations", type=int, default=5)
    ap.add_argument("--out", type=Path, default=None, help="JSON file the results are merged into")
    ap.add_argument("--table", action="store_true", help="only print the tables of --out")
    args = ap.parse_args()
    if args.list:
        for r in PLANT_ROWS:
            print(f"--plant   {r.key:22s} {r.change}")
        for r in MODEL_ROWS:
            print(f"--models  {r.key:22s} {r.change}")
        return
    saved: dict[str, dict] = {"plant": {}, "models": {}, "scaling": {}}
    if args.out is not None and args.out.is_file():
        saved.update(json.loads(args.out.read_text()))
    if args.table:
        print(plant_table(saved["plant"]), "\n")
        print(model_table(saved["models"]), "\n")
        print(scaling_table(saved["scaling"]))
        return

    def save():
        if args.out is not None:
            args.out.write_text(json.dumps(saved, indent=1))

    if args.plant:
        rows = [r for r in PLANT_ROWS if args.rows is None or r.key in args.rows]
        for row in rows:
            t0 = time.perf_counter()
            saved["plant"][row.key] = [plant_run(row.params, seed) for seed in range(args.seeds)]
            save()
            print(f"  {row.key}: {time.perf_counter() - t0:.0f} s", flush=True)
        print(plant_table({r.key: saved["plant"][r.key] for r in rows}))
    elif args.models:
        rows = [r for r in MODEL_ROWS if args.rows is None or r.key in args.rows]
        for row in rows:
            t0 = time.perf_counter()
            runs = []
            for seed in range(args.seeds):
                runs.append(model_run(row, seed, args.realizations))
                r = runs[-1]
                print(
                    f"  {row.key} seed {seed}: NMSE_s {r['nmse_s']:.3f} %, alpha {r['alpha']:.2f} %, "
                    f"beta {r['beta']:.1f} %",
                    flush=True,
                )
            saved["models"][row.key] = runs
            save()
            print(f"  {row.key}: {(time.perf_counter() - t0) / args.seeds:.0f} s per seed", flush=True)
        print(model_table({r.key: saved["models"][r.key] for r in rows}))
    elif args.scaling:
        rows = [r for r in MODEL_ROWS if (args.rows or ["esn"]).count(r.key)]
        for row in rows:
            saved["scaling"][row.key] = scaling(row, args.realizations)
            save()
        print(scaling_table({r.key: saved["scaling"][r.key] for r in rows}))
    else:
        ap.print_help()


if __name__ == "__main__":
    main()
