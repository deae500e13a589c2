"""Thesis chapter 6 with dynmodel: pre-sliding (6.2) and sliding (6.3) cross-prediction, feed-forward
control of a GMS plant (6.4.5), and the real EMPS benchmark; writes the README figures.

    python benchmarks/friction_reproduction.py --control       # 6.4.5: fit, NMSE_s / MAX_s, alpha / beta (20 realizations)
    python benchmarks/friction_reproduction.py --presliding    # 6.2: NARX and networks, test NMSE / MAX
    python benchmarks/friction_reproduction.py --sliding       # 6.3
    python benchmarks/friction_reproduction.py --emps          # EMPS: vir -> qm (RMSE, fit) and qm -> vir
    python benchmarks/friction_reproduction.py --all --figures docs/friction

Models are fitted from the specs in specs/ (seed 0, as written) and saved next to --out. Prints
figures; asserts nothing. Run with OPENBLAS_NUM_THREADS=1 on a shared machine.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import dynmodel
from dynmodel import control as ctl
from dynmodel import engine
from dynmodel.data import load_dataset
from dynmodel.spec import load_spec

ROOT = Path(__file__).resolve().parents[1]
SPECS = ROOT / "specs"


def fit(name: str, out: Path, figures: Path | None):
    """Fit specs/<name>.yaml, save the model, optionally plot the test free run; returns the model."""
    spec = load_spec(SPECS / f"{name}.yaml")
    t0 = time.perf_counter()
    ds = load_dataset(spec)
    model, runs = engine.fit_dataset(spec, ds)
    dynmodel.save(model, out / f"{name}.h5")
    m = model.metrics
    line = "  ".join(
        f"{split} NMSE {m[split]['nmse']:.4g} % MAX {m[split]['max']:.3g}"
        if m[split].get("nmse") is not None
        else f"{split} unstable"
        for split in ("train", "validation", "test")
        if split in m
    )
    extra = ""
    if "rmse" in m.get("test", {}):
        extra = f"  test RMSE {m['test']['rmse']:.4g}, fit {m['test']['fit']:.2f} %"
    print(f"  {name:32s} {line}{extra}  ({time.perf_counter() - t0:.0f} s)", flush=True)
    if figures is not None:
        from dynmodel.commands.fit import plot_fit

        plot_fit(figures / f"{name}.png", ds, runs, model, name)
    return model


def presliding(out: Path, figures: Path | None) -> None:
    print("thesis 6.2, pre-sliding (GMS, 250 Hz, 8000 train / 8000 validation / 8000 test), free run:")
    for name in ("thesis-6.2-presliding-narx", "thesis-6.2-presliding-rnn", "thesis-6.2-presliding-esn"):
        fit(name, out, figures)
    print("  thesis (measured data): NARX 2.49 % / 0.41, RNN 0.86 % / 0.41")


def sliding(out: Path, figures: Path | None) -> None:
    print("thesis 6.3, sliding with fast oscillations (2500 Hz, 72000 / 18000 / 20000), free run:")
    for name in ("thesis-6.3-sliding-narx", "thesis-6.3-sliding-rnn", "thesis-6.3-sliding-esn"):
        fit(name, out, figures)
    print("  thesis (measured data): NARX 1.11 % / 0.49 (free-run optimized), RNN 0.13 % / 0.2")


def control(out: Path, figures: Path | None, realizations: int) -> dict:
    print(f"thesis 6.4.5, GMS plant, feed-forward control ({realizations} noise realizations):")
    results = {}
    for name in ("thesis-6.4.5-rnn", "thesis-6.4.5-esn", "thesis-6.4.5-rnn-copies"):
        model = fit(name, out, figures)
        data = model.spec["data"]
        plant, params = ctl.make_plant(data["generator"], data["params"])
        t0 = time.perf_counter()
        report = ctl.run(model, plant, ctl.Settings(realizations=realizations))
        s = report.summary()
        results[name] = {"static_test": model.metrics["test"], **report.to_json()}

        def fmt(stats, c):
            mean = f"{stats[c]['mean']:.3f}" if c in ("alpha", "beta") else f"{stats[c]['mean']:.4g}"
            return f"{ctl.LABELS[c]} {mean} ± {stats[c]['std']:.2g}"

        row = "  ".join(fmt(s["model"], c) for c in ctl.CRITERIA)
        print(f"    control: {row}  ({time.perf_counter() - t0:.0f} s)")
        perf = "  ".join(fmt(s["perfect"], c) for c in ("nmse_ff", "max_ff", "alpha", "beta"))
        print(f"    perfect model: {perf}")
        if figures is not None:
            from dynmodel.plots import tracking_error

            ser = report.series
            tracking_error(
                figures / f"{name}-control.png",
                ser["t"],
                ser["reference"],
                ser["error_model"],
                ser["error_perfect"],
                50.0,
                20.0,
                f"{name}: alpha {s['model']['alpha']['mean']:.4g} %, beta {s['model']['beta']['mean']:.4g} %",
            )
    print(
        "  thesis: NMSE_s 0.302 %, MAX_s 0.159; NMSE_P 0.897 %, NMSE_ff 2.15e-3 %, alpha 99.76 %, beta 93.68 %;"
        " perfect: alpha 99.992 %, beta 99.65 %"
    )
    (out / "control.json").write_text(json.dumps(results, indent=2) + "\n")
    return results


def emps_physical() -> None:
    """Baseline: M q'' + F_v q' + F_c sign(q') + offset = gtau vir, least squares on filtered
    derivatives of the training file (IDIM-style), simulated open loop from vir on the test file."""
    import scipy.io
    from scipy.signal import butter, filtfilt

    folder = ROOT.parent / "shared" / "data" / "emps"
    train, test = (scipy.io.loadmat(folder / f) for f in ("DATA_EMPS.mat", "DATA_EMPS_PULSES.mat"))
    h, gtau = 1e-3, float(np.ravel(train["gtau"])[0])
    q, u = np.ravel(train["qm"]).astype(float), np.ravel(train["vir"]).astype(float)
    b, a = butter(4, 20 * 2 * h)  # 20 Hz
    qd = np.gradient(filtfilt(b, a, q), h)
    qdd = np.gradient(qd, h)
    X = np.column_stack([qdd, qd, np.sign(qd), np.ones_like(q)])[100:-100]
    M, Fv, Fc, off = np.linalg.lstsq(X, gtau * u[100:-100], rcond=None)[0]
    qt, ut = np.ravel(test["qm"]).astype(float), np.ravel(test["vir"]).astype(float)
    sim = np.empty_like(qt)
    sim[:2] = qt[:2]
    for t in range(2, len(qt)):
        v = (sim[t - 1] - sim[t - 2]) / h
        sim[t] = 2 * sim[t - 1] - sim[t - 2] + h * h * (gtau * ut[t - 1] - Fv * v - Fc * np.sign(v) - off) / M
    rmse = float(np.sqrt(np.mean((sim[20:] - qt[20:]) ** 2)))
    print(
        f"  physical model (M {M:.1f} kg, F_v {Fv:.1f} N s/m, F_c {Fc:.1f} N, offset {off:.2f} N), open loop: "
        f"test RMSE {rmse:.4g}, fit {100 * (1 - rmse / np.std(qt[20:])):.2f} %"
    )


def emps(out: Path, figures: Path | None) -> None:
    print("EMPS (real data): train DATA_EMPS, test DATA_EMPS_PULSES, first 20 test samples for the state:")
    fit("emps-benchmark-narx", out, figures)
    emps_physical()
    print(
        "  published: dynoNet fit 96.8 % (RMSE about 2.64e-3 m); best linear model fit 25.4 %; "
        "NN baselines RMSE 0.074 - 0.22 m"
    )
    fit("emps-cross-esn", out, figures)


def data_figures(figures: Path) -> None:
    """Force against position for the three regimes (fig. 6.5 / 6.8 / 6.11 / 6.22)."""
    from dynmodel import registry
    from dynmodel.plots import recording

    for name, spec_name, n in (
        ("presliding", "thesis-6.2-presliding-narx", 24000),
        ("sliding", "thesis-6.3-sliding-narx", 25000),
        ("plant", "thesis-6.4.5-rnn", 20000),
    ):
        spec = load_spec(SPECS / f"{spec_name}.yaml")
        gen = registry.source(spec.data.generator)
        params = spec.data.params
        u, y = gen.generate(params, n, np.random.default_rng(spec.data.seed))
        t = np.arange(n) * gen.sampling_time(params)
        recording(
            figures / f"data-{name}.png",
            t,
            u,
            y,
            list(gen.input_names),
            list(gen.output_names),
            f"{spec.data.generator} as in {spec_name}.yaml (seed {spec.data.seed})",
        )
    # non-local memory of pre-sliding hysteresis: nested loops (fig. 6.2 / 6.5)
    from dynmodel_plugins.friction.trajectories import Trajectory

    gen = registry.source("gms")
    params = gen.Params.model_validate(
        {
            "trajectory": {
                "kind": "reversals",
                "speed": 5e-6,
                "points": [0, 15e-6, -15e-6, 10e-6, -5e-6, 5e-6, -10e-6, 15e-6],
            },
            "sampling_time": 0.01,
            "position_unit": "um",
        }
    )
    n = int(Trajectory(params.trajectory, np.random.default_rng(0)).total_duration / 0.01) + 50
    u, y = gen.generate(params, n, np.random.default_rng(0))
    recording(
        figures / "data-memory.png",
        np.arange(n) * 0.01,
        u,
        y,
        ["position (um)"],
        ["force (N)"],
        "GMS pre-sliding hysteresis: inner loops close onto the outer loop (non-local memory)",
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presliding", action="store_true")
    ap.add_argument("--sliding", action="store_true")
    ap.add_argument("--control", action="store_true")
    ap.add_argument("--emps", action="store_true")
    ap.add_argument("--all", action="store_true")
    ap.add_argument("--realizations", type=int, default=20)
    ap.add_argument(
        "--out",
        type=Path,
        default=ROOT / "out" / "friction",
        help="folder for model files and JSON (out/ is ignored by git)",
    )
    ap.add_argument("--figures", type=Path, default=None, help="folder for PNG figures")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.figures is not None:
        args.figures.mkdir(parents=True, exist_ok=True)
        data_figures(args.figures)
    t0 = time.perf_counter()
    if args.presliding or args.all:
        presliding(args.out, args.figures)
    if args.sliding or args.all:
        sliding(args.out, args.figures)
    if args.control or args.all:
        control(args.out, args.figures, args.realizations)
    if args.emps or args.all:
        emps(args.out, args.figures)
    print(f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
