"""The family plugin contract as code: :func:`check_family` runs every contract check on a family class.

A third-party family package calls it from its own tests::

    from dynmodel.testing import check_family
    from my_family import MyFamily

    def test_contract(tmp_path):
        check_family(MyFamily, params={"order": 2}, tmp_path=tmp_path)

The checks fit the family on a small generated driven system (through the Python API, so the engine's
preprocessing and split layout apply) and verify: the declaration (name, description, a pydantic
``Params`` that forbids unknown keys and documents every field), a constructor that matches ``Params``,
``get_params`` / ``set_params`` / ``sklearn.base.clone``, fit and free-run prediction better than the
output's mean, the model-space methods and ``to_arrays`` / ``from_arrays``, an HDF5 round trip with
identical predictions, determinism from the seed (and ``stochastic`` telling the truth), and that test
outputs (NaN inside the fitting data) are never read. Hook checks run only for families that define the
hook (``driven_system`` for the reliability check today).

Extension point: a new hook of the contract gets its check next to these ones, registered with
:func:`family_check` (``hook=`` names the attribute whose presence enables it)::

    @family_check("extensions", hook="extensions")
    def _extensions(case: FamilyCase) -> None:
        ...  # call case.fitted().extensions(...) and require what the hook promises
"""

from __future__ import annotations

import inspect
import json
import math
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np
from pydantic import BaseModel

from .errors import DynmodelError
from .family import Family, NotFittedError, Simulation, defines_hook, field_doc, signature_default
from .metrics import COSTS

# ---------------------------------------------------------------------------- the generated system


