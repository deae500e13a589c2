"""Sweep scaling: a 16-point sweep serial vs a local pool of 2 workers vs a Dask LocalCluster of 2, in one run.

The sweep: the quick-start spec (an external ESN on 10000 samples of the NARX system, eq. 3.37), its
``model.params.size`` in {100, 200} x 8 seeds. For each executor it prints

* ``start``: seconds to make the executor (process spawn, imports, cluster start);
* ``cold``: wall seconds of the sweep on a fresh executor, start-up included (what a user waits for);
* ``warm``: wall seconds of the same sweep again on the warmed executor (workers started, data cached);
* ``speedup``: serial warm / warm (target >= 1.7 on 2 cores), and serial cold / cold;
* ``overhead/task``: (workers x warm wall - sum of the points' in-worker seconds) / points: what the
  executor adds per point (scheduling, transfer of results and models, idle workers at the end);
* ``round trip``: mean seconds of an empty task submitted and awaited one at a time (the latency floor);
* ``cpu/pt``: CPU seconds of the thread that ran each fit, per point (warm run). On a busy machine wall times
  inflate but CPU times do not: ``workers x serial cpu/pt / cpu/pt`` bounds the speedup an idle
  machine would give, before scheduling overhead.

It also checks that all three give bit-identical metrics. Timings depend on the machine's load: the
target is judged on a quiet machine. Prints figures; asserts nothing.

    python benchmarks/sweep_scaling.py            # 16 points (sizes 100, 200 x 8 seeds)
    python benchmarks/sweep_scaling.py --quick    # 8 points (sizes 50, 100 x 4 seeds)
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def round_trip(executor, n: int = 30) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        executor.submit(os.getpid).result()
    return (time.perf_counter() - t0) / n


def run(name, make, spec, grid, workers):
    import dynmodel

    t0 = time.perf_counter()
    executor = make()
    start = time.perf_counter() - t0
    try:
        t1 = time.perf_counter()
        cold = dynmodel.sweep(spec, grid, executor=executor, keep="none")
        cold_s = time.perf_counter() - t1 + start
        t2 = time.perf_counter()
        warm = dynmodel.sweep(spec, grid, executor=executor, keep="none")
        warm_s = time.perf_counter() - t2
        rt = round_trip(executor)
    finally:
        executor.shutdown()
    busy = sum(r["seconds"] for r in warm.records.values())
    cpu = sum(r["cpu_seconds"] for r in warm.records.values()) / len(warm.points)
    overhead = (workers * warm_s - busy) / len(warm.points)
    metrics = {k: r["metrics"] for k, r in warm.records.items()}
    same = metrics == {k: r["metrics"] for k, r in cold.records.items()}
    return {
        "name": name,
        "workers": workers,
        "start": start,
        "cold": cold_s,
        "warm": warm_s,
        "busy": busy,
        "cpu": cpu,
        "overhead": overhead,
        "round_trip": rt,
        "metrics": metrics,
        "repeatable": same,
        "ok": warm.counts()["ok"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="8 smaller points")
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask LocalCluster")
    args = parser.parse_args()

    from dynmodel.executors import InProcessExecutor, LocalPoolExecutor, make_executor

    spec = ROOT / "specs" / "quickstart.yaml"
    sizes, seeds = ([50, 100], 4) if args.quick else ([100, 200], 8)
    grid = {"model.params.size": sizes, "seed": {"range": [0, seeds]}}
    n = len(sizes) * seeds
    print(f"sweep: {spec.relative_to(ROOT)}, model.params.size {sizes} x {seeds} seeds = {n} points")
    print(f"machine: {os.cpu_count()} cores, load average {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    rows = [run("serial (in-process)", InProcessExecutor, spec, grid, 1)]
    rows.append(run("local pool, 2 workers", lambda: LocalPoolExecutor(2), spec, grid, 2))
    if not args.no_dask:
        try:
            import distributed  # noqa: F401
        except ImportError:
            print('Dask not installed (pip install "dynmodel[dask]"): skipped')
        else:
            rows.append(run("Dask local:2", lambda: make_executor(scheduler="local:2"), spec, grid, 2))
    serial = rows[0]
    head = f"{'executor':24} {'start s':>8} {'cold s':>8} {'warm s':>8} {'speedup':>8} {'cold sp.':>8} {'overhead/task s':>16} {'round trip s':>13} {'cpu/pt s':>9} {'cpu bound':>9} {'fits ok':>8}"
    print(head)
    print("-" * len(head))
    for r in rows:
        print(
            f"{r['name']:24} {r['start']:8.2f} {r['cold']:8.2f} {r['warm']:8.2f} {serial['warm'] / r['warm']:8.2f} "
            f"{serial['cold'] / r['cold']:8.2f} {r['overhead']:16.3f} {r['round_trip']:13.4f} {r['cpu']:9.3f} "
            f"{r['workers'] * serial['cpu'] / r['cpu']:9.2f} {r['ok']:>5}/{n}"
        )
    same = all(r["metrics"] == serial["metrics"] for r in rows) and all(r["repeatable"] for r in rows)
    print(f"metrics bit-identical across executors and runs: {'yes' if same else 'NO'}")
    print(f"mean fit time per point (serial, warm): {serial['busy'] / n:.2f} s")
    print(
        "targets (quiet 2-core machine): warm speedup >= 1.7 for both parallel executors; Dask overhead/task <= 0.2 s"
    )


if __name__ == "__main__":  # worker processes are spawned and import this file
    main()
