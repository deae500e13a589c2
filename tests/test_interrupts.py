"""Ctrl-C (SIGINT) and SIGTERM as a user, ``timeout``, SLURM or ``docker stop`` send them: real processes,
real signals (each test starts ``dynmodel`` in a subprocess and signals it)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from conftest import write_yaml

#: the whole command line of a dynmodel run in a subprocess
DYNMODEL = [sys.executable, "-m", "dynmodel.cli"]


def annealing(steps: int, seed: int = 0) -> dict:
    """An annealed RNN on 1500 generated samples: about 0.5 ms per annealing step (12000 steps: ~6 s)."""
    return {
        "name": "anneal",
        "data": {
            "generator": "narx-system",
            "n": 1500,
            "seed": 1,
            "split": {"train": 0.6, "validation": 0.2, "test": 0.2},
        },
        "model": {"family": "annealed-rnn", "params": {"size": 10, "steps": steps, "restarts": 1, "workers": 1}},
        "seed": seed,
    }


def _default_sigint() -> None:
    # a shell's background job (and so a test run started with `&`) ignores SIGINT, which a child inherits;
    # a user's foreground command has Python's own handler, which these tests are about
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class Run:
    """``dynmodel ARGS`` in ``cwd``, its stderr collected line by line while it runs."""

    def __init__(self, args: list, cwd: Path):
        self.proc = subprocess.Popen(
            [*DYNMODEL, *map(str, args)],
            cwd=cwd,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=_default_sigint,
        )
        self.lines: list[str] = []
        self._out: list[str] = []
        self._readers = [
            threading.Thread(target=self._read, args=(self.proc.stderr, self.lines), daemon=True),
            threading.Thread(target=self._read, args=(self.proc.stdout, self._out), daemon=True),
        ]
        for reader in self._readers:
            reader.start()

    @staticmethod
    def _read(stream, into: list[str]) -> None:
        for line in stream:
            into.append(line.rstrip("\n"))

    @property
    def stdout(self) -> str:
        return "\n".join(self._out)

    def wait_for(self, test, timeout: float = 60.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and self.proc.poll() is None:
            if test():
                return True
            time.sleep(0.005)
        return False

    def seen(self, text: str) -> bool:
        return any(text in line for line in list(self.lines))

    def finish(self, timeout: float = 60.0) -> int:
        self.proc.wait(timeout)
        for reader in self._readers:
            reader.join(5)
        return self.proc.returncode

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)

    @property
    def errors(self) -> list[str]:
        """stderr without the progress lines."""
        return [ln for ln in self.lines if ln.strip() and not ln.startswith("[dynmodel")]


def children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (from /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as fh:
                stat = fh.read()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
            out.append(int(entry))
    return out


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def still_running(pids: list[int], seconds: float) -> list[int]:
    """The processes of ``pids`` still alive after waiting up to ``seconds`` for all of them to end."""
    deadline = time.monotonic() + seconds
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    return [p for p in pids if alive(p)]


def kill_all(pids: list[int]) -> None:
    """Never leave a process behind, whatever happened."""
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="real signals and /proc")


# ------------------------------------------------------------------------------ issue: Ctrl-C in a batch


def test_ctrl_c_during_an_annealing_stops_an_in_process_sweep(tmp_path):
    """--workers 1: the annealing must not swallow the Ctrl-C and let the sweep record its cut-short point."""
    write_yaml(tmp_path / "spec.yaml", annealing(12000))
    write_yaml(tmp_path / "grid.yaml", {"seed": [0, 1]})
    out = tmp_path / "out"
    run = Run(["sweep", "spec.yaml", "--grid", "grid.yaml", "--workers", 1, "--out", out, "-q"], tmp_path)
    try:
        assert run.wait_for(lambda: (out / "sweep.json").exists()), run.lines
        time.sleep(1.0)  # inside the first point's annealing (about 6 s)
        run.proc.send_signal(signal.SIGINT)
        code = run.finish(60)
    finally:
        run.kill()
    assert code == 130, (code, run.lines)
    assert run.errors == [
        f"interrupted: 0 of 2 points finished, kept in {out}; run the same command with --resume to finish"
    ], run.lines
    assert not (out / "points").exists() or not list((out / "points").iterdir())  # --resume redoes the point
    rows = json.loads((out / "results.json").read_text())["points"]
    assert [r["status"] for r in rows] == ["not run", "not run"]


def test_ctrl_c_during_an_annealing_stops_an_in_process_auto_search(tmp_path):
    """family auto with --workers 1: the search stops (and keeps its best so far), it does not go on."""
    spec = annealing(400)
    spec["model"] = {"family": "auto", "params": {"budget": 60, "families": ["annealed-rnn"]}}
    write_yaml(tmp_path / "auto.yaml", spec)
    run = Run(["fit", "auto.yaml", "--out", "auto.h5", "--workers", 1], tmp_path)
    t0 = time.monotonic()
    try:
        assert run.wait_for(lambda: run.seen("search")), run.lines  # candidates annealing in this process
        time.sleep(1.0)
        run.proc.send_signal(signal.SIGINT)
        code = run.finish(60)
    finally:
        run.kill()
    assert code == 130, (code, run.lines)
    assert time.monotonic() - t0 < 30  # not the 60 s budget
    assert len(run.errors) == 1 and run.errors[0].startswith("error: ") and "interrupted (Ctrl-C)" in run.errors[0]


# ------------------------------------------------------------------------------ issue: a plain fit cut short


@pytest.mark.parametrize(("sig", "code", "how"), [(signal.SIGINT, 130, "Ctrl-C"), (signal.SIGTERM, 143, "SIGTERM")])
def test_an_interrupted_annealing_keeps_its_best_network_and_says_so(tmp_path, sig, code, how):
    write_yaml(tmp_path / "rnn.yaml", annealing(20000))
    run = Run(["fit", "rnn.yaml", "--out", "rnn.h5", "--json", "rnn.json"], tmp_path)
    try:
        assert run.wait_for(lambda: run.seen("anneal")), run.lines
        time.sleep(0.3)
        run.proc.send_signal(sig)
        got = run.finish(60)
    finally:
        run.kill()
    assert got == code, (got, run.lines)
    assert len(run.errors) == 1, run.lines
    line = run.errors[0]
    assert line.startswith("error: rnn.yaml: the annealing was interrupted") and f"({how})" in line
    assert "kept the best network found so far" in line and f"written to {tmp_path / 'rnn.h5'}" in line
    assert "Traceback" not in run.stdout + "\n".join(run.lines)
    assert (tmp_path / "rnn.h5").is_file()  # the model is still saved
    summary = json.loads((tmp_path / "rnn.json").read_text())
    assert summary["interrupted"] and "the annealing was interrupted" in summary["interrupted"]
    assert summary["notes"][0] == summary["interrupted"]


# ------------------------------------------------------------------------------ issue: SIGTERM and worker processes


def test_a_sigterm_swallowed_by_a_finalizer_is_delivered_again():
    """The SIGTERM handler raises in whatever code runs when the signal arrives; in a finalizer or a weakref
    callback Python only prints that exception ("Exception ignored in ..."), and a sweep under load ran to its
    end with exit 0. The signal is then sent again, and lands in the code around it."""
    import gc

    from dynmodel import cli
    from dynmodel.errors import Terminated

    class Finalized:
        def __del__(self):
            raise Terminated()  # as the handler does when the signal arrives during a finalizer

    with cli._sigterm_as_interrupt():
        with pytest.raises(Terminated):
            Finalized()
            gc.collect()
            time.sleep(5)  # the signal sent again lands here
    assert signal.getsignal(signal.SIGTERM) is not None


def test_sigterm_stops_a_sweeps_worker_processes_and_keeps_its_finished_points(tmp_path):
    write_yaml(tmp_path / "spec.yaml", annealing(5000))
    write_yaml(tmp_path / "grid.yaml", {"seed": [0, 1, 2, 3, 4, 5]})
    out = tmp_path / "out"
    run = Run(["sweep", "spec.yaml", "--grid", "grid.yaml", "--workers", 2, "--out", out, "-q"], tmp_path)
    workers: list[int] = []
    try:
        assert run.wait_for(lambda: (out / "points").is_dir() and any((out / "points").iterdir()), 90), run.lines
        workers = [p for p in children(run.proc.pid) if alive(p)]
        assert len(workers) >= 2  # the pool's workers (and multiprocessing's resource tracker)
        run.proc.send_signal(signal.SIGTERM)
        code = run.finish(60)
        left = still_running(workers, 10)
    finally:
        run.kill()
        kill_all(workers)
    assert code == 143, (code, run.lines)
    assert not left, f"worker processes still running after SIGTERM: {left}"
    finished = sorted(p.stem for p in (out / "points").iterdir())
    assert finished and len(finished) < 6
    assert len(run.errors) == 1, run.lines
    assert run.errors[0].startswith(f"terminated (SIGTERM): {len(finished)} of 6 points finished, kept in {out}")
    rows = json.loads((out / "results.json").read_text())["points"]
    assert sum(r["status"] == "ok" for r in rows) == len(finished)


# ------------------------------------------------------------------------------ issue: a report folder half written


def test_ctrl_c_while_the_diagnosis_report_is_written_leaves_no_partial_folder(tmp_path):
    from dynmodel.paths import check_output

    spec = annealing(10)
    spec["model"] = {"family": "narx", "params": {"degree": 2, "lags": {"u": [0, 1, 2], "y": [1, 2]}}}
    write_yaml(tmp_path / "narx.yaml", spec)
    report = tmp_path / "anneal-diagnosis"

    def writing() -> bool:  # the report's folder, or its temporary sibling, appeared
        return any(p.name == report.name or p.name.startswith(f".{report.name}.") for p in tmp_path.iterdir())

    run = Run(["diagnose", "narx.yaml", "--rounds", 1, "--seeds", 1, "-q"], tmp_path)
    try:
        assert run.wait_for(writing, 60), run.lines
        run.proc.send_signal(signal.SIGINT)  # the figures take a second or more
        code = run.finish(60)
    finally:
        run.kill()
    assert code == 130, (code, run.lines)
    assert not report.exists() or (report / "index.md").is_file(), sorted(os.listdir(report))
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary folder left
    check_output(report, "report", option="--report")  # a rerun is accepted


# ------------------------------------------------------------------------------ issue: workers outliving a killed parent

_POOL_SCRIPT = """
import sys, time
from dynmodel.executors import make_executor

