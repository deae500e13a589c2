"""dynmodel.inspection.describe: what `dynmodel inspect --json` writes, from the library."""

from __future__ import annotations

import json

from conftest import narx

import dynmodel
from dynmodel.inspection import FACTS, describe
from dynmodel_plugins.narx import Narx


def test_describe_a_model_fitted_on_arrays_after_a_round_trip(tmp_path):
    u, y = narx(1500, 1)
    path = dynmodel.save(Narx(degree=2, lags={"u": [0, 1], "y": [1]}).fit(u, y), tmp_path / "m.h5")
    model = dynmodel.load(path)
    summary = describe(model, path)
    assert summary["file"] == str(path) and summary["family"] == "narx"
    assert summary["inputs"] == ["u"] and summary["outputs"] == ["y"]
    assert set(FACTS) <= set(summary) and summary["metrics"] == model.metrics
    assert summary["model"] == model.family.summary() and summary["model"]  # the family's own facts
    assert summary["metrics"]["train"]["nmse"] < 1.0  # a degree-2 NARX on eq. 3.37 fits well
    json.dumps(summary)  # JSON-ready as it is
