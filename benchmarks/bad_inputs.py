"""Run the bad-input battery of issue 15 as a new user would and count what is handled.

Every case of ``tests/bad_inputs.py`` runs the installed ``dynmodel`` command (a fresh process, no
``-q``, progress lines allowed) in a fresh working folder holding the user's data, spec and models.
A case is handled when its exit code is the documented one, an error is one ``error: ... Fix: ...``
line on stderr without a traceback, and every file in the folder is byte-identical afterwards (no
new file after a failure). Prints one line per case and the totals:

    python benchmarks/bad_inputs.py            # all cases, 2 at a time
    python benchmarks/bad_inputs.py -k predict # cases whose id contains 'predict'

Cases that cannot be arranged for the current user (an unreadable file, for root) are listed as
not run, never counted as handled.
"""

from __future__ import annotations

import argparse
import fnmatch
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from bad_inputs import Case, cases, damaged_files, judge, make_models, make_readonly, populate, snapshot  # noqa: E402


def dynmodel_command() -> list[str]:
    exe = Path(sys.executable).with_name("dynmodel")
    if exe.exists():
        return [str(exe)]
    found = shutil.which("dynmodel")
    if found is None:
        sys.exit("the dynmodel command is not installed (pip install -e .)")
    return [found]


def _interrupt(proc: subprocess.Popen, after: float) -> tuple[str, str]:
    """Ctrl-C once the annealing has run for ``after`` seconds (its progress line seen)."""
    lines: list[str] = []
    started: list[float] = []

    def read() -> None:
        for line in proc.stderr:
            lines.append(line)
            if "anneal" in line and not started:
                started.append(time.perf_counter())

    out: list[str] = []
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    drain = threading.Thread(target=lambda: out.append(proc.stdout.read()), daemon=True)
    drain.start()
    deadline = time.perf_counter() + 600
    while proc.poll() is None and time.perf_counter() < deadline:
        if started and time.perf_counter() - started[0] >= after:
            proc.send_signal(signal.SIGINT)
            break
        time.sleep(0.1)
    try:
        proc.wait(timeout=300)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    drain.join(timeout=10)
    stdout = "".join(out)
    reader.join(timeout=10)
    return stdout, "".join(lines)


def run_case(case: Case, cache: Path, base: Path, command: list[str]) -> tuple[str, list[str], int, float]:
    """(status, problems, damaged file count, seconds) for one case."""
    if case.root_skip and os.geteuid() == 0:
        return "not run (root reads every file)", [], 0, 0.0
    work = Path(tempfile.mkdtemp(prefix=f"{case.id[:40]}-", dir=base))
    populate(work, cache)
    if case.setup is not None:
        case.setup(work)
    try:
        undo = make_readonly(work / case.readonly) if case.readonly else None
    except OSError as exc:
        shutil.rmtree(work, ignore_errors=True)
        return f"not run ({exc})", [], 0, 0.0
    before = snapshot(work)
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    try:
        proc = subprocess.Popen(
            command + case.argv,
            cwd=work,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            # a user's Ctrl-C works even when this script runs as a background job (which ignores SIGINT)
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        if case.interrupt_after is not None:
            stdout, stderr = _interrupt(proc, case.interrupt_after)
        else:
            stdout, stderr = proc.communicate(timeout=1800)
    finally:
        if undo is not None:
            undo()
    seconds = time.perf_counter() - t0
    after = snapshot(work)
    problems = judge(case, proc.returncode, stdout, stderr, before, after)
    damaged = [n for n in damaged_files(before, after) if not any(fnmatch.fnmatch(n, w) for w in case.writes)]
    shutil.rmtree(work, ignore_errors=True)
    return ("handled" if not problems else "NOT handled"), problems, len(damaged), seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", default="", help="only cases whose id contains this text")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    selected = [c for c in cases() if args.k in c.id]
    command = dynmodel_command()
    with tempfile.TemporaryDirectory(prefix="dynmodel-battery-") as tmp:
        base = Path(tmp)
        cache = make_models(base / "models")
        t0 = time.perf_counter()
        with ThreadPoolExecutor(args.workers) as pool:
            results = list(pool.map(lambda c: run_case(c, cache, base, command), selected))
        total = time.perf_counter() - t0
    handled = not_run = damaged = 0
    for case, (status, problems, n_damaged, seconds) in zip(selected, results):
        print(f"{status:>30}  {case.id:<45} exit {case.code} expected  {seconds:5.1f} s")
        for p in problems:
            print(f"{'':>32}- {p}")
        handled += status == "handled"
        not_run += status.startswith("not run")
        damaged += n_damaged
    ran = len(selected) - not_run
    print(
        f"\n{handled} of {ran} handled, {damaged} files damaged"
        + (f" ({not_run} case(s) not run for this user)" if not_run else "")
        + f"; {total:.0f} s with {args.workers} workers (dynmodel: {command[0]})"
    )
    sys.exit(0 if handled == ran and damaged == 0 else 1)


if __name__ == "__main__":
    main()
