"""Issue 15: every bad input of the battery (tests/bad_inputs.py) gets its documented exit code,
one error line, no traceback, and leaves every file of the working folder byte-identical."""

from __future__ import annotations

import os

import pytest
from bad_inputs import cases, judge, make_models, make_readonly, populate, snapshot

CASES = [c for c in cases() if c.interrupt_after is None]  # Ctrl-C runs: benchmarks/bad_inputs.py


@pytest.fixture(scope="module")
def model_cache(tmp_path_factory):
    return make_models(tmp_path_factory.mktemp("models"))


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id, marks=[pytest.mark.slow] if c.slow else []) for c in CASES])
def test_bad_input(case, cli, tmp_path, model_cache, monkeypatch):
    if case.root_skip and os.geteuid() == 0:
        pytest.skip("root reads every file")
    work = tmp_path / "work"
    work.mkdir()
    populate(work, model_cache)
    if case.setup is not None:
        case.setup(work)
    undo = None
    if case.readonly:
        try:
            undo = make_readonly(work / case.readonly)
        except OSError as exc:
            pytest.skip(str(exc))
    before = snapshot(work)
    monkeypatch.chdir(work)
    try:
        r = cli(*case.argv)
    finally:
        if undo is not None:
            undo()
    after = snapshot(work)
    problems = judge(case, r.exit_code, r.stdout, r.stderr, before, after)
    assert not problems, (problems, r.stdout[-2000:], r.stderr[-2000:])
