"""The family extension hook (docs/plugins-extensions.md): families offer their own extensions through the
plugin contract, the same proposals serve a search without a diagnosis, a third-party family gets them by
implementing the hook, and the detectors name no family."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT
from hidden_effects import HIDDEN

from dynmodel import registry
from dynmodel.diagnose import Settings, diagnose
from dynmodel.extensions import (
    Extension,
    ExtensionContext,
    family_extensions,
    merge,
    params_patch,
    switch_family,
    with_inputs,
)
from dynmodel.spec import spec_model, validate_spec
from dynmodel_plugins.esn.params import EsnParams
from dynmodel_plugins.narx.embedding import default_lag_table
from dynmodel_plugins.narx.extensions import expand

CAUSES = sorted(set(registry.detectors()) | {"inadequate-structure"})
EVIDENCE = {
    "missing-dynamics": {"order": 6},
    "unmodeled-oscillation": {"period_samples": 12.0},
    "inadequate-structure": {"reference": {"output_order": 4, "input_order": 5}},
}


def _raw(family: str, params: dict | None = None) -> dict:
    data = {"generator": "narx-system", "n": 3000, "split": {"train": 0.6, "validation": 0.2, "test": 0.2}}
    return {"name": "x", "data": data, "model": {"family": family, "params": dict(params or {})}}


def _context(raw: dict, tmp_path: Path, **kw) -> ExtensionContext:
    """What a search has before fitting: the resolved spec, channel names, sampling time."""
    spec = validate_spec(raw, "<test>", tmp_path)
    return ExtensionContext.from_spec(spec.resolved(), ["u"], ["y"], 1.0, written=raw, **kw)


@pytest.mark.parametrize("family", ["narx", "esn", "annealed-rnn"])
def test_every_proposal_is_a_valid_spec_without_a_diagnosis(family, tmp_path):
    raw = _raw(family)
    offered = 0
    for cause in CAUSES:
        ctx = _context(raw, tmp_path, evidence=EVIDENCE.get(cause, {}))
        for ext in family_extensions(cause, ctx):
            assert isinstance(ext, Extension) and ext.summary and "\n" not in ext.summary
            patched = validate_spec(merge(raw, ext.patch), "<test>", tmp_path)  # raises when invalid
            assert patched.resolved() != validate_spec(raw, "<test>", tmp_path).resolved(), (cause, ext.summary)
            offered += 1
    assert offered >= 5


def test_narx_offers_a_higher_degree_and_output_terms_for_an_output_nonlinearity(tmp_path):
    ctx = _context(_raw("narx", {"degree": 2}), tmp_path)
    props = family_extensions("output-nonlinearity", ctx)
    degrees = [p.patch["model"]["params"].get("degree") for p in props if "model" in p.patch]
    assert 3 in degrees and 4 in degrees
    terms = next(p for p in props if "output-dependent" in p.summary)
    # the default lag table, asked of the family, written out with one more output lag
    lags = terms.patch["model"]["params"]["lags"]
    default = default_lag_table(["u"], ["y"], 2)
    assert expand(lags["u"]) == default["u"] and expand(lags["y"]) == [*default["y"], max(default["y"]) + 1]
    # a polynomial cannot follow a direction-dependent friction force: esn offers to replace it
    switch = [p for p in family_extensions("direction-dependence", ctx) if p.patch.get("model", {}).get("family")]
    assert switch and switch[0].patch["model"]["family"] == "esn"


def test_narx_with_linear_inputs_offers_input_monomials_for_a_static_nonlinearity(tmp_path):
    """A model whose inputs enter linearly (input_terms: linear) cannot form a static input nonlinearity at any
    degree: the family offers every monomial of its inputs first; one that has them is offered degrees only."""
    linear = family_extensions("static-nonlinearity", _context(_raw("narx", {"input_terms": "linear"}), tmp_path))
    assert linear[0].patch["model"]["params"] == {"input_terms": "any"}
    full = family_extensions("static-nonlinearity", _context(_raw("narx"), tmp_path))
    assert full and all("input_terms" not in p.patch["model"]["params"] for p in full)


def test_narx_lag_order_proposal_follows_the_evidence_and_stays_in_the_pool(tmp_path):
    ctx = _context(_raw("narx", {"degree": 3}), tmp_path, evidence={"order": 30})
    (lags,) = [p for p in family_extensions("missing-dynamics", ctx) if "longer lags" in p.summary]
    table = lags.patch["model"]["params"]["lags"]
    patched = validate_spec(merge(_raw("narx", {"degree": 3}), lags.patch), "<test>", tmp_path)
    p = patched.model.params
    expanded = p.lag_table()
    assert max(expanded["u"]) == 30 and max(expanded["y"]) == 30 and table
    n = sum(len(v) for v in expanded.values())
    from math import comb

    assert comb(n + 3, 3) <= p.max_pool  # thinned to stay below the pool limit


def test_esn_sizes_come_from_the_family_not_from_an_assumption(tmp_path):
    default = EsnParams().size
    ctx = _context(_raw("esn"), tmp_path)
    (larger,) = [p for p in family_extensions("unmodeled-oscillation", ctx) if "larger" in p.summary]
    assert larger.patch == params_patch(size=2 * default) and f"was {default}" in larger.summary
    ctx = _context(_raw("esn", {"size": 37}), tmp_path)
    (larger,) = [p for p in family_extensions("unmodeled-oscillation", ctx) if "larger" in p.summary]
    assert larger.patch == params_patch(size=74)


def test_new_channels_enter_through_the_family(tmp_path):
    narx = _context(_raw("narx"), tmp_path)
    patch = with_inputs(narx, delay_lines=[40], derived=[{"time": "linear"}], history=2)
    assert patch["data"] == {"delay_lines": [40], "derived_inputs": [{"time": "linear"}]}
    lags = patch["model"]["params"]["lags"]
    assert (
        lags["u@40"] == [0, 1, 2]
        and lags["time_linear"] == [0, 1, 2]
        and expand(lags["u"]) == default_lag_table(["u"], ["y"], 3)["u"]
    )
    esn = _context(_raw("esn"), tmp_path)
    assert with_inputs(esn, delay_lines=[40], history=2) == {"data": {"delay_lines": [40]}}  # a network takes them
    diff = _context({**_raw("narx"), "data": {**_raw("narx")["data"], "delay_form": "difference"}}, tmp_path)
    assert "u~40" in with_inputs(diff, delay_lines=[40])["model"]["params"]["lags"]


def test_a_family_switch_deletes_the_old_parameters(tmp_path):
    raw = _raw("narx", {"degree": 3, "lags": {"u": [0, 1], "y": [1]}})
    ctx = _context(raw, tmp_path)
    patch = switch_family(ctx, "esn", {"size": 50}, cost="mse1")
    spec = validate_spec(merge(raw, patch), "<test>", tmp_path)
    assert spec.model.family == "esn" and spec.model.params.size == 50 and spec.cost == "mse1"


def test_a_third_party_family_gets_model_side_proposals(monkeypatch, tmp_path):
    """A family registered by another package offers its own extension through the hook: the diagnosis
    measures it (here a polynomial family whose hook proposes a cubic term for an output nonlinearity)."""
    Narx = registry.families()["narx"]

    class Poly(Narx):
        name = "thirdparty-poly"

        @classmethod
        def extensions(cls, cause, ctx):
            if cause == "output-nonlinearity" and ctx.family == cls.name:
                return [Extension("the third party's cubic terms", {"model": {"params": {"degree": 3}}})]
            return []

        @classmethod
        def include_inputs(cls, channels, history, ctx):
            return {}

    table = dict(registry.families(), **{"thirdparty-poly": Poly})
    monkeypatch.setattr(registry, "families", lambda: table)
    spec_model.cache_clear()
    try:
        case = HIDDEN["output-nonlinearity"](7)
        case.model = {"family": "thirdparty-poly", "params": {"degree": 2, "lags": {"u": [0, 1, 2], "y": [1, 2]}}}
        result = diagnose(case.spec(tmp_path), "<test>", tmp_path, Settings(rounds=1))
    finally:
        monkeypatch.undo()
        spec_model.cache_clear()
    assert result.verdict == "output-nonlinearity"
    assert result.findings[0].extensions[0].summary == "the third party's cubic terms"
    assert result.rounds[0].chosen.extension.summary == "the third party's cubic terms"
    assert result.gain["relative_reduction"] > 0.9


def test_the_detectors_name_no_family():
    families = sorted(registry.families())
    for path in sorted((ROOT / "plugins" / "detectors").glob("*.py")):
        text = path.read_text()
        for name in families:
            assert not re.search(rf"[\"']{re.escape(name)}[\"']", text), f"{path.name} names the family {name}"
    for path in sorted((ROOT / "dynmodel" / "diagnose").glob("*.py")) + [ROOT / "dynmodel" / "extensions.py"]:
        text = path.read_text()
        for name in families:
            assert not re.search(rf"[\"']{re.escape(name)}[\"']", text), f"{path.name} names the family {name}"


def test_memory_and_fitted_model_reach_the_hook_in_a_diagnosis(tmp_path):
    from dynmodel.diagnose.context import Context
    from dynmodel.diagnose.fitting import Fitter

    case = HIDDEN["structure-stopped-early"](7)
    fitter = Fitter("<test>", tmp_path)
    fit = fitter.fit(case.spec(tmp_path))
    ctx = Context(fit, Settings(), fitter)
    ectx = ctx.extension_context({"order": 3})
    assert ectx.fitted is fit.model.family and ectx.n_train > 1000 and ectx.evidence == {"order": 3}
    kept = max(len(t) for t in fit.model.family.terms_)
    (more,) = family_extensions("structure-stopped-early", ectx)
    assert more.patch["model"]["params"]["max_terms"] == max(2 * kept, kept + 6)
    assert np.isfinite(ctx.memory) and ctx.extension_context().memory == ctx.memory
