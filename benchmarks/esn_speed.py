"""ESN speed and memory: drive microseconds per step, fit time and peak memory, side by side in one run.

1. Drive speed, on the same random sparse network (connection probability 2/M, input 0.1, bias
   0.8, sigma(C) = 0.95) and the same narx-system input, M = 200 (N = 10 000) and M = 1000
   (N = 100 000): dynmodel's compiled kernels (the chunked drive the fit runs, the same drive
   storing every state in a fresh N x M array as fits did before, the external-mode free run), a
   plain numpy loop ``x = tanh(C @ x + c0 + B u_t)`` with C dense and as a scipy CSR matrix, and
   reservoirpy's ``Reservoir.run`` when it is importable.
2. Fit of a 1000-element internal-mode ESN (default readout: FOS stopped on a 20 % validation
   split) at N = 100 000 and 1 000 000 samples, each in a fresh process: seconds and peak resident
   memory, for the streamed fit (moments accumulated chunk by chunk, ``dynmodel.fit``) and for the
   stored-states fit (every state kept, then the array solvers: the algorithm before issue 20; at
   N = 1e6 only with ``--stored-1e6``, it needs about 15 GB), and reservoirpy's
   ``Reservoir >> Ridge`` fit at N = 100 000.
3. Agreement of the streamed readout with the stored-states readout (M = 1000, N = 20 000), for
   every solver: the largest difference of the validation predictions (relative to the output
   std) and the validation NMSE, next to the rounding floor: the stored-states fit against itself
   with its QR run in chunks of 300 rows (the same arithmetic in another order). States of random
   1000-element networks are so collinear that float64 determines the least-squares readout only
   to about 1e-6 and FOS's term choice not at all on near ties.

Times are wall clock and, in brackets, CPU time of the process (less inflated on a busy machine).
Prints figures; asserts nothing.

    python benchmarks/esn_speed.py            # everything (about 10 minutes on a quiet 2-core machine)
    python benchmarks/esn_speed.py --quick    # M = 200 speed, the N = 1e5 fits, agreement at N = 5000
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from dynmodel import kernels

try:  # optional peer
    from reservoirpy.nodes import Reservoir, Ridge
except Exception:  # noqa: BLE001
    Reservoir = None

SOLVERS = ("lstsq", "ridge", "fos")


def timed(fn, repeats: int = 3) -> tuple[float, float]:
    """Shortest wall-clock and CPU seconds of ``repeats`` calls of ``fn()``."""
    wall = cpu = float("inf")
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall, cpu = min(wall, time.perf_counter() - w0), min(cpu, time.process_time() - c0)
    return wall, cpu


def peak_mb() -> float:
    """Peak resident memory of this process (VmHWM: unlike ru_maxrss, it does not inherit the
    parent's peak across fork and exec)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def numpy_loop(C, B, c0, U, steps):
    x = np.zeros(C.shape[0])
    X = np.empty((steps, C.shape[0]))
    for t in range(steps):
        x = np.tanh(C @ x + c0 + B @ U[t])
        X[t] = x
    return X


def _net(m: int, mode: str = "external"):
    from dynmodel_plugins.esn.network import build_network
    from dynmodel_plugins.esn.params import EsnParams

    # the plain network of the docstring (5.3.2 elements, input 0.1), which the numpy loop also runs;
    # since issue 14 the family's defaults are leaky elements with input to half of them
    params = EsnParams(size=m, mode=mode, relaxation=0.0, relaxation_gain=False, input_connectivity=0.1)
    return build_network(params, 1, 1, np.random.default_rng(0))


# ------------------------------------------------------------------ 1. drive speed


def speed(m: int, n: int) -> None:
    from dynmodel.moments import chunk_rows
    from dynmodel_plugins.generators.maps import NarxSystem

    u, y = NarxSystem.generate(NarxSystem.Params(), n, np.random.default_rng(1))
    net = _net(m)
    args = net.kernel_args()
    internal = (*args[:3], np.ascontiguousarray(net.B_in), *args[4:])
    rows = chunk_rows(m + 2)
    buf = np.empty((rows, m + 1))

    def chunked():
        x = np.zeros(m)
        for a in range(0, n, rows):
            kernels.drive_chunk(*internal, u[a : a + rows], x, True, buf[: min(rows, n - a)])

    kernels.drive(*internal, u[:10], np.zeros(m))  # compile outside the timing
    chunked()
    per = 1e6 / n
    t_chunk = timed(chunked)
    t_store = timed(lambda: kernels.drive(*internal, u, np.zeros(m)))
    W = 0.01 * np.random.default_rng(2).standard_normal((1, m))
    D, w0, lo, hi = np.zeros((1, 2)), np.zeros(1), np.full(1, -1e12), np.full(1, 1e12)

    def free():
        kernels.free_run(*args, u, np.zeros((0, 1)), 0, 0.0, W, D, w0, np.zeros(1), lo, hi, np.zeros(m), False)

    free()
    t_free = timed(free)
    steps = min(n, 20000)
    dense = net.C.toarray()
    t_dense = timed(lambda: numpy_loop(dense, net.B_in, net.c0, u, steps), 2)
    t_csr = timed(lambda: numpy_loop(net.C, net.B_in, net.c0, u, steps), 2)
    Xd = kernels.drive(*internal, u[:2000], np.zeros(m))
    agree = float(np.abs(Xd - numpy_loop(dense, net.B_in, net.c0, u, 2000)).max())

    def row(label, t, steps_=n, ref=None):
        w, c = t[0] * 1e6 / steps_, t[1] * 1e6 / steps_
        extra = f"   ({w / ref:5.1f}x the chunked drive)" if ref else ""
        print(f"  {label:44s} {w:8.3f} us/step  [cpu {c:7.3f}]{extra}")

    print(f"\nDrive speed, M = {m}, N = {n}")
    ref = t_chunk[0] * per
    row("dynmodel drive, chunked (what the fit runs)", t_chunk)
    row("dynmodel drive storing all N x M states", t_store, ref=ref)
    row("dynmodel external free run (output fed back)", t_free, ref=ref)
    row("numpy loop, dense C", t_dense, steps, ref)
    row("numpy loop, scipy CSR C", t_csr, steps, ref)
    if Reservoir is not None:
        res = Reservoir(W=net.C.tocsr(), Win=np.ascontiguousarray(net.B_in), bias=net.c0, lr=1.0)
        res.run(u[:10])
        row("reservoirpy Reservoir.run", timed(lambda: (res.reset(), res.run(u)), 2), ref=ref)
    else:
        print("  reservoirpy: not installed")
    print(f"  (dynmodel and numpy states agree to {agree:.1e})")


# ------------------------------------------------------------------ 2. fit time and peak memory


def _training_data(n: int, m: int, solver: str):
    from dynmodel.data import load_dataset, training_data
    from dynmodel.engine import preprocessor
    from dynmodel.spec import validate_spec

    raw = {
        "data": {
            "generator": "narx-system",
            "n": n,
            "seed": 1,
            "split": {"train": 0.8, "validation": 0.2},
            "transient": min(1000, n // 20),
            "scaling": "none",
        },
        "model": {"family": "esn", "params": {"size": m, "readout": {"solver": solver}}},
    }
    spec = validate_spec(raw)
    ds = load_dataset(spec)
    return spec, training_data(ds, preprocessor(spec, ds))


def child_fit(kind: str, n: int, m: int, solver: str) -> dict:
    """One fit in this (fresh) process: seconds and peak memory."""
    from dynmodel.engine import family_rng
    from dynmodel_plugins.esn import EchoStateNetwork

    spec, warm = _training_data(8000, m, solver)  # compile and touch everything outside the figures
    EchoStateNetwork(**spec.model.params.model_dump()).fit(warm, rng=family_rng(0))
    base = peak_mb()
    spec, td = _training_data(n, m, solver)
    data_mb = peak_mb()
    params = spec.model.params.model_dump()
    w0, c0 = time.perf_counter(), time.process_time()
    if kind == "streamed":
        fam = EchoStateNetwork(**params).fit(td, rng=family_rng(0))
        w1 = time.perf_counter()
        fam.simulate(np.ascontiguousarray(td.series[0].u))  # a free run over the whole recording
        sim_s = time.perf_counter() - w1
    elif kind == "stored":
        stored_readout(td, params, solver)
        sim_s = float("nan")
    else:  # reservoirpy
        u, y = td.series[0].u, td.series[0].y
        net = _net(m, "internal")
        res = Reservoir(W=net.C.tocsr(), Win=np.ascontiguousarray(net.B_in), bias=net.c0, lr=1.0)
        (res >> Ridge(ridge=1e-8)).fit(u, y, warmup=1000)
        sim_s = float("nan")
    return {
        "fit_s": time.perf_counter() - w0,
        "fit_cpu_s": time.process_time() - c0,
        "simulate_s": sim_s,
        "peak_mb": peak_mb(),
        "base_mb": base,
        "data_mb": data_mb,
    }


def stored_readout(td, params: dict, solver: str, rng_seed: int = 0):
    """The fit before issue 20: every state stored, then the array solvers of dynmodel.regression."""
    from dynmodel import regression
    from dynmodel.engine import family_rng
    from dynmodel_plugins.esn import EchoStateNetwork
    from dynmodel_plugins.esn.network import build_network

    fam = EchoStateNetwork(**params)
    net = build_network(fam.params, td.n_inputs, td.n_outputs, family_rng(rng_seed))
    drives = fam.training_drives(td)
    feats = [np.hstack([kernels.drive(*net.kernel_args(), d, np.zeros(net.size)), d]) for d in drives]
    F, Y = td.stack("train", feats), td.targets("train")
    Fv, Yv = td.stack("validation", feats), td.targets("validation")
    if solver == "lstsq":
        fit = regression.lstsq(F, Y)
    elif solver == "ridge":
        fit = regression.ridge(F, Y, "auto", Fv, Yv)
    else:
        r = fam.params.readout
        fit = regression.fos(F, Y, Fv=Fv, Yv=Yv, patience=r.patience)
    return fit, Fv, Yv


def run_child(kind: str, n: int, m: int, solver: str) -> dict | None:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", kind, str(n), str(m), solver]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        print(f"  ({kind} fit at N = {n} failed: {out.stderr.strip().splitlines()[-1:]})")
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def fits(sizes: list[int], m: int, solver: str, stored_1e6: bool) -> None:
    print(f"\nFit of a {m}-element internal ESN, {solver} readout (train 80 %, validation 20 %); fresh process each")
    print(f"  {'':34s} {'N':>9s} {'fit s':>8s} {'[cpu s]':>9s} {'peak MB':>9s} {'(before the fit)':>17s}")
    for n in sizes:
        kinds = ["streamed", "stored"] if (n < 1_000_000 or stored_1e6) else ["streamed"]
        if Reservoir is not None and n <= 100_000:
            kinds.append("reservoirpy")
        for kind in kinds:
            r = run_child(kind, n, m, solver)
            if r is None:
                continue
            label = {
                "streamed": "dynmodel, streamed moments",
                "stored": "dynmodel, states stored (before)",
                "reservoirpy": "reservoirpy Reservoir >> Ridge",
            }[kind]
            print(
                f"  {label:34s} {n:9d} {r['fit_s']:8.1f} {r['fit_cpu_s']:9.1f} {r['peak_mb']:9.0f} {r['data_mb']:17.0f}"
            )
            if kind == "streamed":
                print(f"  {'  then a free run over the recording':34s} {n:9d} {r['simulate_s']:8.1f}")
        if n >= 1_000_000 and not stored_1e6:
            print(f"  {'dynmodel, states stored (before)':34s} {n:9d}   (not run: about 15 GB; --stored-1e6)")


# ------------------------------------------------------------------ 3. agreement


def agreement(n: int, m: int) -> None:
    import dynmodel.regression as regression
    from dynmodel import readout
    from dynmodel.engine import family_rng
    from dynmodel_plugins.esn import EchoStateNetwork
    from dynmodel_plugins.esn.network import build_network
    from dynmodel_plugins.esn.streaming import teacher_forced_moments

    print(f"\nStreamed readout against the stored-states readout, M = {m}, N = {n} (validation rows)")
    print(
        f"  {'solver':7s} {'max|dy|/std(y)':>15s} {'rounding floor':>15s} "
        f"{'val NMSE stored':>16s} {'streamed':>10s} {'floor':>10s}"
    )
    for solver in SOLVERS:
        spec, td = _training_data(n, m, solver)
        params = spec.model.params.model_dump()
        ref, Fv, Yv = stored_readout(td, params, solver)
        chunk = regression._CHUNK_ELEMENTS
        regression._CHUNK_ELEMENTS = 300 * (m + 2)  # the same solver, its QR in chunks of 300 rows
        try:
            floor, _, _ = stored_readout(td, params, solver)
        finally:
            regression._CHUNK_ELEMENTS = chunk
        fam = EchoStateNetwork(**params)
        net = build_network(fam.params, td.n_inputs, td.n_outputs, family_rng(0))
        mom = teacher_forced_moments(net, td, fam.training_drives(td), True, ("train", "validation"))
        if solver == "lstsq":
            new = readout.lstsq(mom["train"])
        elif solver == "ridge":
            new = readout.ridge(mom["train"], "auto", mom["validation"])
        else:
            new = readout.fos(mom["train"], mom["validation"], patience=fam.params.readout.patience)
        scale = float(np.std(Yv))
        p_ref, p_new, p_floor = ref.predict(Fv), new.predict(Fv), floor.predict(Fv)

        def nm(p, Yv=Yv):
            return 100 * float(np.mean((Yv - p) ** 2) / np.var(Yv))

        print(
            f"  {solver:7s} {np.abs(p_new - p_ref).max() / scale:15.1e} {np.abs(p_floor - p_ref).max() / scale:15.1e} "
            f"{nm(p_ref):15.6f}% {nm(p_new):9.6f}% {nm(p_floor):9.6f}%"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="M = 200 speed, N = 1e5 fits, agreement at N = 5000")
    ap.add_argument("--solver", default="fos", choices=SOLVERS, help="readout of the timed fits (default fos)")
    ap.add_argument("--stored-1e6", action="store_true", help="also run the stored-states fit at N = 1e6 (~15 GB)")
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        kind, n, m, solver = args.child
        print(json.dumps(child_fit(kind, int(n), int(m), solver)))
        return
    t0 = time.perf_counter()
    speed(200, 10000)
    if not args.quick:
        speed(1000, 100000)
    fits([100_000] if args.quick else [100_000, 1_000_000], 1000, args.solver, args.stored_1e6)
    agreement(5000 if args.quick else 20000, 1000)
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
