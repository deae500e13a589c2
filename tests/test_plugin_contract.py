"""The family plugin contract as code: check_family over every installed family and the example package,
and proof that each check catches the breach it is about."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import ROOT
from pydantic import Field

from dynmodel import registry
from dynmodel.data.training import TrainingData
from dynmodel.family import Family, FamilyParams, Simulation, constructor_arguments, no_progress
from dynmodel.testing import CHECKS, FamilyCheck, FamilyContractError, check_family, family_check

EXAMPLE = ROOT / "examples" / "dynmodel-arx"

#: small settings so that the contract checks take well under a second per family
SMALL: dict[str, dict[str, Any]] = {
    "narx": {},
    "esn": {"size": 40},
    "annealed-rnn": {"size": 10, "steps": 20},
    "lorenz-net": {"size": 4, "layers": 2, "extra_links": 2, "steps": 10, "time_scale": 0.1},
    "arx": {},
}
CORE_CHECKS = {
    "declaration",
    "constructor",
    "get_set_params",
    "fit_predict",
    "model_space",
    "save_load",
    "determinism",
    "test_outputs_unread",
}


@pytest.mark.parametrize("name", sorted(registry.families()))
def test_every_installed_family_keeps_the_contract(name, tmp_path):
    results = check_family(registry.families()[name], SMALL.get(name, {}), tmp_path=tmp_path)
    assert {r.name for r in results if r.status == "passed"} >= CORE_CHECKS


def _example_family():
    try:
        from dynmodel_arx import Arx
    except ImportError:  # not installed (CI installs it): check it from its source
        sys.path.insert(0, str(EXAMPLE / "src"))
        from dynmodel_arx import Arx
    return Arx


@pytest.mark.parametrize("cost", ["mse1", "mse_inf"])
def test_the_example_third_party_family_keeps_the_contract(cost, tmp_path):
    results = check_family(_example_family(), fit_options={"cost": cost}, tmp_path=tmp_path)
    assert [r.name for r in results if r.status == "skipped"] == ["frozen_config", "driven_system"]


def test_the_installed_example_is_the_one_in_examples():
    installed = registry.families().get("arx")
    if installed is None:
        pytest.skip("the example family is not installed (.ci/run installs it)")
    import inspect

    assert Path(inspect.getfile(installed)).read_text() == (EXAMPLE / "src" / "dynmodel_arx" / "model.py").read_text()


# ------------------------------------------------------------------ a minimal family, then broken on purpose


class LinearParams(FamilyParams):
    lags: int = Field(3, ge=1, description="input lags u(t) ... u(t - lags + 1) of the static readout")


class Linear(Family):
    """y(t) = w . [u(t), ..., u(t - lags + 1)] + c, by least squares: the smallest valid family."""

    name = "linear-test"
    description = "finite impulse response by least squares (a test family)"
    Params = LinearParams
    stochastic = False

    def __init__(self, *, lags: int = 3) -> None:
        super().__init__(**constructor_arguments(locals()))

    def _features(self, u: np.ndarray) -> np.ndarray:
        cols = [np.concatenate([np.zeros((k, u.shape[1])), u[: len(u) - k]]) for k in range(self.params.lags)]
        return np.hstack(cols + [np.ones((len(u), 1))])

    def fit(self, data: TrainingData, cost="mse1", rng=None, progress=no_progress):
        X = data.stack("train", [self._features(s.u) for s in data.series])
        self.w_ = np.linalg.lstsq(X, data.targets("train"), rcond=None)[0]
        return self

    def simulate(self, u, y_measured=None, bounds=None):
        self.check_fitted()
        return Simulation(self._features(np.asarray(u, dtype=np.float64)) @ self.w_)

    def to_arrays(self):
        return {"w": self.w_}, {}

    @classmethod
    def from_arrays(cls, params, arrays, attrs):
        self = cls(**params)
        self.w_ = np.asarray(arrays["w"], dtype=np.float64)
        return self


class ReadsTestOutputs(Linear):
    def fit(self, data, cost="mse1", rng=None, progress=no_progress):
        super().fit(data, cost, rng, progress)
        self.w_[-1] += 0.0 * np.mean(np.concatenate([s.y for s in data.series]))  # NaN inside test ranges
        return self


class SaysStochastic(Linear):
    stochastic = True  # but the fit never draws a random number


class HidesItsSeed(Linear):
    def fit(self, data, cost="mse1", rng=None, progress=no_progress):
        super().fit(data, cost, rng, progress)
        self.w_ = self.w_ + 1e-3 * rng.standard_normal(self.w_.shape)
        return self


class ForgetsAnArray(Linear):
    def to_arrays(self):
        return {"w": self.w_[:-1]}, {}

    @classmethod
    def from_arrays(cls, params, arrays, attrs):
        self = cls(**params)
        self.w_ = np.vstack([arrays["w"], np.zeros((1, arrays["w"].shape[1]))])
        return self


class FreezesWhatNeedsValidation(Linear):
    """Its fit needs a validation split, yet it offers a configuration to fit again without one (the annealed
    RNN inherited such a hook from the echo state network: family auto's refit failed after its work)."""

    def fit(self, data, cost="mse1", rng=None, progress=no_progress):
        if not data.has("validation"):
            raise ValueError("this family optimises on the validation split; give one")
        return super().fit(data, cost, rng, progress)

    def frozen_config(self):
        return {"params": {"lags": self.params.lags}, "cost": None}


class DriftingSignature(Linear):
    def __init__(self, *, lags: int = 4) -> None:  # Params says 3
        Family.__init__(self, **constructor_arguments(locals()))


def test_a_minimal_family_passes():
    assert all(r.status != "failed" for r in check_family(Linear))


@pytest.mark.parametrize(
    "cls, check, reason",
    [
        (ReadsTestOutputs, "test_outputs_unread", "NaN test outputs were read"),
        (SaysStochastic, "determinism", "declares stochastic = True, but seed 1 gives the fit of seed 0"),
        (HidesItsSeed, "determinism", "declares stochastic = False, but its fit depends on the seed"),
        (ForgetsAnArray, "save_load", "predictions after load are identical"),
        (ForgetsAnArray, "model_space", "from_arrays\\(to_arrays\\(\\)\\) simulates identically"),
        (DriftingSignature, "constructor", "the default of 'lags' is 4, Params declares 3"),
        (FreezesWhatNeedsValidation, "frozen_config", "optimises on the validation split"),
    ],
)
def test_each_check_catches_its_breach(cls, check, reason):
    with pytest.raises(FamilyContractError, match=reason):
        check_family(cls, only=[check])


def test_every_failure_is_listed_and_unknown_checks_are_refused():
    class Both(ForgetsAnArray, SaysStochastic):
        pass

    with pytest.raises(FamilyContractError, match="in 2 check\\(s\\):\n  save_load: .*\n  determinism: "):
        check_family(Both, only=["save_load", "determinism"])
    with pytest.raises(ValueError, match="unknown check"):
        check_family(Linear, only=["no-such-check"])


def test_a_hook_check_runs_only_for_families_that_define_the_hook():
    seen = []

    @family_check("test-hook", hook="test_hook")
    def _hook(case):
        seen.append(case.cls.test_hook())

    class WithHook(Linear):
        @staticmethod
        def test_hook():
            return "offered"

    try:
        assert check_family(Linear, only=["test-hook"])[0].status == "skipped"
        assert check_family(WithHook, only=["test-hook"])[0].status == "passed"
        assert seen == ["offered"]
    finally:
        CHECKS[:] = [c for c in CHECKS if c.name != "test-hook"]
    assert all(isinstance(c, FamilyCheck) for c in CHECKS)