def contract_system(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A stable, mildly nonlinear single-input single-output system in physical units (offsets and
    scales far from 0 and 1, so that scaling matters):

    v_t = 0.7 v_{t-1} + 0.5 e_t (e white),  x_t = 0.6 x_{t-1} + 0.8 v_{t-1} - 0.3 x_{t-1}^2 / (1 + x_{t-1}^2),
    u = 2 + 1.5 v,  y = 10 + 3 x.
    """
    rng = np.random.default_rng(seed)
    e = rng.standard_normal(n + 100)
    v = np.zeros(n + 100)
    x = np.zeros(n + 100)
    for t in range(1, n + 100):
        v[t] = 0.7 * v[t - 1] + 0.5 * e[t]
        x[t] = 0.6 * x[t - 1] + 0.8 * v[t - 1] - 0.3 * x[t - 1] ** 2 / (1.0 + x[t - 1] ** 2)
    return 2.0 + 1.5 * v[100:], 10.0 + 3.0 * x[100:]


# ---------------------------------------------------------------------------- checks and their registry


class FamilyContractError(AssertionError):
    """One or more contract checks failed; the message lists each with its reason."""


def require(condition: Any, message: str) -> None:
    """A contract requirement (raises AssertionError, also under ``python -O``)."""
    if not condition:
        raise AssertionError(message)


def require_identical(actual: np.ndarray, expected: np.ndarray, message: str) -> None:
    """Bit-for-bit equal arrays (NaN where NaN), else AssertionError with the size of the difference."""
    a, b = np.asarray(actual), np.asarray(expected)
    if a.shape != b.shape:
        raise AssertionError(f"{message}: shapes {a.shape} and {b.shape}")
    if not np.array_equal(a, b, equal_nan=True):
        differ = ~((a == b) | (np.isnan(a) & np.isnan(b)))
        worst = float(np.nanmax(np.abs(a - b))) if np.isfinite(a - b).any() else float("nan")
        raise AssertionError(f"{message}: {int(differ.sum())} of {a.size} values differ, by up to {worst:.3g}")


@dataclass(frozen=True)
class FamilyCheck:
    name: str
    run: Callable[[FamilyCase], None]
    #: run only for families that define this attribute (a hook of the contract); None: always
    hook: str | None = None

    def applies(self, cls: type) -> bool:
        return self.hook is None or defines_hook(cls, self.hook)


#: every contract check, in the order they run; extended with :func:`family_check`
CHECKS: list[FamilyCheck] = []


def family_check(name: str, *, hook: str | None = None) -> Callable[[Callable[[FamilyCase], None]], Any]:
    """Register a contract check ``fn(case)`` that raises AssertionError (see :func:`require`) on a
    breach; with ``hook``, it runs only for families that define that attribute."""

    def register(fn: Callable[[FamilyCase], None]) -> Callable[[FamilyCase], None]:
        if any(c.name == name for c in CHECKS):
            raise ValueError(f"a family check named '{name}' is already registered")
        CHECKS.append(FamilyCheck(name, fn, hook))
        return fn

    return register


@dataclass
class CheckResult:
    name: str
    status: str  # "passed", "failed" or "skipped"
    seconds: float = 0.0
    message: str = ""


@dataclass
class FamilyCase:
    """One family under test: its class, small parameters, the generated data and cached fits."""

    cls: type[Family]
    params: dict[str, Any]
    tmp_path: Path
    fit_options: dict[str, Any] = field(default_factory=dict)
    min_score: float = 0.0
    n_train: int = 800
    n_test: int = 300
    _fits: dict[int, Family] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self.u, self.y = contract_system(self.n_train, 1)
        self.u_test, self.y_test = contract_system(self.n_test, 2)

    def new(self, **overrides: Any) -> Family:
        return self.cls(**{**self.params, **overrides})

    def fit(self, seed: int = 0) -> Family:
        """A fresh fit on the training recording (the last 25 % validate)."""
        est = self.new()
        require(
            # fit on arrays: Family.fit routes non-TrainingData arguments at run time (family._routes_arrays)
            cast(Any, est).fit(self.u, self.y, validation=0.25, seed=seed, **self.fit_options) is est,
            "fit(u, y) on arrays returns self",
        )
        return est

    def fitted(self, seed: int = 0) -> Family:
        """The fit of ``seed``, made once per case."""
        if seed not in self._fits:
            self._fits[seed] = self.fit(seed)
        return self._fits[seed]

    def predict(self, model: Any) -> np.ndarray:
        """Free run of a fitted family or FittedModel over the test recording (tune-in from y)."""
        import warnings

        from .errors import ModelWarning

        warm = (model.model_ if isinstance(model, Family) else model).warmup
        with warnings.catch_warnings():  # the check's test input may leave the training range a little
            warnings.simplefilter("ignore", ModelWarning)
            return model.predict(self.u_test, self.y_test[:warm] if warm else None)


def check_family(
    cls: type[Family],
    params: Mapping[str, Any] | None = None,
    *,
    fit_options: Mapping[str, Any] | None = None,
    tmp_path: str | Path | None = None,
    min_score: float = 0.0,
    only: Iterable[str] | None = None,
    skip: Iterable[str] = (),
) -> list[CheckResult]:
    """Run the family contract checks on ``cls``; raise FamilyContractError listing every failure.

    ``params``: constructor arguments for the fits (small, so that the checks are fast);
    ``fit_options``: extra keywords for ``fit`` (e.g. ``cost="mse_inf"``); ``min_score``: the R^2 the
    free run on fresh data must exceed (0: better than the output's mean); ``only`` / ``skip``: check
    names. Returns one :class:`CheckResult` per check (passed or skipped)."""
    wanted = set(only) if only is not None else None
    unknown = ((wanted or set()) | set(skip)) - {c.name for c in CHECKS}
    if unknown:
        raise ValueError(f"unknown check(s) {sorted(unknown)}; known: {[c.name for c in CHECKS]}")
    with tempfile.TemporaryDirectory(prefix="dynmodel-check-") as scratch:
        case = FamilyCase(cls, dict(params or {}), Path(tmp_path or scratch), dict(fit_options or {}), min_score)
        results = []
        for check in CHECKS:
            if (wanted is not None and check.name not in wanted) or check.name in skip:
                continue
            if not check.applies(cls):
                results.append(CheckResult(check.name, "skipped", message=f"the family does not define {check.hook}"))
                continue
            t0 = time.perf_counter()
            try:
                check.run(case)
                results.append(CheckResult(check.name, "passed", time.perf_counter() - t0))
            except Exception as exc:  # every breach is reported, not only the first
                message = str(exc) or type(exc).__name__
                if not isinstance(exc, AssertionError):
                    message = f"{type(exc).__name__}: {message}"
                results.append(CheckResult(check.name, "failed", time.perf_counter() - t0, message))
    failed = [r for r in results if r.status == "failed"]
    if failed:
        lines = "\n".join(f"  {r.name}: " + r.message.replace("\n", "\n    ") for r in failed)
        raise FamilyContractError(f"{cls.__name__} breaks the family contract in {len(failed)} check(s):\n{lines}")
    return results


# ---------------------------------------------------------------------------- the checks


@family_check("declaration")
def _declaration(case: FamilyCase) -> None:
    cls = case.cls
    require(isinstance(cls, type) and issubclass(cls, Family), "a family subclasses dynmodel.family.Family")
    require(isinstance(cls.name, str) and cls.name, "a family sets its id in the class attribute `name`")
    require(isinstance(cls.description, str) and cls.description, "a family describes itself in `description`")
    require(isinstance(cls.stochastic, bool), "`stochastic` is True or False")
    require(cls.default_cost in COSTS, f"`default_cost` is one of {COSTS}")
    require(
        isinstance(cls.Params, type) and issubclass(cls.Params, BaseModel),
        "`Params` is a pydantic model (subclass dynmodel.family.FamilyParams)",
    )
    require(cls.Params.model_config.get("extra") == "forbid", "`Params` rejects unknown keys (extra='forbid')")
    undocumented = [n for n, f in cls.Params.model_fields.items() if not field_doc(f)]
    require(not undocumented, f"every parameter has a description; missing for {undocumented}")
    try:
        cls.Params()
    except Exception as exc:
        raise AssertionError(f"`Params()` with the defaults must be valid: {exc}") from None
    cls.Params.model_json_schema()  # `dynmodel schema` shows it


@family_check("constructor")
def _constructor(case: FamilyCase) -> None:
    cls = case.cls
    fields = cls.Params.model_fields
    sig = inspect.signature(cls)
    named = [p for p in sig.parameters.values() if p.kind is not inspect.Parameter.VAR_KEYWORD]
    if named:  # an explicit constructor (help and completion show it) must match Params exactly
        require(
            [p.name for p in named] == list(fields),
            f"the constructor's parameters {[p.name for p in named]} differ from Params {list(fields)}",
        )
        for p in named:
            require(p.kind is inspect.Parameter.KEYWORD_ONLY, f"'{p.name}' is keyword-only (write `*,` first)")
            want = signature_default(fields[p.name])
            require(
                p.default is want or p.default == want,
                f"the default of '{p.name}' is {p.default!r}, Params declares {want!r}"
                + (" (None stands for a factory default)" if fields[p.name].default_factory else ""),
            )
            require(p.annotation is not inspect.Parameter.empty, f"'{p.name}' has a type annotation")
    default = cls()
    require(default.params == cls.Params(), "cls() holds the declared defaults")
    case.new()
    try:
        cls(no_such_parameter=1)
    except (TypeError, ValueError) as exc:  # TypeError from an explicit signature, ValueError from Params
        require("no_such_parameter" in str(exc), f"the error for an unknown parameter names it: {exc}")
    else:
        raise AssertionError("an unknown constructor parameter is rejected")


@family_check("get_set_params")
def _get_set_params(case: FamilyCase) -> None:
    cls = case.cls
    fields = cls.Params.model_fields
    defaults = cls().get_params()
    require(list(defaults) == list(fields), f"get_params() lists the Params fields; got {list(defaults)}")
    require(
        all(defaults[n] == signature_default(f) for n, f in fields.items()),
        "get_params() of cls() returns the constructor defaults",
    )
    est = case.new()
    given = est.get_params(deep=False)
    require(all(given[k] is v for k, v in case.params.items()), "get_params returns the arguments as given")
    require(cls(**given).params == est.params, "cls(**get_params()) rebuilds the same parameters")
    require(est.set_params(**given) is est, "set_params returns self")
    before = est.get_params()
    for bad in ({"no_such_parameter": 1},):
        try:
            est.set_params(**bad)
        except ValueError:
            pass
        else:
            raise AssertionError(f"set_params({bad}) is rejected with a ValueError")
    require(est.get_params() == before, "a rejected set_params changes nothing")
    try:
        from sklearn.base import clone
    except ImportError:  # scikit-learn is optional
        return
    twin = clone(est)
    require(type(twin) is cls and twin is not est, "sklearn.base.clone gives a new object of the class")
    require(twin.params == est.params, "a clone has the same parameters")
    fitted_twin = clone(case.fitted())
    require(getattr(fitted_twin, "model_", None) is None, "a clone of a fitted family is not fitted")


@family_check("fit_predict")
def _fit_predict(case: FamilyCase) -> None:
    fam = case.fitted()
    require(any(k.endswith("_") and not k.startswith("_") for k in vars(fam)), "fitted attributes end in '_'")
    pred = case.predict(fam)
    require(isinstance(pred, np.ndarray) and pred.shape == (case.n_test, 1), f"predict gives (n, 1); {pred.shape}")
    warm = fam.model_.warmup
    require(np.isfinite(pred[warm:]).all(), "the free run on fresh data of the training range stays finite")
    score = fam.score(case.u_test, case.y_test)
    require(
        score > case.min_score,
        f"the free run on fresh data scores R^2 = {score:.4g}, not above {case.min_score:g} (the output's mean)",
    )
    unfitted = case.new()
    for call, what in ((lambda: unfitted.predict(case.u_test), "predict"),):
        try:
            call()
        except NotFittedError:
            pass
        else:
            raise AssertionError(f"{what} before fit raises NotFittedError")
    um = fam.model_.preprocessor.inputs(case.u_test)
    try:
        unfitted.simulate(um)
    except NotFittedError:
        pass
    except Exception as exc:
        raise AssertionError(
            f"simulate before fit raises NotFittedError (call self.check_fitted()), not {exc!r}"
        ) from None
    else:
        raise AssertionError("simulate before fit raises NotFittedError (call self.check_fitted())")


def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"{type(o).__name__} is not JSON-able")


@family_check("model_space")
def _model_space(case: FamilyCase) -> None:
    fam = case.fitted()
    model = fam.model_
    um = model.preprocessor.inputs(case.u_test)
    ym = model.preprocessor.outputs(case.y_test)
    warm = fam.warmup
    require(isinstance(warm, int) and warm >= 0, f"warmup is an integer >= 0; got {warm!r}")
    sim = fam.simulate(um, ym[:warm] if warm else None)
    require(isinstance(sim, Simulation), "simulate returns a dynmodel.family.Simulation")
    require(sim.y.shape == (len(um), 1) and sim.y.dtype == np.float64, f"simulate gives float64 (n, 1); {sim.y.shape}")
    require(
        sim.diverged_at is None or (isinstance(sim.diverged_at, int) and 0 <= sim.diverged_at < len(um)),
        f"diverged_at is None or a sample index; got {sim.diverged_at!r}",
    )
    one = fam.predict_one_step(um, ym)
    require(one is None or one.shape == (len(um), 1), "predict_one_step gives None or (n, n_outputs)")
    arrays, attrs = fam.to_arrays()
    for key, value in arrays.items():
        a = np.asarray(value)
        require(a.dtype.kind in "biuf", f"to_arrays: '{key}' is a numeric array (dtype {a.dtype})")
    try:
        json.dumps(attrs, default=_json_default)
    except TypeError as exc:
        raise AssertionError(f"to_arrays: the attributes are JSON-able ({exc})") from None
    again = type(fam).from_arrays(fam.params.model_dump(mode="json"), arrays, attrs)
    require(type(again) is type(fam), "from_arrays returns an instance of the class")
    require_identical(
        again.simulate(um, ym[:warm] if warm else None).y, sim.y, "from_arrays(to_arrays()) simulates identically"
    )


@family_check("save_load")
def _save_load(case: FamilyCase) -> None:
    from . import store

    fam = case.fitted()
    path = store.save(fam, case.tmp_path / f"{case.cls.__name__}-contract.h5")
    loaded = store.load(path, families={case.cls.name: case.cls})
    require(type(loaded.family) is case.cls, "the model file loads as the same family")
    require(loaded.family.params == fam.params, "the loaded family has the saved parameters")
    require(loaded.metrics == fam.model_.metrics, "the loaded model has the saved metrics")
    require_identical(case.predict(loaded), case.predict(fam), "predictions after load are identical")


@family_check("determinism")
def _determinism(case: FamilyCase) -> None:
    first = case.predict(case.fitted(0))
    require_identical(case.predict(case.fit(0)), first, "two fits with one seed predict identically")
    other = case.predict(case.fitted(1))
    same = np.array_equal(other, first, equal_nan=True)
    if case.cls.stochastic:
        require(not same, "the family declares stochastic = True, but seed 1 gives the fit of seed 0")
    else:
        require(same, "the family declares stochastic = False, but its fit depends on the seed")


@family_check("test_outputs_unread")
def _test_outputs_unread(case: FamilyCase) -> None:
    """A test range between the training and validation ranges: its outputs reach the family as NaN.
    The family either fits without reading them (finite predictions) or refuses, naming the test split."""
    from . import engine
    from .api import ArrayData, ArraySpec
    from .data.dataset import Recording, load_dataset
    from .spec import EvaluationSpec

    n = len(case.u)
    a, b = int(0.6 * n), int(0.8 * n)
    data = ArrayData(input=["u"], output=["y"], split={"train": (0, a), "test": (a, b), "validation": (b, n)})
    fam = case.new()
    spec = ArraySpec(fam, data, case.fit_options.get("cost", fam.default_cost), 0, EvaluationSpec())
    rec = Recording("contract", case.u[:, None].copy(), case.y[:, None].copy())
    ds = load_dataset(spec, {"data": ([rec], 1.0, ["u"], ["y"])})
    try:
        model, _ = engine.fit_family(fam, spec, ds)
    except DynmodelError as exc:
        require("test" in str(exc), f"a family that cannot fit around a test range says so, naming it: {exc}")
        return
    pred = case.predict(model)
    require(np.isfinite(pred[model.warmup :]).all(), "NaN test outputs were read: the predictions hold NaN")
    val = model.metrics["validation"]["nmse"]
    require(val is not None and math.isfinite(val), f"NaN test outputs were read: validation NMSE {val}")


@family_check("frozen_config", hook="frozen_config")
def _frozen_config(case: FamilyCase) -> None:
    """``family: auto``'s refit: the configuration a fit froze (and its warm start, if offered) fits again without
    a validation split, as the search fits it on every sample; None (the family declines) passes."""
    config = case.fitted().frozen_config()
    if config is None:
        return
    require(
        isinstance(config, dict) and isinstance(config.get("params"), dict), "frozen_config() gives {'params': {...}}"
    )
    cost = config.get("cost")
    require(cost is None or cost in COSTS, f"frozen_config()'s cost {cost!r} is None or one of {COSTS}")
    options = {**case.fit_options, **({"cost": cost} if cost else {})}
    starts = {"params": config["params"]}
    if config.get("warm") is not None:
        require(isinstance(config["warm"], dict), "frozen_config()'s 'warm' is params (a dict)")
        starts["warm"] = config["warm"]
    for name, params in starts.items():
        est = case.cls(**params)
        cast(Any, est).fit(case.u, case.y, validation=None, seed=0, **options)
        y = case.predict(est)
        require(np.all(np.isfinite(y)), f"the refit from frozen_config()'s '{name}' predicts non-finite outputs")


@family_check("driven_system", hook="driven_system")
def _driven_system(case: FamilyCase) -> None:
    from .reliability.system import DrivenSystem

    system = case.fitted().driven_system()
    if system is None:
        return
    require(isinstance(system, DrivenSystem), "driven_system() returns a dynmodel.reliability DrivenSystem or None")
    m = system.state_dim
    lo, hi = system.state_box()
    require(np.shape(lo) == (m,) and np.shape(hi) == (m,), "state_box() gives two arrays of state_dim values")
    X = np.zeros((2, m)) if system.rest_state is None else np.tile(system.rest_state, (2, 1))
    V = system.drive(np.tile(system.inputs.mean, (2, 1)))
    nxt = system.step(X, V)
    require(nxt.shape == (2, m) and np.isfinite(nxt).all(), "step() maps (R, M) states to finite (R, M) states")


@family_check("search_space", hook="search_space")
def _search_space(case: FamilyCase) -> None:
    """``family: auto``: the starting candidates and the neighbours are well-formed candidates of the family,
    with finite work estimates; the first one fits the contract system and scores; under a protocol that lets
    a run use no measured output (``max_warmup`` 0) the candidates need none."""
    from .search.space import Candidate, Found, SearchContext

    n_val = case.n_train // 4
    ctx = SearchContext(
        input_names=("u",),
        output_names=("y",),
        sampling_time=1.0,
        n_train=case.n_train - n_val,
        n_validation=n_val,
        data={"delay_lines": [], "derived_inputs": [], "detrend": []},
    )
    found = case.cls.search_space(ctx)
    require(isinstance(found, list) and found, "search_space(ctx) returns a non-empty list of Candidates")
    for cand in found:
        require(isinstance(cand, Candidate), f"search_space returns Candidates (got {type(cand).__name__})")
        require(cand.family == case.cls.name, f"a candidate of family '{cand.family}', not '{case.cls.name}'")
        require(cand.cost in (None, "mse1", "mse_inf"), f"candidate cost {cand.cost!r} is not mse1 or mse_inf")
        for w in (cand.work, cand.screen_work):
            require(w is None or (math.isfinite(w) and w >= 0), f"work estimate {w!r} is not a finite number >= 0")
        case.cls(**cand.params)  # the params are valid (ParameterError otherwise)
        if cand.screen:
            case.cls(**{**cand.params, **cand.screen})
    first = found[0]
    est = case.cls(**first.params)
    cast(Any, est).fit(case.u, case.y, validation=0.25, seed=0, cost=first.cost or case.cls.default_cost)
    score = est.score(case.u_test, case.y_test)
    require(score > case.min_score, f"the first candidate's free run scores R^2 {score:.3g} on fresh data")
    around = case.cls.search_space(ctx, Found(first, est, est.model_.metrics, 1.0))
    require(isinstance(around, list), "search_space(ctx, around) returns a list (possibly empty)")
    for cand in around:
        require(isinstance(cand, Candidate) and cand.family == case.cls.name, "neighbours are Candidates of the family")
        case.cls(**cand.params)
    from dataclasses import replace

    strict = case.cls.search_space(replace(ctx, max_warmup=0))
    for cand in strict[:2]:
        est = case.cls(**cand.params)
        cast(Any, est).fit(case.u, case.y, validation=0.25, seed=0, cost=cand.cost or case.cls.default_cost)
        require(
            est.warmup == 0,
            f"with max_warmup 0 (no measured output allowed) the candidate '{cand.summary}' needs {est.warmup}",
        )
