"""The contract between the engine and a model-family plugin, and the estimator face of a family.

A family is a class registered under the ``dynmodel.families`` entry-point group. It follows
scikit-learn habits: parameters in the constructor (validated by the family's pydantic
``Params`` model), ``fit`` returns ``self``, fitted attributes end in ``_``. All arrays the
family's own methods see and return are in model space (scaled, delay lines applied); the engine
does the conversion from and to physical units.

A plugin implements only the model-space ``fit(data: TrainingData, cost, rng, progress)``. This base
class makes the same object an estimator for arrays and DataFrames: ``Family.fit(u, y, ...)`` routes
anything that is not a :class:`TrainingData` through :func:`dynmodel.api.fit_arrays` (the engine's
preprocessing, split layout and evaluation), after which :meth:`Family.predict` and
:meth:`Family.score` work in physical units. ``get_params`` / ``set_params`` return and change the
constructor arguments as given, so ``sklearn.base.clone`` works. ``docs/plugins.md`` states the
contract; :func:`dynmodel.testing.check_family` checks it.
"""

from __future__ import annotations

import difflib
import functools
import inspect
import textwrap
import types
from abc import ABC, abstractmethod
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, Union, get_args, get_origin

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError, model_validator
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

from .data.training import TrainingData
from .errors import ParameterError
from .fields import refuse_booleans

if TYPE_CHECKING:
    from .extensions import Extension, ExtensionContext
    from .model import FittedModel
    from .reliability.system import DrivenSystem
    from .search.space import Candidate, Found, SearchContext

#: progress callback: (stage, fraction done in [0, 1] or None, message)
Progress = Callable[[str, "float | None", str], None]


def no_progress(stage: str, fraction: float | None, message: str) -> None:
    return None


class FamilyParams(BaseModel):
    """Base for a family's parameter model: unknown parameters are rejected."""

    model_config = ConfigDict(extra="forbid")

    @model_validator(mode="before")
    @classmethod
    def _no_booleans(cls, data: Any) -> Any:
        return refuse_booleans(cls, data)


@dataclass
class Simulation:
    """A free run: outputs (n, n_outputs), NaN from the sample where it diverged on."""

    y: np.ndarray
    diverged_at: int | None = None


class NotFittedError(RuntimeError):
    pass


def constructor_arguments(frame_locals: dict[str, Any]) -> dict[str, Any]:
    """The keyword arguments of an explicit family constructor, from ``locals()`` taken as its first
    statement: ``super().__init__(**constructor_arguments(locals()))``."""
    return {k: v for k, v in frame_locals.items() if k not in ("self", "__class__")}


def signature_default(field: FieldInfo) -> Any:
    """A parameter's default as the constructor shows it: the declared default, or None for a field
    whose default is built by a factory (a nested model such as ``refinement``), None meaning that
    built default."""
    if field.default_factory is not None or field.default is PydanticUndefined:
        return None
    return field.default


def _is_declared_default(field: FieldInfo, value: Any) -> bool:
    if field.default_factory is not None:
        return value is None
    default = field.default
    if value is default:
        return True
    try:
        return type(value) is type(default) and bool(value == default)
    except (TypeError, ValueError):
        return False


def _nested_update(current: Any, path: list[str], value: Any) -> dict[str, Any]:
    """``current`` (None, a mapping or a pydantic model) as a dict with ``path`` set to ``value``."""
    if isinstance(current, BaseModel):
        out = current.model_dump(exclude_unset=True, by_alias=True)
    elif isinstance(current, Mapping):
        out = dict(current)
    else:
        out = {}
    key = path[0]
    out[key] = value if len(path) == 1 else _nested_update(out.get(key), path[1:], value)
    return out


