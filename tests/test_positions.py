"""Inputs that move like a position, and the direction features the search offers around a network of them
(docs/auto.md, "Friction")."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from conftest import make_spec, write_csv, write_yaml

from dynmodel import engine
from dynmodel.data import load_dataset
from dynmodel.data.derived import compute as derived_compute
from dynmodel.data.derived import position_like
from dynmodel.family import no_progress
from dynmodel.search import search_options
from dynmodel.search.params import AutoParams
from dynmodel.search.run import context
from dynmodel.search.space import Candidate, Found, SearchContext
from dynmodel.spec import validate_spec
from dynmodel_plugins.esn.search import neighbours, starting
from dynmodel_plugins.narx import search as narx_search


def _slow(n: int, seed: int) -> np.ndarray:
    """A smooth position: a few slow sines (strokes of 100 to 400 samples)."""
    t = np.arange(n)
    rng = np.random.default_rng(seed)
    return sum(np.sin(2 * np.pi * t / p + rng.uniform(0, 2 * np.pi)) for p in (800, 390, 230))


def test_a_position_has_a_deadband_and_noise_or_a_held_pressure_has_none():
    x = _slow(6000, 0)
    span = np.subtract(*np.quantile(x, [0.99, 0.01]))
    assert position_like([x]) == pytest.approx(0.005 * span)
    noise = np.random.default_rng(1).standard_normal(6000)
    assert position_like([noise]) is None  # it reverses about every other sample
    held = [level + 0.01 * _slow(2000, k) for k, level in enumerate((1.0, 3.0, 7.0))]
    assert position_like(held) is None  # set per recording: it barely moves within any of them
    assert position_like([np.zeros(100)]) is None
    assert position_like([np.linspace(0, 1, 500)]) is None  # never reverses: no direction to tell
    # a force held for 40 samples at random levels reverses rarely, but jumps: no position, no direction
    stepped = np.repeat(np.random.default_rng(2).uniform(-1, 1, 150), 40)
    assert position_like([stepped]) is None
    assert position_like([stepped + 0.02 * _slow(6000, 3)]) is None  # with a little drift between the jumps


def _ctx(positions: dict[str, float], data: dict | None = None) -> SearchContext:
    return SearchContext(("x", "p"), ("f",), 1.0, 6000, 2000, data or {}, positions=positions)


def _ctx1(positions: dict[str, float], data: dict | None = None) -> SearchContext:
    """:func:`_ctx` with the position as the only input (a force from a position)."""
    return replace(_ctx(positions, data), input_names=("x",))


def _found(params: dict, data: dict | None = None) -> Found:
    return Found(Candidate("esn", params, "a network", data=data or {}), None, {}, 1.0)


def test_the_esn_offers_direction_features_of_its_positions_alone_and_with_delay_lines():
    out = neighbours(_ctx({"x": 0.01}), _found({"size": 400}))
    patches = [c.data for c in out if "derived_inputs" in c.data]
    derived = [{"direction": "x", "deadband": 0.01}, {"since_reversal": "x", "deadband": 0.01}]
    assert patches == [
        {"derived_inputs": derived},
        {"delay_lines": [1, 2, 5, 10, 25, 50, 100], "delay_form": "difference", "derived_inputs": derived},
    ]
    assert all(c.params == {"size": 400} for c in out if c.data in patches)
    # around a network that has delay lines already, they are kept
    lines = {"delay_lines": [1, 2, 5], "delay_form": "difference"}
    around = [c.data for c in neighbours(_ctx({"x": 0.01}), _found({}, lines)) if "derived_inputs" in c.data]
    assert around == [{**lines, "derived_inputs": derived}]


def test_where_a_position_is_the_only_input_the_esn_also_starts_with_the_friction_network():
    """Direction features and delay lines as a starting candidate, not only around a network that screened
    well: on the sliding friction plant of thesis 6.3 no network without them did (benchmarks/auto_thesis.py)."""
    derived = [{"direction": "x", "deadband": 0.01}, {"since_reversal": "x", "deadband": 0.01}]
    [start] = [c for c in starting(_ctx1({"x": 0.01})) if c.data]
    lines = {"delay_lines": [1, 2, 5, 10, 25, 50, 100], "delay_form": "difference"}
    assert start.data == {**lines, "derived_inputs": derived} and start.params == {"size": 400}
    # the same candidate as the one grown around the starting network of that size: fitted once
    assert start.key in {c.key for c in neighbours(_ctx1({"x": 0.01}), _found({"size": 400}))}
    # the spec's own delay lines stay, the features alone are added; no position, no such candidate
    own = _ctx1({"x": 0.01}, {"delay_lines": [3, 30]})
    assert [c.data for c in starting(own) if c.data] == [{"derived_inputs": derived}]
    assert not any(c.data for c in starting(_ctx1({})))
    assert not any(c.data for c in starting(_ctx1({"x": 0.01}, {"derived_inputs": [{"time": "linear"}]})))
    # beside another input (a seal's pressure) it is only grown around a network that screened well
    assert not any(c.data for c in starting(_ctx({"x": 0.01})))


@pytest.mark.parametrize(
    "ctx, found",
    [
        (_ctx({}), _found({})),  # no input moves like a position
        (_ctx({"x": 0.01}), _found({"mode": "external", "tune_in": 20})),  # a fed-back network
        (_ctx({"x": 0.01}, {"derived_inputs": [{"time": "linear"}]}), _found({})),  # the spec derives inputs
    ],
)
def test_no_direction_features_where_they_do_not_apply(ctx, found):
    assert not any("derived_inputs" in c.data for c in neighbours(ctx, found))


def test_the_narx_family_offers_its_default_with_direction_features_and_its_neighbours_keep_them():
    derived = [{"direction": "x", "deadband": 0.01}, {"since_reversal": "x", "deadband": 0.01}]
    [cand] = [c for c in narx_search.starting(_ctx({"x": 0.01})) if c.data]
    assert cand.data == {"derived_inputs": derived} and "lags" not in cand.params  # the default's own search
    assert not any(c.data for c in narx_search.starting(_ctx({})))
    assert not any(c.data for c in narx_search.starting(_ctx({"x": 0.01}, {"derived_inputs": [{"time": "linear"}]})))

    class Fitted:  # what a fit on those inputs chose: its lags name the derived inputs
        embedding_ = type(
            "E", (), {"regressors": [type("R", (), {"name": n, "lag": 1})() for n in ("x", "x_dir", "f")]}
        )
        exponents_ = [np.array([1, 1, 1])]
        terms_ = [[0, 1, 2]]
        selection_: dict = {}

    around = Found(replace(cand, params={}), Fitted(), {}, 1.0)
    grown = narx_search.neighbours(_ctx({"x": 0.01}), around)
    assert grown and all(c.data == {"derived_inputs": derived} for c in grown)
    assert all(
        c.summary.endswith(", with the direction and travel since the last reversal of x as inputs") for c in grown
    )


def test_the_search_context_names_the_position_and_not_the_noise_input(tmp_path):
    n = 3000
    x, u = _slow(n, 2), np.random.default_rng(3).standard_normal(n)
    path = write_csv(tmp_path / "d.csv", {"x": x, "u": u, "f": np.tanh(5 * np.gradient(x)) + 0.1 * u})
    raw = {
        "data": {"path": str(path), "input": ["x", "u"], "output": ["f"], "split": {"train": 0.7, "validation": 0.3}},
        "model": {"family": "auto"},
    }
    spec = make_spec(raw)
    ctx, _ = context(spec, load_dataset(spec), AutoParams(), None)
    assert list(ctx.positions) == ["x"]
    assert ctx.positions["x"] == pytest.approx(0.005 * np.subtract(*np.quantile(x[:2100], [0.99, 0.01])), rel=1e-2)


def _dahl_search(tmp_path, exclude: list[str], families: tuple[str, ...] = ("esn",)) -> dict:
    raw = {
        "data": {
            "generator": "dahl",
            "n": 4000,
            "seed": 1,
            "input": ["position"],
            "output": ["force"],
            "split": {"train": 0.75, "validation": 0.25},
        },
        "model": {
            "family": "auto",
            "params": {"families": list(families), "budget": 20, "seeds": 1, "exclude": exclude},
        },
        "seed": 0,
    }
    spec = validate_spec(raw, "<test>", tmp_path)
    with search_options(workers=1):
        model, _ = engine.fit_dataset(spec, load_dataset(spec), no_progress)
    return model.search


def test_validate_names_the_inputs_that_move_like_a_position(tmp_path, cli):
    raw = {
        "data": {"generator": "dahl", "n": 2000, "input": ["position"], "output": ["force"]},
        "model": {"family": "auto"},
    }
    result = cli("validate", write_yaml(tmp_path / "s.yaml", raw))
    assert result.exit_code == 0, result.output
    assert "auto: inputs that move like a position: position (" in result.output


@pytest.mark.slow
def test_a_friction_search_measures_direction_features_unless_data_extensions_are_excluded(tmp_path):
    rec = _dahl_search(tmp_path, [])
    assert rec["context"]["positions"] == {"position": pytest.approx(1.7e-7, rel=0.2)}
    measured = [c for c in rec["candidates"] if "derived_inputs" in c["data"] and c["levels"]]
    assert len(measured) >= 2 and all(math.isfinite(c["validation_nmse"]) for c in measured)
    assert not any(c["data"] for c in _dahl_search(tmp_path, ["data-extensions"])["candidates"])


@pytest.mark.slow
def test_on_dahl_friction_the_narx_default_with_direction_features_validates_far_better_than_without(tmp_path):
    """A Dahl force follows the travel since the last reversal: a polynomial of it and the direction fits what a
    polynomial of the position lags cannot (benchmarks/auto_friction.py: 0.043 % test NMSE, the NARX default
    0.418 %)."""
    rec = _dahl_search(tmp_path, [], ("narx",))
    by_summary = {c["summary"]: c for c in rec["candidates"]}
    plain = by_summary["lags and degree chosen on validation (the default)"]
    featured = next(c for c in rec["candidates"] if c["data"] and c["summary"].startswith("lags and degree"))
    assert featured["validation_nmse"] < 0.5 * plain["validation_nmse"]
    assert rec["winner"] != plain["key"]


def test_the_sign_of_an_input_as_a_derived_channel(tmp_path):
    u = np.array([[0.5], [-0.0005], [-2.0], [0.001]])
    assert derived_compute([{"sign": "v", "deadband": 0.001}], u, ["v"], 1.0).ravel().tolist() == [1, 0, -1, 0]
    raw = {
        "data": {"generator": "lugre", "n": 500, "input": ["position"], "output": ["force"]},
        "model": {"family": "narx"},
    }
    raw["data"]["derived_inputs"] = [{"sign": "position", "deadband": 0.0}]
    lags = {"position": [0], "position_sign": [0], "force": [1]}
    raw["model"]["params"] = {"lags": lags, "degree": 1, "max_terms": 4, "patience": None}  # every term kept
    spec = validate_spec(raw, "<test>", tmp_path)
    model, _ = engine.fit_dataset(spec, load_dataset(spec), no_progress)
    assert {r.name for r in model.family.embedding_.regressors} == {"position", "position_sign", "force"}


def _lugre_velocity(tmp_path, n: int = 4000) -> dict:
    """LuGre friction driven by a velocity: the generator's position differentiated (a tribometer logs the
    sliding velocity)."""
    raw = {"data": {"generator": "lugre", "n": n, "seed": 1, "input": ["position"], "output": ["force"]}}
    rec = load_dataset(validate_spec(raw, "<test>", tmp_path)).recordings[0]
    path = write_csv(tmp_path / "v.csv", {"v": np.gradient(rec.u[:, 0]) * 250.0, "f": rec.y[:, 0]})
    return {
        "data": {"path": str(path), "input": ["v"], "output": ["f"], "split": {"train": 0.75, "validation": 0.25}},
        "model": {"family": "auto", "params": {"families": ["narx"], "budget": 20, "seeds": 1}},
        "seed": 0,
    }


@pytest.mark.slow
def test_a_velocity_changes_sign_and_the_narx_default_on_its_sign_validates_far_better(tmp_path):
    """A LuGre force switches on the sign of the sliding velocity, which no polynomial of the velocity gives
    (benchmarks/auto_friction.py has the position; with the velocity as the input, 12000 samples: auto 3.1 %
    test NMSE before, 5e-7 % with the sign)."""
    spec = validate_spec(_lugre_velocity(tmp_path), "<test>", tmp_path)
    ctx, _ = context(spec, load_dataset(spec), AutoParams(), None)
    assert list(ctx.signed) == ["v"] and ctx.sign_inputs() == [{"sign": "v", "deadband": ctx.positions["v"]}]
    [cand] = [c for c in narx_search.starting(ctx) if "sign" in c.summary]
    assert cand.data == {"derived_inputs": ctx.sign_inputs()}
    with search_options(workers=1):
        model, _ = engine.fit_dataset(spec, load_dataset(spec), no_progress)
    rec = model.search
    plain = next(c for c in rec["candidates"] if c["summary"] == "lags and degree chosen on validation (the default)")
    assert "sign of v" in rec["winner_summary"]
    assert model.metrics["validation"]["nmse"] < 0.1 * plain["validation_nmse"]
    # the same motion kept on one side of zero moves like a position and does not change sign
    raw = _lugre_velocity(tmp_path)
    data = np.loadtxt(raw["data"]["path"], delimiter=",", skiprows=1)
    raw["data"]["path"] = str(write_csv(tmp_path / "above.csv", {"v": data[:, 0] + 10.0, "f": data[:, 1]}))
    spec = validate_spec(raw, "<test>", tmp_path)
    ctx, _ = context(spec, load_dataset(spec), AutoParams(), None)
    assert list(ctx.positions) == ["v"] and not ctx.signed and not ctx.sign_inputs()


def test_narx_neighbours_keep_every_one_of_more_terms_and_screen_them_refined():
    """Half and twice the terms with the validation stop leave the size where the least-squares growth stopped
    (EMPS: the same model, 0.0799 % screened, for 8 and 16 at most); the neighbours that keep all of 1.5 k and
    2 k terms are screened with their weights refined on the free run, where their size pays (EMPS: 12 kept,
    0.119 % least squares, 0.021 % refined, chosen)."""

    class Fitted:  # eight terms on lags u 0..2, y 1..2, degree 3
        embedding_ = type(
            "E", (), {"regressors": [type("R", (), {"name": n, "lag": k})() for n, k in [("x", 0), ("f", 2)]]}
        )
        exponents_ = [np.array([[1, 0], [0, 1], [3, 0]])]
        terms_ = [list(range(8))]
        selection_: dict = {}

    found = Found(Candidate("narx", {"max_terms": 8}, "a narx"), Fitted(), {}, 1.0)
    grown = narx_search.neighbours(_ctx({}), found)
    kept = {c.params["max_terms"]: c for c in grown if "terms kept" in c.summary}
    assert sorted(kept) == [12, 16]
    for m, cand in kept.items():
        assert cand.params["patience"] is None and cand.screen_cost is None and cand.cost == "mse_inf"
        assert cand.summary.endswith(f"all {m} terms kept (was 8)")
    capped = {c.params["max_terms"] for c in grown if "at most" in c.summary}
    assert capped == {4, 16}  # the validation-stopped sizes stay
    Fitted.terms_ = [list(range(narx_search.KEPT_UP_TO + 1))]  # a large model: its refined screening costs
    assert not any("terms kept" in c.summary for c in narx_search.neighbours(_ctx({}), found))


def test_several_outputs_get_a_linear_output_error_model_on_each_output_s_own_past():
    """Every output at every lag in every equation lets least squares couple the outputs into a drifting run
    (a 6 x 6 joint-velocity plant: 24.6 % validation NMSE, every term refined); each output on its own past
    is the output-error model of system identification (0.457 %)."""
    ctx = SearchContext(("x", "p"), ("f", "g"), 1.0, 6000, 2000, {})
    [own] = [c for c in narx_search.starting(ctx) if "own past" in c.summary]
    assert own.params["terms"] == {
        out: ["1", "x[t]", "x[t-1]", "x[t-2]", "p[t]", "p[t-1]", "p[t-2]", f"{out}[t-1]", f"{out}[t-2]"]
        for out in ("f", "g")
    }
    assert (
        own.cost == "mse_inf"
        and own.screen_cost is None
        and own.params["bounds"] == {"f": [None, None], "g": [None, None]}
    )
    [longer] = narx_search.neighbours(ctx, Found(own, None, {}, 1.0))
    assert (
        longer.params["terms"]["g"][-4:] == ["g[t-1]", "g[t-2]", "g[t-3]", "g[t-4]"]
        and "x[t-4]" in longer.params["terms"]["f"]
    )
    single = SearchContext(("x",), ("f",), 1.0, 6000, 2000, {})
    assert not any("own past" in c.summary for c in narx_search.starting(single))