if __name__ == "__main__":
    pool = make_executor(workers=2)
    futures = [pool.submit(time.sleep, 120) for _ in range(2)]
    while not all(f.running() for f in futures):
        time.sleep(0.05)
    print(" ".join(str(pid) for pid in pool._pool._processes), flush=True)
    time.sleep(600)
"""


def test_pool_workers_exit_when_the_process_that_started_them_is_killed(tmp_path):
    """A script (or a notebook kernel) using the local process pool is killed outright (SIGKILL: nothing runs
    on its side): its workers notice within seconds that their parent is gone and exit, instead of finishing
    their fit and waiting forever to hand over a result nobody reads."""
    script = tmp_path / "pool.py"
    script.write_text(_POOL_SCRIPT)
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=tmp_path)
    workers: list[int] = []
    try:
        assert proc.stdout is not None
        workers = [int(pid) for pid in proc.stdout.readline().split()]
        assert len(workers) == 2 and all(alive(p) for p in workers)
        proc.kill()
        proc.wait(10)
        left = still_running(workers, 15)
    finally:
        proc.kill()
        kill_all(workers)
    assert not left, f"pool workers still running 15 s after their parent was killed: {left}"


_CTRL_C_WHILE_LOADING = """
import sys


class CtrlC:
    '''Ctrl-C arrives while the command line's modules load (typer, rich: the first quarter second).'''

    def find_spec(self, name, path=None, target=None):
        if name == "rich.console":
            raise KeyboardInterrupt