def _type_text(annotation: Any) -> str:
    """A readable type: ``int | None``, ``dict[str, list[int | LagRange]]``, ``'a' | 'b'``."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:
        return _type_text(args[0])
    if origin is Literal:
        return " | ".join(repr(a) for a in args)
    if origin in (Union, types.UnionType):
        return " | ".join(_type_text(a) for a in args)
    if annotation is type(None) or annotation is None:
        return "None"
    if origin is not None:
        return f"{getattr(origin, '__name__', str(origin))}[{', '.join(_type_text(a) for a in args)}]"
    return getattr(annotation, "__name__", str(annotation).replace("typing.", ""))


def field_doc(field: FieldInfo) -> str:
    """A parameter's description; for a nested model without one, the model's own docstring."""
    if field.description:
        return field.description
    nested = field.annotation
    if isinstance(nested, type) and issubclass(nested, BaseModel) and nested.__doc__:
        return " ".join(nested.__doc__.split())
    return ""


def params_doc(params: type[BaseModel]) -> str:
    """A numpydoc ``Parameters`` section from a params model (types, defaults and descriptions)."""
    lines = ["Parameters", "----------"]
    for name, field in params.model_fields.items():
        default = signature_default(field)
        shown = (
            f"None (default {type(field.get_default(call_default_factory=True)).__name__}())"
            if (field.default_factory is not None)
            else repr(default)
        )
        lines.append(f"{name} : {_type_text(field.annotation)}, default {shown}")
        lines += textwrap.wrap(field_doc(field), 96, initial_indent="    ", subsequent_indent="    ")
    return "\n".join(lines)


def _fit_on_arrays(
    self: Family,
    u: Any,
    y: Any,
    *,
    validation: float | tuple[Any, Any] | None = 0.2,
    cost: Literal["mse1", "mse_inf"] | None = None,
    seed: int = 0,
    sampling_time: float | None = None,
    input_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
    transient: int = 0,
    scaling: Literal["standard", "none"] = "standard",
    delay_lines: Sequence[int] = (),
    delay_form: Literal["copy", "difference"] = "copy",
    derived_inputs: Sequence[dict[str, Any]] = (),
    detrend: Sequence[Any] = (),
    spikes: Literal["replace", "keep"] = "replace",
    progress: Progress | bool | None = None,
) -> Family:
    """Fit on measured inputs ``u`` and outputs ``y`` in physical units; returns self.

    ``u``, ``y``: arrays (n,) or (n, channels), pandas Series / DataFrames (their names become the
    channel names), or lists of those for several recordings (a free run restarts at each).
    ``validation``: the fraction at the end of every recording held out for model selection (0.2,
    as ``data.split: {train: 0.8, validation: 0.2}``), separate recordings ``(u_val, y_val)``, or
    None (the whole data trains; families that select on a validation split then refuse).
    ``cost``, ``seed`` and the remaining keywords are the spec's ``cost``, ``seed`` and ``data``
    keys (scaling, transient, delay lines, derived inputs, detrending, spikes), applied exactly as
    ``dynmodel fit`` applies them (``cost`` None: the family's :attr:`default_cost`, as a spec
    without ``cost:``). ``sampling_time`` (s): None takes the step of a uniform pandas time index
    (DatetimeIndex, TimedeltaIndex), else 1 per sample. Channel names default to ``u`` / ``y`` (one channel) or ``u0``,
    ``u1``, ... ``progress``: a callback ``(stage, fraction, message)`` or True for progress on stderr.
    Spikes replaced in the training and validation outputs (``spikes="replace"``, the default) and a clipped
    output are told as :class:`~dynmodel.textfiles.DataNote` warnings; the arrays given are never changed.

    Afterwards ``model_`` holds the :class:`~dynmodel.model.FittedModel` (preprocessing, metrics of
    the train and validation splits in ``model_.metrics``); ``predict``, ``score`` and
    ``dynmodel.save`` use it.
    """
    options = constructor_arguments(locals())
    del options["u"], options["y"]
    from .api import fit_arrays

    # scikit-learn keeps constructor arguments as given (clone checks their identity), so a dict or list
    # changed after construction is validated and used here, as get_params reports it
    self.params = self._validated(self._given)
    fit_arrays(self, u, y, **options)
    return self


def _routes_arrays(model_space_fit: Callable[..., Any]) -> Callable[..., Any]:
    """Wrap a family's model-space ``fit``: the engine's TrainingData goes to it unchanged, anything
    else (arrays, DataFrames, lists of recordings) to :func:`_fit_on_arrays`."""

    @functools.wraps(model_space_fit)
    def fit(self, *args, **kwargs):
        first = args[0] if args else kwargs.get("data", kwargs.get("u"))
        if isinstance(first, TrainingData):
            return model_space_fit(self, *args, **kwargs)
        return _fit_on_arrays(self, *args, **kwargs)

    fit.__signature__ = inspect.signature(_fit_on_arrays)  # type: ignore[attr-defined]
    fit.__doc__ = (
        f"{_fit_on_arrays.__doc__}\n"
        "    Model space (the plugin contract, what the engine calls): "
        "``fit(data: TrainingData, cost, rng, progress)``.\n"
        f"    {(model_space_fit.__doc__ or '').strip()}\n"
    )
    fit._routes_arrays = True  # type: ignore[attr-defined]
    return fit


class Family(ABC):
    #: after a fit (on arrays or through the engine): the FittedModel in physical units
    model_: FittedModel
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    Params: ClassVar[type[FamilyParams]] = FamilyParams
    #: what to try when a free run diverges (the fix of the one-line error)
    stability_hint: ClassVar[str] = "use cost: mse_inf"
    #: the cost a spec without ``cost:`` fits with ('mse1' or 'mse_inf'): what the family's estimation
    #: does best for a model that is evaluated in free run
    default_cost: ClassVar[str] = "mse1"
    #: what to try when the model needs more measured outputs (``warmup``) than a protocol's
    #: initialization window allows; ``{window}`` is replaced by the window's length
    warmup_hint: ClassVar[str] = "configure the model to start from at most {window} measured outputs"
    #: does ``fit`` draw random numbers (network weights, annealing moves)? Then a result depends on the
    #: seed, and ``dynmodel diagnose`` repeats fits over seeds to measure a gain's uncertainty
    stochastic: ClassVar[bool] = True

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        fit = cls.__dict__.get("fit")
        if fit is not None and not getattr(fit, "_routes_arrays", False):
            cls.fit = _routes_arrays(fit)  # type: ignore[method-assign]
        own = cls.__dict__.get("__doc__") or cls.description or ""
        if "Parameters\n" not in own:
            cls.__doc__ = f"{own.rstrip()}\n\n{params_doc(cls.Params)}\n" if own else f"{params_doc(cls.Params)}\n"

    def __init__(self, **params: Any) -> None:
        """Generic constructor: ``params`` are the fields of ``Params``. A family writes its own
        keyword-only constructor (so that help and completion show the parameters) that calls this
        with :func:`constructor_arguments`; :func:`dynmodel.testing.check_family` checks that it
        matches ``Params``."""
        self.params = self._validated(params)
        self._given = dict(params)

    @classmethod
    def _validated(cls, given: Mapping[str, Any]) -> FamilyParams:
        """``Params`` from constructor arguments; ParameterError (a ValueError) names the first problem.

        Arguments equal to their declared default are left out, so that the model's
        ``model_fields_set`` holds what the user chose (a validator may compare a chosen value with
        another parameter); None stands for the built default of a factory field."""
        fields = cls.Params.model_fields
        unknown = [k for k in given if k not in fields]
        if unknown:
            close = difflib.get_close_matches(unknown[0], list(fields), n=1)
            fix = (f"did you mean '{close[0]}'? " if close else "") + f"Parameters: {', '.join(fields)}"
            raise ParameterError(f"unknown parameter '{unknown[0]}'", cls.__name__, fix)
        chosen = {k: v for k, v in given.items() if not _is_declared_default(fields[k], v)}
        try:
            return cls.Params(**chosen)
        except ValidationError as exc:
            from .spec import validation_summary

            raise ParameterError(
                validation_summary(exc), cls.__name__, f"see help({cls.__name__}) for the allowed values"
            ) from None

    #: scikit-learn < 1.6 reads the estimator type here (``is_regressor``)
    _estimator_type = "regressor"

    def __sklearn_tags__(self) -> Any:
        """scikit-learn >= 1.6: a regressor of (n, inputs) arrays on (n,) or (n, outputs) targets, no NaN, that
        must be fitted; so ``is_regressor``, ``cross_val_score`` and ``GridSearchCV`` take it (folds of a time
        series: ``TimeSeriesSplit``, each fold a recording of its own)."""
        from sklearn.utils import InputTags, RegressorTags, Tags, TargetTags

        return Tags(
            estimator_type="regressor",
            target_tags=TargetTags(required=True, multi_output=True, single_output=True),
            regressor_tags=RegressorTags(),
            input_tags=InputTags(one_d_array=True, two_d_array=True, allow_nan=False),
        )

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Constructor arguments as given, declared defaults for the others (scikit-learn; ``deep``
        is accepted for compatibility: a family holds no nested estimators)."""
        return {
            name: self._given[name] if name in self._given else signature_default(field)
            for name, field in self.Params.model_fields.items()
        }

    def set_params(self, **params: Any) -> Family:
        """Change constructor arguments and validate them all again; returns self. A nested field is
        reached with a double underscore: ``set_params(refinement__max_nfev=50)``. On an error nothing
        changes."""
        given = dict(self._given)
        for key, value in params.items():
            name, *path = key.split("__")
            if path and name in self.Params.model_fields:
                given[name] = _nested_update(given.get(name), path, value)
            else:
                given[name] = value
        self.params = self._validated(given)
        self._given = given
        return self

    def __repr__(self) -> str:
        fields = self.Params.model_fields
        shown = [f"{k}={v!r}" for k, v in self._given.items() if k in fields and not _is_declared_default(fields[k], v)]
        return f"{type(self).__name__}({', '.join(shown)})"

    # -- the estimator in physical units (after fit on arrays, or for an engine-fitted model) ---------
    def predict(self, u: Any, y_tune: Any = None) -> Any:
        """Free-running prediction from the rest state in physical units: an array (n, n_outputs), or a
        DataFrame (index of ``u``, output names as columns) when ``u`` is a DataFrame or Series.

        ``y_tune``: measured outputs, at least the first :attr:`warmup` samples (tune-in of external
        networks, initial values of NARX models); ``model_.predict_one_step(u, y)`` gives one-step
        predictions."""
        return self._fitted_model().predict(u, y_tune)

    def score(self, u: Any, y: Any) -> float:
        """R^2 of the free run on ``(u, y)`` (higher is better, 1 is perfect, 0 the level of the mean):
        1 - NMSE / 100 averaged over outputs, the first :attr:`warmup` samples of every recording being
        the tune-in taken from ``y``; -inf when the free run diverges. See :meth:`FittedModel.score`."""
        return self._fitted_model().score(u, y)

    def _fitted_model(self) -> FittedModel:
        model = getattr(self, "model_", None)
        if model is None:
            raise NotFittedError(
                f"this {type(self).__name__} has no preprocessing to work in physical units; call fit(u, y) first"
            )
        return model

    # -- fitting -------------------------------------------------------------------------
    @abstractmethod
    def fit(
        self,
        data: TrainingData,
        cost: str = "mse1",
        rng: np.random.Generator | None = None,
        progress: Progress = no_progress,
    ) -> Family:
        """Fit to ``data`` minimising ``cost`` ('mse1' or 'mse_inf'); return self."""

    # -- prediction ----------------------------------------------------------------------
    @property
    def warmup(self) -> int:
        """Samples at the start of a run that use measured outputs (tune-in); 0 for pure simulators.
        Known before ``fit`` where the parameters fix it, so that a protocol's window is checked
        before a long fit (and again after it)."""
        return 0

    @abstractmethod
    def simulate(
        self, u: np.ndarray, y_measured: np.ndarray | None = None, bounds: tuple[np.ndarray, np.ndarray] | None = None
    ) -> Simulation:
        """Free run over ``u`` (n, n_inputs) from the rest state.

        ``y_measured`` provides at least the first ``warmup`` measured outputs. When the
        output leaves ``bounds`` (lo, hi) the run stops and reports the sample.
        """

    def predict_one_step(self, u: np.ndarray, y_measured: np.ndarray) -> np.ndarray | None:
        """One-step-ahead predictions, or None where they equal the free run."""
        return None

    # -- persistence ---------------------------------------------------------------------
    @abstractmethod
    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Fitted state as plain arrays and JSON-able attributes (no pickles)."""

    @classmethod
    @abstractmethod
    def from_arrays(cls, params: dict[str, Any], arrays: dict[str, np.ndarray], attrs: dict[str, Any]) -> Family:
        """Rebuild a fitted model from :meth:`to_arrays` output."""

    # -- reliability -----------------------------------------------------------------------
    def driven_system(self) -> DrivenSystem | None:
        """The fitted model as a batched driven system x_t = f(x_{t-1}, v_t) in model space, for
        ``dynmodel reliability-check`` (see :mod:`dynmodel.reliability.system`); None when the
        family has no state to test."""
        return None

    def check_data(self, input_names: Sequence[str], output_names: Sequence[str], splits: Collection[str]) -> None:
        """Refuse, with a ValueError (one line: what and how to fix), data this configuration cannot be fitted on,
        before any fit: ``input_names`` are the model's inputs (delay copies and derived channels included),
        ``splits`` the splits the data have (``validation`` when a validation split exists). Names in the
        parameters that are no column, a validation split the configuration selects on. ``dynmodel validate``
        and ``fit`` call it; the default checks nothing."""
        return None

    def summary(self) -> dict[str, Any]:
        """A few facts for `dynmodel inspect`."""
        return {}

    def stored_values(self) -> int:
        """The number of floating-point values in the fitted model's arrays (:meth:`to_arrays`)."""
        arrays, _ = self.to_arrays()
        return int(sum(np.size(a) for a in arrays.values() if np.issubdtype(np.asarray(a).dtype, np.floating)))

    def fitted_values(self) -> int:
        """The number of values the fit estimated from the data: the model's size for ``family: auto``, which
        prefers the simpler of two models that validate alike. Default :meth:`stored_values`; override it where
        the arrays hold values drawn at random and never fitted (an echo state network's reservoir)."""
        return self.stored_values()

    # -- extensions (dynmodel diagnose, family: auto; docs/plugins-extensions.md) ------------
    @classmethod
    def extensions(cls, cause: str, ctx: ExtensionContext) -> list[Extension]:
        """Changes of the spec this family offers for ``cause`` (a diagnosis cause id, e.g.
        'output-nonlinearity', 'missing-dynamics'), as merge patches with one-line summaries, most
        promising first; [] for causes it has nothing for. When ``ctx.family`` is another family, only
        proposals that switch the spec to this family (see :func:`dynmodel.extensions.switch_family`)."""
        return []

    @classmethod
    def include_inputs(cls, channels: list[str], history: int, ctx: ExtensionContext) -> dict[str, Any]:
        """Patch that makes a model of this family (``ctx.family``) use the new model-input ``channels``
        (delay lines, derived inputs) with ``history`` past samples of each (0: the current value only);
        {} when the family uses every model input anyway."""
        return {}

    # -- the model search (family: auto; docs/plugins.md, docs/auto.md) -------------------------
    @classmethod
    def search_space(cls, ctx: SearchContext, around: Found | None = None) -> list[Candidate]:
        """Candidate configurations of this family for ``family: auto``, most promising first, each a
        :class:`dynmodel.search.space.Candidate` (params, cost, data-side patch, work estimate).

        ``around`` None: the starting candidates for the data ``ctx`` describes (sizes, the protocol's
        initialization window, how far test inputs leave the training range). ``around`` a measured
        candidate of this family that did well (:class:`dynmodel.search.space.Found`, with its fitted
        instance): its neighbours, the ways to grow it. Cheap (no fitting). [] (the default): the family
        takes no part in the search."""
        return []

    @classmethod
    def full_work(cls, ctx: SearchContext, found: Found) -> float | None:
        """Seconds of one full fit of ``found.candidate`` (its full variant on ``ctx.n_train`` training samples,
        as :attr:`Candidate.work`), estimated again from its screening fit ``found`` (what that fit chose: its
        size); None (the default): the candidate's own estimate stands. Cheap (no fitting). The search uses a
        larger answer only to leave out a full fit the budget cannot take (docs/plugins.md)."""
        return None

    def frozen_config(self) -> dict[str, Any] | None:
        """How to fit this fitted model's configuration again on other data without a validation split, every
        choice it made on validation frozen (a selected structure, a tuned factor): ``{"params": {...}, "cost":
        name or None}`` (None: the cost it was fitted with), optionally with ``"warm": {...}``: params that start
        from this model's own fitted values (a warm start; fitted with this model's preprocessing, in whose
        scaling the values hold), tried when the refit from ``params`` fails or stalls (not when its run leaves
        the band), or first (``"warm_first": True``) with ``params`` as the fallback; None (the default) when it
        cannot. ``family: auto`` refits its choice so on the training and validation samples together, so that
        the model it keeps learns from every sample the search may read (docs/auto.md)."""
        return None

    def check_fitted(self) -> None:
        if not any(k.endswith("_") and not k.startswith("_") for k in vars(self)):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit() first")


def defines_hook(cls: type, hook: str) -> bool:
    """Does ``cls`` provide ``hook`` beyond what :class:`Family` itself defines (an optional hook of the contract:
    ``frozen_config``, ``search_space``, ...)?"""
    mine = inspect.getattr_static(cls, hook, None)
    return mine is not None and mine is not inspect.getattr_static(Family, hook, None)
