"""The search's band check on a free run (dynmodel.search.checks): what counts as leaving the band around the
training output range, read on synthetic runs of a dataset whose training input spans [-1, 1] and training
output [0, 1] (so the band is [-0.49, 1.49] and the outer band [-1, 2] where the input lies inside)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import write_csv

from dynmodel.data import load_dataset
from dynmodel.data.dataset import Dataset
from dynmodel.search import checks
from dynmodel.spec import validate_spec

N = 2000


@pytest.fixture(scope="module")
def ds(tmp_path_factory) -> Dataset:
    base = tmp_path_factory.mktemp("band")
    u = np.sin(np.linspace(0.0, 40.0, 1000))  # spans [-1, 1]
    write_csv(base / "d.csv", {"u": u, "y": (u + 1) / 2})  # y spans [0, 1]
    raw = {
        "data": {"path": "d.csv", "input": ["u"], "output": ["y"], "split": {"train": 1.0}},
        "model": {"family": "narx"},
    }
    return load_dataset(validate_spec(raw, "<test>", base))


def _leaves(ds: Dataset, y: np.ndarray) -> int | None:
    return checks._leaves(y[:, None], *checks.band(ds))


def test_a_run_inside_the_band_passes_and_one_held_at_its_edge_fails(ds):
    assert _leaves(ds, np.full(N, 0.5)) is None
    held = np.full(N, 0.5)
    held[800:] = 1.49  # a diverging run held at an output clip at the band's edge
    assert _leaves(ds, held) == 800


def test_a_brief_overshoot_passes_but_not_a_long_or_a_far_one(ds):
    y = np.full(N, 0.5)
    y[100:105] = 1.7  # five samples beyond the band, inside the outer band: a peak overshot
    assert _leaves(ds, y) is None
    y[100 : 100 + checks.BRIEF + 1] = 1.7  # longer than BRIEF in a row
    assert _leaves(ds, y) == 100
    y = np.full(N, 0.5)
    y[300] = 2.2  # beyond the outer band, once
    assert _leaves(ds, y) == 300
    y = np.full(N, 0.5)
    y[::40] = 1.7  # one sample in 40: 2.5 % of the run outside, each time briefly
    assert _leaves(ds, y) == 0
    y = np.full(N, 0.5)
    y[1500] = np.nan  # a run that turned non-finite, once
    assert _leaves(ds, y) == 1500