sys.meta_path.insert(0, CtrlC())
sys.argv = ["dynmodel", "--version"]
from dynmodel.launch import main

main()
"""


def test_ctrl_c_while_the_command_line_loads_ends_with_one_line(tmp_path):
    """The console script (``dynmodel.launch:main``): a Ctrl-C before any command runs ends as one later does,
    one line and exit 130, not a traceback; ``import dynmodel`` itself loads no pydantic or numpy (it was 0.4 s
    of the window)."""
    script = tmp_path / "ctrl_c.py"
    script.write_text(_CTRL_C_WHILE_LOADING)
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert r.returncode == 130, r.stderr
    assert r.stderr.strip() == "error: interrupted (Ctrl-C). Fix: rerun the command"
    light = subprocess.run(
        [sys.executable, "-c", "import sys, dynmodel; print(sorted({'numpy', 'pydantic'} & set(sys.modules)))"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert light.stdout.strip() == "[]", light.stderr
    api = subprocess.run(
        [sys.executable, "-c", "import dynmodel; print(dynmodel.load_spec.__module__, dynmodel.Spec.__name__)"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert api.stdout.split() == ["dynmodel.spec", "Spec"], api.stderr


def test_ctrl_c_while_the_command_line_is_parsed_ends_with_one_line(cli, monkeypatch):
    """Outside a command's own handling (typer parses the line, calls the group's callback) a Ctrl-C used to end
    with exit 130 and nothing said; it is one line like any other interruption."""
    from typer.core import TyperGroup

    def ctrl_c(self, ctx):
        raise KeyboardInterrupt

    monkeypatch.setattr(TyperGroup, "invoke", ctrl_c)
    r = cli("validate", "spec.yaml")
    assert r.exit_code == 130
    assert r.stderr.strip() == "error: interrupted (Ctrl-C). Fix: rerun the command"
