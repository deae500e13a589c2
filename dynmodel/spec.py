"""The YAML spec: pydantic v2 models, loading, and one-line error messages.

Top-level keys: ``name``, ``data``, ``model``, ``cost``, ``evaluation``, ``seed``, ``output``.
``data`` is a file source (``path``) or a generator source (``generator``); ``model`` is a
union keyed on ``family`` whose ``params`` are validated by the family's own pydantic model.
Both unions are built from the installed plugins, so ``dynmodel schema`` shows every
family's and generator's parameters. Unknown keys are rejected everywhere.
"""

from __future__ import annotations

import difflib
import json
import re
from functools import cache
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union, cast, get_args, get_origin

import yaml
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    Tag,
    ValidationError,
    create_model,
    field_validator,
    model_validator,
)
from typing_extensions import Self

from . import registry
from .errors import SpecError
from .fields import NUMBER_NOT_BOOLEAN, refuse_booleans
from .metrics import DEFAULT_METRICS, MetricName

#: field separators by name, and as written in single-quoted YAML (where '\t' stays a backslash and a t)
DELIMITER_NAMES = {"tab": "\t", "\\t": "\t", "comma": ",", "semicolon": ";", "space": " ", "pipe": "|"}


def _delimiter(value: Any) -> Any:
    """One character; ``tab``, ``comma``, ``semicolon``, ``space``, ``pipe`` or ``\t`` name one."""
    if isinstance(value, str):
        value = DELIMITER_NAMES.get(value.strip().lower() if value.strip() else value, value)
        if len(value) != 1:
            raise ValueError(
                f"the delimiter {value!r} is not one character: give one (',', ';', '|') or a name: tab, comma, "
                "semicolon, space, pipe"
            )
    return value


Delimiter = Annotated[str, BeforeValidator(_delimiter)]

SPLITS = ("train", "validation", "test")
SplitName = Literal["train", "validation", "test"]


class StrictModel(BaseModel):
    """Base for every spec section: unknown keys are errors."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    @model_validator(mode="before")
    @classmethod
    def _no_booleans(cls, data: Any) -> Any:
        return refuse_booleans(cls, data)


#: ``data.path`` of recordings given in Python (``dynmodel.fit(spec, data=...)``), never a file
IN_MEMORY = "<arrays>"

SplitBound = Union[
    Annotated[float, Field(gt=0.0, le=1.0)], tuple[Annotated[int, Field(ge=0)], Annotated[int, Field(ge=0)]]
]


class SplitSpec(StrictModel):
    """Where each split lies inside every recording of the main source.

    Fractions are consecutive, in the order train, validation, test. Sample ranges are
    half-open ``[start, stop)`` indices within each recording.
    """

    train: Optional[SplitBound] = None
    validation: Optional[SplitBound] = None
    test: Optional[SplitBound] = None

    @field_validator("train", "validation", "test", mode="before")
    @classmethod
    def _fraction_or_range(cls, v: Any) -> Any:
        """A sample count written where a fraction goes gets the range form in its message."""
        if isinstance(v, (int, float)) and not isinstance(v, bool) and v > 1:
            raise ValueError(
                f"{v:g} is neither a fraction of each recording (0 < f <= 1) nor a sample range; for a number of "
                f"samples write the range [start, stop], e.g. [0, {int(v)}]"
            )
        return v

    @model_validator(mode="after")
    def _consistent(self) -> SplitSpec:
        given = {k: v for k, v in self.items()}
        if not given:
            raise ValueError("give at least the train part, e.g. {train: 0.7, validation: 0.3}")
        kinds = {type(v) is tuple for v in given.values()}
        if len(kinds) > 1:
            raise ValueError("use either fractions for every split or sample ranges for every split, not both")
        if kinds == {False}:
            total = sum(given.values())
            if total > 1.0 + 1e-9:
                raise ValueError(f"the fractions add up to {total:g}, more than 1")
        else:
            ranges = sorted((v[0], v[1], k) for k, v in given.items())
            for a, b, k in ranges:
                if b <= a:
                    raise ValueError(f"{k} range [{a}, {b}] is empty; write [start, stop] with stop > start")
            for (a1, b1, k1), (a2, b2, k2) in zip(ranges, ranges[1:]):
                if a2 < b1:
                    raise ValueError(f"{k1} [{a1}, {b1}] and {k2} [{a2}, {b2}] overlap")
        return self

    def items(self):
        return [(k, getattr(self, k)) for k in SPLITS if getattr(self, k) is not None]


class NoiseSpec(StrictModel):
    """Gaussian measurement noise added to the output of chosen splits (noisy-training experiments)."""

    std: float = Field(ge=0.0, description="noise std as a fraction of the clean output std")
    splits: list[SplitName] = Field(default_factory=lambda: cast(list[SplitName], ["train", "validation"]))
    seed: Optional[int] = Field(None, ge=0, description="noise seed; default derived from the spec seed")


class ChannelFiles(StrictModel):
    """One recording whose input and output columns lie in two files (e.g. uval.mat and yval.mat)."""

    input: str = Field(description="the file holding the input columns")
    output: str = Field(description="the file holding the output columns (same number of samples)")


def _path_tag(value: Any) -> str:
    return "list" if isinstance(value, list) else "files" if isinstance(value, (dict, ChannelFiles)) else "file"


_OnePath = Annotated[
    Union[Annotated[str, Tag("file")], Annotated[ChannelFiles, Tag("files")]],
    Discriminator(
        _path_tag, custom_error_type="path", custom_error_message="write a file name or {input: FILE, output: FILE}"
    ),
]
#: a data file, a recording split over an input file and an output file, or a list of either
PathSpec = Annotated[
    Union[Annotated[str, Tag("file")], Annotated[ChannelFiles, Tag("files")], Annotated[list[_OnePath], Tag("list")]],
    Discriminator(
        _path_tag, custom_error_type="path", custom_error_message="write a file name or {input: FILE, output: FILE}"
    ),
]


class FileSourceFields(StrictModel):
    path: PathSpec = Field(
        description="CSV/TXT (header row), NPZ, HDF5 or MATLAB .mat; {input: FILE, output: FILE} when the input "
        "and output columns lie in two files; a list means several recordings"
    )
    input: list[Union[str, int]] = Field(
        min_length=1,
        description="input columns (CSV header names, NPZ keys, HDF5 dataset paths, MAT variables; 'name[j]' picks column j)",
    )
    output: list[Union[str, int]] = Field(min_length=1, description="output columns")
    header: bool = Field(True, description="text files: first row holds the column names")
    columns: Optional[list[str]] = Field(None, description="names for the columns of a headerless text file")
    delimiter: Optional[Delimiter] = Field(
        None,
        description="text files: field separator, one character or tab, comma, semicolon, space, pipe (detected "
        "when omitted)",
    )
    segments: Optional[list[tuple[int, int]]] = Field(
        None, description="several recordings inside one file, as [start, stop) sample ranges"
    )
    sampling_time: Optional[float] = Field(None, gt=0, description="seconds per sample (default 1)")
    time_column: Optional[Union[str, int]] = Field(
        None,
        description="column of time stamps; without resample the stamps must be uniform and give the sampling time",
    )
    time_unit: float = Field(1.0, gt=0, description="seconds per unit of the time column (0.001 for milliseconds)")
    resample: Optional[float] = Field(
        None,
        gt=0,
        description="interpolate every recording linearly onto a uniform grid with this step in seconds "
        "(for non-uniformly sampled files; needs time_column; sets the sampling time)",
    )

    @model_validator(mode="after")
    def _time_unit_of_a_named_unit(self) -> Self:
        """A time column named in milli- or microseconds (t_ms, time [us]) read as seconds makes every time in
        seconds (resample, the sampling time, a saturating drift) wrong by 1000: say so unless time_unit is set."""
        col = self.time_column
        unit = _named_time_unit(col) if isinstance(col, str) and "time_unit" not in self.model_fields_set else None
        if unit is not None:
            name, factor = unit
            raise ValueError(
                f"the time column '{col}' reads as {name}, but time_unit (seconds per unit) is 1: add time_unit: "
                f"{factor} (or time_unit: 1 if it holds seconds)"
            )
        return self


def _named_time_unit(column: str) -> tuple[str, str] | None:
    """('milliseconds', '0.001') for a column name such as t_ms, time(ms), time [ms]; None for others."""
    for pattern, unit in (
        (r"ms|msec|millis|milliseconds?", ("milliseconds", "0.001")),
        (r"us|µs|usec|micros|microseconds?", ("microseconds", "1e-6")),
    ):
        if re.search(rf"(^|[^a-z])({pattern})([^a-z]|$)", column.lower()):
            return unit
    return None


class SeparateSource(StrictModel):
    """A separate recording for one split; unset keys are taken from the main source."""

    path: Optional[PathSpec] = None
    input: Optional[list[Union[str, int]]] = None
    output: Optional[list[Union[str, int]]] = None
    header: Optional[bool] = None
    columns: Optional[list[str]] = None
    delimiter: Optional[Delimiter] = None
    segments: Optional[list[tuple[int, int]]] = None
    sampling_time: Optional[float] = Field(None, gt=0)
    time_column: Optional[Union[str, int]] = None
    time_unit: Optional[float] = Field(None, gt=0)
    resample: Optional[float] = Field(None, gt=0)
    generator: Optional[str] = None
    params: Optional[dict[str, Any]] = None
    n: Optional[int] = Field(None, gt=0)
    seed: Optional[int] = Field(None, ge=0)


TEST_NAME = r"^[A-Za-z][A-Za-z0-9_-]*$"


class TestSource(SeparateSource):
    """One of several named test sets; unset keys are taken from the main source. Scored as
    ``test:<name>`` (metrics, ``--json``, the model file)."""

    name: str = Field(
        pattern=TEST_NAME,
        description="name of this test set (letters, digits, '_' and '-'); its metrics key is test:<name>",
    )
    init_window: Optional[int] = Field(
        None, ge=0, description="this test set's initialization window (default: data.init_window)"
    )
    score: Optional[Literal["window", "all"]] = Field(
        None, description="this test set's scoring (default: evaluation.score)"
    )


def _unique_test_names(v: Any) -> Any:
    if isinstance(v, list):
        if not v:
            raise ValueError("the list of test sets is empty; name at least one, or leave test out")
        names = [t if isinstance(t, str) else t.name for t in v]
        dup = next((n for n in names if names.count(n) > 1), None)
        if dup is not None:
            raise ValueError(f"two test sets are named '{dup}'; give each a different name")
    return v


def _test_tag(value: Any) -> str:
    return "named" if isinstance(value, list) else "single"


#: data.test: one separate test recording, or a list of named test sets
TestSpec = Annotated[
    Union[Annotated[SeparateSource, Tag("single")], Annotated[list[TestSource], Tag("named")]],
    Discriminator(_test_tag),
]
_UNION_TAGS = ("single", "named", "files", "list")


class InitWindowSplits(StrictModel):
    """Initialization windows per split (test applies to every test set)."""

    validation: Optional[int] = Field(None, ge=0, description="samples at the start of each validation recording")
    test: Optional[int] = Field(None, ge=0, description="samples at the start of each test recording")


class SaturatingTime(StrictModel):
    """1 - exp(-t / tau): a drift that levels off (thesis 6.2.2, charge leakage of a piezo sensor)."""

    saturating: float = Field(gt=0, description="time constant tau in seconds")


#: a function of the time t (seconds) since a recording's first sample: ``linear`` (t) or {saturating: tau}
TimeFunction = Union[Literal["linear"], SaturatingTime]


class TimeChannel(StrictModel):
    """An input channel that is a function of the time since the recording's start (a drift term)."""

    time: TimeFunction = Field(description="linear (t in seconds) or {saturating: tau} (1 - exp(-t / tau))")
    name: Optional[str] = Field(None, description="channel name (default time_linear / time_saturating_<tau>)")


class DirectionChannel(StrictModel):
    """+1 while an input moves up, -1 while it moves down (held through standstill)."""

    direction: str = Field(description="the input column whose direction of motion is wanted")
    deadband: float = Field(
        0.0,
        ge=0,
        description="a reversal counts once the input has moved back by more than this "
        "(input units; ignores noise at the turning points)",
    )
    name: Optional[str] = Field(None, description="channel name (default <input>_direction)")


class ReversalChannel(StrictModel):
    """The change of an input since its last reversal (the displacement that shapes hysteresis loops)."""

    since_reversal: str = Field(description="the input column")
    deadband: float = Field(0.0, ge=0, description="as for direction")
    name: Optional[str] = Field(None, description="channel name (default <input>_since_reversal)")


class SignChannel(StrictModel):
    """+1 where an input is above +deadband, -1 below -deadband, 0 between (a velocity's sign: Coulomb friction)."""

    sign: str = Field(description="the input column")
    deadband: float = Field(0.0, ge=0, description="|input| at most this counts as 0 (input units)")
    name: Optional[str] = Field(None, description="channel name (default <input>_sign)")


#: the kinds of a derived input, as the key of its spec item
DERIVED_KINDS = ("time", "direction", "since_reversal", "sign")


def _derived_tag(value: Any) -> str | None:
    keys = set(value) if isinstance(value, dict) else {k for k in DERIVED_KINDS if getattr(value, k, None) is not None}
    for key in DERIVED_KINDS:
        if key in keys:
            return key
    return None


DerivedInput = Annotated[
    Union[
        Annotated[TimeChannel, Tag("time")],
        Annotated[DirectionChannel, Tag("direction")],
        Annotated[ReversalChannel, Tag("since_reversal")],
        Annotated[SignChannel, Tag("sign")],
    ],
    Discriminator(
        _derived_tag,
        custom_error_type="derived_input",
        custom_error_message="write {time: linear}, {time: {saturating: TAU}}, "
        "{direction: INPUT}, {since_reversal: INPUT} or {sign: INPUT}",
    ),
]


class DataCommon(StrictModel):
    split: Optional[SplitSpec] = Field(
        None,
        description="default {train: 0.6, validation: 0.2, test: 0.2}; without test when a separate test source is given",
    )
    validation: Optional[SeparateSource] = Field(None, description="a separate validation recording")
    test: Optional[TestSpec] = Field(
        None,
        description="a separate test recording, or a list of named test sets [{name: ..., path/segments/...}] "
        "each scored on its own (metrics keys test:<name>)",
    )
    init_window: Optional[Union[Annotated[int, Field(ge=0)], InitWindowSplits]] = Field(
        None,
        description="state-initialization window of the benchmark protocols: the first k samples of every "
        "validation and test recording may initialize the model (measured past outputs, tune-in, washout) and are "
        "not scored; a validation or test range inside a longer recording becomes a run of its own. A number applies "
        "to validation and test, {validation: k, test: k} per split. Training is never trimmed by it",
    )
    transient: int = Field(
        0, ge=0, description="samples excluded from fitting and scoring at the start of each split segment"
    )
    transient_at: Literal["segment", "recording"] = Field(
        "segment",
        description="segment: the transient is cut at the start of every split segment; recording: only "
        "where a recording starts (and the state restarts), so a segment continuing a run keeps all its samples",
    )
    delay_lines: list[Annotated[int, Field(gt=0)]] = Field(
        default_factory=list,
        description="extra copies of every input delayed by these numbers of samples (external memory, thesis 6.3.2)",
    )
    derived_inputs: list[DerivedInput] = Field(
        default_factory=list,
        description="extra model inputs computed from each recording: functions of the time "
        "since its start ({time: linear}, {time: {saturating: TAU}}: drift terms), the direction of motion of an input "
        "({direction: u}) and its change since the last reversal ({since_reversal: u}); appended after the delay lines",
    )
    detrend: list[TimeFunction] = Field(
        default_factory=list,
        description="remove a trend from the output before fitting: least squares of the training "
        "outputs on these functions of time (e.g. [linear, {saturating: 30}]); predictions get the trend back",
    )
    delay_form: Literal["copy", "difference"] = Field(
        "copy",
        description="copy: the delay lines hold u(t - d) (named u@d); difference: u(t) - u(t - d), scaled to "
        "unit std on the training split (named u~d; invariant to the level of u, e.g. where a position lies)",
    )
    noise: Optional[NoiseSpec] = None
    spikes: Literal["replace", "keep"] = Field(
        "replace",
        description="isolated spikes in the training and validation outputs (a sample far from both its neighbours, "
        "which agree with each other: a sensor glitch): replace each by the mean of its neighbours (noted), or keep "
        "them as measured; test outputs are never changed",
    )
    scaling: Literal["standard", "none"] = Field(
        "standard", description="standard: zero mean, unit std per channel from the training split"
    )

    @field_validator("test")
    @classmethod
    def _test_names(cls, v: Any) -> Any:
        return _unique_test_names(v)


class FileData(DataCommon, FileSourceFields):
    pass


class ReportUnit(StrictModel):
    """A unit for reporting an output: reported value = scale x value in the data's units."""

    scale: float = Field(gt=0, description="factor from the data's units (1000: V -> mV, m -> mm)")
    name: str = Field(min_length=1, description="the unit's name, e.g. mm")


class EvaluationSpec(StrictModel):
    """Metrics on free-running predictions started at each recording's first sample (thesis 6.2.2)."""

    metrics: list[MetricName] = Field(
        default_factory=lambda: list(DEFAULT_METRICS),
        description="nmse (%), max (in output stds), rmse (output units), fit (%: 100 (1 - rmse / std))",
    )
    one_step: bool = Field(True, description="also report the one-step NMSE where the family distinguishes it")
    units: dict[str, ReportUnit] = Field(
        default_factory=dict,
        description="report the RMSE of these outputs in other units, e.g. {qm: {scale: 1000, name: mm}} "
        "(benchmark sources set their protocol's units)",
    )
    score: Literal["window", "all"] = Field(
        "window",
        description="window: validation and test are scored after their transient, initialization window and the "
        "model's measured start; all: every validation and test sample is scored, so the model may use no measured "
        "output (the Cascaded Tanks and Bouc-Wen PDF protocols)",
    )

    @field_validator("metrics")
    @classmethod
    def _nonempty(cls, v: list[str]) -> list[str]:
        if not v:
            raise ValueError("list at least one metric: nmse, max, rmse, fit")
        return list(dict.fromkeys(v))


def _data_tag(value: Any) -> str | None:
    if isinstance(value, dict):
        if "generator" in value:
            return f"generator:{value['generator']}"
        return "benchmark" if "benchmark" in value else "file"
    return getattr(value, "source_tag", None)


def _benchmark_data_model(benches: dict[str, Any]) -> type[BaseModel]:
    names = tuple(sorted(benches))
    tag: Any = Literal[names]  # a type built at run time (typed Any: type checkers cannot follow it)
    model = create_model(
        "BenchmarkData",
        __base__=DataCommon,
        __doc__="a standard benchmark read from local files, with its protocol's splits, windows and units",
        benchmark=(tag, Field(description="the benchmark (see `dynmodel plugins`)")),
        root=(str, Field(description="folder holding the benchmark's files (relative to the spec file)")),
        test=(
            Optional[list[Annotated[str, Field(pattern=TEST_NAME)]]],
            Field(None, description="the benchmark's test sets to score (default: all of them)"),
        ),
        validation=(
            None,
            Field(None, description="not available: carve the validation split from the training data with split"),
        ),
    )
    model.source_tag = property(lambda self: "benchmark")  # type: ignore[attr-defined]
    return model


def _generator_data_model(name: str, gen: Any) -> type[BaseModel]:
    params_model = gen.Params
    tag: Any = Literal[name]  # a type built at run time (typed Any: type checkers cannot follow it)
    model = create_model(
        f"GeneratorData_{name.replace('-', '_')}",
        __base__=DataCommon,
        __doc__=getattr(gen, "description", None) or f"data generated by '{name}'",
        generator=(tag, Field(description=getattr(gen, "description", ""))),
        params=(params_model, Field(default_factory=params_model)),
        n=(int, Field(10000, gt=0, description="number of samples")),
        seed=(int, Field(0, ge=0, description="seed of this realization")),
        input=(Optional[list[str]], Field(None, description=f"generated inputs: {list(gen.input_names)}")),
        output=(Optional[list[str]], Field(None, description=f"generated outputs: {list(gen.output_names)}")),
        sampling_time=(Optional[float], Field(None, gt=0, description="taken from the generator when omitted")),
    )
    model.source_tag = property(lambda self: f"generator:{self.generator}")  # type: ignore[attr-defined]
    return model


def _model_spec_model(name: str, fam: Any) -> type[ModelChoice]:
    params_model = fam.Params
    tag: Any = Literal[name]  # a type built at run time (typed Any: type checkers cannot follow it)
    return create_model(
        f"ModelSpec_{name.replace('-', '_')}",
        __base__=ModelChoice,
        __doc__=getattr(fam, "description", None),
        family=(tag, ...),
        params=(params_model, Field(default_factory=params_model)),
    )


class ModelChoice(StrictModel):
    """The ``model`` section: a family and its validated params. Each installed family (and ``auto``)
    gets its own subclass whose ``family`` is that family's name and whose ``params`` are its own
    pydantic model (see :func:`spec_model`)."""

    family: str
    params: Any = None


def _auto_model() -> ModelChoice:
    from .search.params import auto_model_spec

    return auto_model_spec()(family="auto")


class Spec(StrictModel):
    """A dynmodel experiment: data, model family, cost, evaluation."""

    name: str = Field("model", description="experiment name, used for the default output file")
    data: DataCommon
    model: ModelChoice = Field(
        default_factory=_auto_model,
        description="the model family and its params; left out: family auto (search every family)",
    )
    cost: Optional[Literal["mse1", "mse_inf"]] = Field(
        None,
        description="mse1: one-step error; mse_inf: free-running error; default: the family's own "
        "(narx: mse_inf, the networks: mse1)",
    )
    evaluation: EvaluationSpec = Field(default_factory=EvaluationSpec)
    seed: int = Field(0, ge=0, description="seed of every random choice in fitting (networks, noise)")
    output: Optional[str] = Field(None, description="model file (HDF5); default <name>.h5 next to the spec")

    _base_dir: Path = PrivateAttr(default_factory=Path.cwd)
    _source: str = PrivateAttr(default="<spec>")

    # ``Spec`` is the type every spec is an instance of; its ``data`` and ``model`` are typed by their
    # common bases. The class that validates (data sources and families of the installed plugins as
    # discriminated unions) is the subclass :func:`spec_model` builds: validating through ``Spec``
    # itself goes there, so an unknown family or data key is never accepted by the generic types.

    def __init__(self, **data: Any) -> None:
        if type(self) is Spec:
            raise TypeError(
                "dynmodel.spec.Spec is the common base of specs: build one with Spec.model_validate(mapping), "
                "dynmodel.validate_spec(mapping) or dynmodel.load_spec(path)"
            )
        super().__init__(**data)

    @classmethod
    def model_validate(cls, obj: Any, *args: Any, **kwargs: Any) -> Self:
        """Validate ``obj`` against the installed plugins (on ``Spec`` itself: through :func:`spec_model`)."""
        if cls is Spec:
            return cast(Self, spec_model().model_validate(obj, *args, **kwargs))
        return super().model_validate(obj, *args, **kwargs)

    @classmethod
    def model_json_schema(cls, *args: Any, **kwargs: Any) -> dict[str, Any]:
        """The JSON Schema (on ``Spec`` itself: with every installed family's and generator's parameters)."""
        if cls is Spec:
            return spec_model().model_json_schema(*args, **kwargs)
        return super().model_json_schema(*args, **kwargs)

    @model_validator(mode="after")
    def _family_cost(self) -> Spec:
        if self.cost is None and self.model.family != "auto":  # auto: each candidate its family's own
            self.cost = getattr(registry.families().get(self.model.family), "default_cost", "mse1")
        return self

    @property
    def base_dir(self) -> Path:
        return self._base_dir

    @property
    def source(self) -> str:
        return self._source

    def resolve_path(self, p: str) -> Path:
        path = Path(p).expanduser()
        return path if path.is_absolute() else (self._base_dir / path)

    def output_path(self) -> Path:
        """The spec's ``output``, else ``<name>.h5`` next to the spec, the name made safe for a file name (a
        name with slashes or '..' must not write elsewhere)."""
        from .paths import safe_name

        return self.resolve_path(self.output or f"{safe_name(self.name)}.h5")

    def resolved(self) -> dict[str, Any]:
        """The full spec with defaults filled in and data paths made absolute."""
        d = self.model_dump(mode="json")
        test = d["data"].get("test")
        tests = [t for t in test if isinstance(t, dict)] if isinstance(test, list) else [test or {}]
        for section in [d["data"], *tests, d["data"].get("validation") or {}]:
            if section.get("path") is not None:
                section["path"] = _resolve_paths(section["path"], self.resolve_path)
        if isinstance(d["data"].get("root"), str):
            d["data"]["root"] = str(self.resolve_path(d["data"]["root"]))
        d["output"] = str(self.output_path())
        return d


@cache
def spec_model() -> type[Spec]:
    """The subclass of :class:`Spec` that validates specs for the installed plugins: ``data`` a union
    of the file, generator and benchmark sources, ``model`` a union keyed on ``family``."""
    fams = registry.families()
    gens = registry.sources()
    FileData.source_tag = property(lambda self: "file")  # type: ignore[attr-defined]
    data_variants = [Annotated[FileData, Tag("file")]]
    data_variants += [Annotated[_generator_data_model(n, g), Tag(f"generator:{n}")] for n, g in gens.items()]
    if registry.benchmarks():
        data_variants.append(Annotated[_benchmark_data_model(registry.benchmarks()), Tag("benchmark")])
    data_spec: Any = Annotated[Union[tuple(data_variants)], Discriminator(_data_tag)]
    model_variants = [_model_spec_model(n, f) for n, f in fams.items()]
    if not model_variants:
        raise SpecError("no model family is installed", fix="pip install -e . in the dynmodel folder")
    from .search.params import auto_model_spec

    auto_spec = auto_model_spec()  # family: auto, the model search (docs/auto.md)
    model_spec: Any = Annotated[Union[tuple([*model_variants, auto_spec])], Field(discriminator="family")]
    return create_model(
        "Spec",
        __base__=Spec,
        __doc__=Spec.__doc__,
        __module__=__name__,
        data=(data_spec, ...),
        model=(
            model_spec,
            Field(
                default_factory=lambda: auto_spec(family="auto"),
                description="the model family and its params; left out: family auto (search every family)",
            ),
        ),
    )


def _resolve_paths(p: Any, resolve) -> Any:
    """Every file name of a ``path`` value (a name, {input, output}, or a list of either) made absolute; the
    marker of recordings given in Python (:data:`IN_MEMORY`) kept as it is."""
    if isinstance(p, str):
        return p if p == IN_MEMORY else str(resolve(p))
    if isinstance(p, dict):
        return {k: str(resolve(v)) for k, v in p.items()}
    return [_resolve_paths(x, resolve) for x in p]


# ---------------------------------------------------------------- error formatting


def _unwrap(tp: Any) -> Any:
    while get_origin(tp) is Annotated:
        tp = get_args(tp)[0]
    return tp


def _leaves(node: Any) -> list[Any]:
    """The member types of a (nested, Optional, Annotated) union."""
    node = _unwrap(node)
    if get_origin(node) is Union:
        return [leaf for a in get_args(node) if a is not type(None) for leaf in _leaves(a)]
    return [node]


def _allowed_keys(loc: tuple) -> list[str] | None:
    """Field names of the section that ``loc`` (ending with the bad key) points into."""
    node: Any = spec_model()
    for i, part in enumerate(loc[:-1]):
        leaves = _leaves(node)
        lists = [a for a in leaves if get_origin(a) is list]
        if isinstance(part, int) or part == "named":  # into a list (of named test sets)
            if not lists:
                return None
            node = lists[0] if part == "named" else get_args(lists[0])[0]
            continue
        named = (
            {"single": "SeparateSource", "benchmark": "BenchmarkData"}.get(part, part) if i or part != "data" else ""
        )
        member = next((a for a in leaves if getattr(a, "__name__", None) == named), None)
        if member is not None and (part != "benchmark" or i == 1):  # the tag of a union member
            node = member
            continue
        node = _unwrap(node)
        if isinstance(node, type) and issubclass(node, BaseModel):
            if part not in node.model_fields:
                return None
            node = node.model_fields[part].annotation
            continue
        tagged = {
            m.tag: _unwrap(a)
            for a in get_args(node)
            if get_origin(a) is Annotated
            for m in getattr(a, "__metadata__", ())
            if isinstance(m, Tag)
        }
        if part in tagged:  # a union member named by its tag (a derived input's kind)
            node = tagged[part]
            continue
        args = [_unwrap(a) for a in get_args(node) if a is not type(None)]
        chosen = None
        for a in args:
            if isinstance(a, type) and issubclass(a, BaseModel):
                fam = a.model_fields.get("family") or a.model_fields.get("generator")
                tag = get_args(fam.annotation)[0] if fam is not None else None
                if part in (tag, f"generator:{tag}") or (part == "file" and a.__name__ == "FileData"):
                    chosen = a
                    break
        if chosen is None:
            models = [a for a in args if isinstance(a, type) and issubclass(a, BaseModel)]
            if len(models) == 1 and part in models[0].model_fields:
                node = models[0].model_fields[part].annotation
                continue
            if not models:
                return None
            chosen = models[0]
            if part not in ("file",) and part in chosen.model_fields:
                node = chosen.model_fields[part].annotation
                continue
        node = chosen
    node = _unwrap(node)
    if isinstance(node, type) and issubclass(node, BaseModel):
        return list(node.model_fields)
    for a in get_args(node):
        a = _unwrap(a)
        if isinstance(a, type) and issubclass(a, BaseModel):
            return list(a.model_fields)
    return None


def _is_member_tag(p: Any) -> bool:
    """A union member's name in a pydantic error location (a model class, a tag of data.test), not a key."""
    if not isinstance(p, str):
        return False
    models = {c.__name__ for c in [*StrictModel.__subclasses__(), *ModelChoice.__subclasses__()]}
    models |= {"TestSource", "FileData"}
    return p in models or p in _UNION_TAGS or p in ("int", "float", "str") or p.startswith(("list[", "constrained-"))


def _dotted(loc: tuple) -> str:
    parts: list[str] = []
    bench_tag = False
    for p in loc:
        if isinstance(p, str) and (p == "file" or p.startswith("generator:") or p.startswith("function-")):
            continue
        if p == "benchmark" and parts == ["data"] and not bench_tag:  # the tag of the benchmark source
            bench_tag = True
            continue
        if _is_member_tag(p):
            continue
        if p in DERIVED_KINDS and len(parts) >= 2 and parts[-2] == "derived_inputs" and parts[-1].startswith("["):
            continue  # the union tag of a derived input (its kind), not a key the user wrote
        if isinstance(p, str) and parts == ["model"] and (p in registry.families() or p == "auto"):
            continue
        parts.append(f"[{p}]" if isinstance(p, int) else str(p))
    return ".".join(parts).replace(".[", "[")


def validation_summary(exc: Exception) -> str:
    """The first problem of a pydantic ValidationError on one line, as ``where: what``
    (unknown keys first); other exceptions give their first line."""
    errors = exc.errors() if isinstance(exc, ValidationError) else []
    if not errors:
        return str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    e = next((x for x in errors if x["type"] == "extra_forbidden"), errors[0])
    path = tuple(p for p in e["loc"] if not (isinstance(p, str) and p.startswith("function-")))
    if e["type"] == NUMBER_NOT_BOOLEAN:
        path += (e["ctx"]["key"],)
    if e["type"] == "extra_forbidden" and path:
        path, msg = path[:-1], f"unknown key '{path[-1]}'"
    else:
        msg = e["msg"]
    loc = _dotted(path)
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    return f"{loc}: {msg}" if loc else msg


def format_validation_error(err: ValidationError, source: str) -> SpecError:
    """Turn the first pydantic error into one line: where, what, how to fix (unknown keys first,
    since a misspelt key usually also causes the 'missing' error of the key it meant)."""
    errors = err.errors()
    e = next((x for x in errors if x["type"] == "extra_forbidden"), errors[0])
    loc = tuple(e["loc"])
    kind = e["type"]
    if kind == NUMBER_NOT_BOOLEAN:  # raised for the whole section: the key is in its context
        loc += (e["ctx"]["key"],)
        e = {**e, "input": e["ctx"]["value"]}
    where = f"{source}: {_dotted(loc)}" if loc else source
    if kind == "extra_forbidden":
        key = str(loc[-1])
        allowed = _allowed_keys(loc) or []
        close = difflib.get_close_matches(key, allowed, n=1)
        fix = f"did you mean '{close[0]}'?" if close else "remove it."
        if allowed:
            fix += f" Allowed keys here: {', '.join(allowed)}"
        return SpecError(f"unknown key '{key}'", f"{source}: {_dotted(loc[:-1]) or 'top level'}", fix)
    if kind == "missing":
        return SpecError("required key is missing", where, f"add '{_dotted(loc[-1:])}'")
    value = e.get("input")
    shown = json.dumps(value, default=str) if not isinstance(value, dict) else "a mapping"
    if len(shown) > 60:
        shown = shown[:57] + "..."
    msg = e["msg"]
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    return SpecError(f"{msg} (got {shown})", where, "correct this value (see `dynmodel schema`)")


# ---------------------------------------------------------------- loading


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate keys instead of silently keeping the last one."""


def _construct_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False):
    """A mapping whose own keys are unique (a merged ``<<: *anchor`` may be overridden, as YAML allows) and
    hashable."""
    seen: dict[Any, Any] = {}
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node, deep=deep)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(
                None, None, f"a {'list' if isinstance(key, list) else 'mapping'} is used as a key", key_node.start_mark
            ) from None
        if key in seen:
            mark = key_node.start_mark
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key '{key}' (first at line {seen[key] + 1})", mark
            )
        seen[key] = key_node.start_mark.line
    loader.flatten_mapping(node)  # merge keys (<<: *defaults), as the safe loader does
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
# YAML 1.1 (PyYAML) reads 1e-6 and 2E3 as text, 1.0e-6 as a number; YAML 1.2 and every user read both as
# numbers (a grid value 1e-6 must be the same configuration, and seed, as 1.0e-6)
_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def read_yaml(text: str, source: str) -> Any:
    """Safe YAML with duplicate keys refused; a malformed document raises SpecError naming the line."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - safe loader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{source}:{mark.line + 1}:{mark.column + 1}" if mark else source
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise SpecError(
            f"malformed YAML: {problem}", where, "check indentation, colons and brackets on that line"
        ) from None


def parse_yaml(text: str, source: str) -> dict[str, Any]:
    raw = read_yaml(text, source)
    if raw is None:
        raise SpecError("the spec is empty", source, "write at least data: and model: sections")
    if not isinstance(raw, dict):
        raise SpecError(
            f"the spec must be a mapping of keys, not a {type(raw).__name__}",
            source,
            "start with 'name:', 'data:', 'model:' lines",
        )
    for key in raw:
        if not isinstance(key, str):
            raise SpecError(
                f"the key {key!r} is not a name (YAML reads yes/no/on/off as booleans, null as nothing and digits as "
                "numbers)",
                source,
                "write a spec key such as name:, data:, model: (quote a key that must stay text)",
            )
    return raw


def _precheck_plugins(raw: dict[str, Any], source: str) -> None:
    """Name unknown families and generators with the installed alternatives."""
    model = raw.get("model")
    if isinstance(model, dict) and "family" in model:
        known = sorted(registry.families())
        if model["family"] not in known and model["family"] != "auto":
            what, fix = registry.unknown_name_message("family", str(model["family"]), known)
            raise SpecError(what, f"{source}: model.family", fix)
    data = raw.get("data")
    test = data.get("test") if isinstance(data, dict) else None
    tests = [(t, f"data.test[{i}]") for i, t in enumerate(test)] if isinstance(test, list) else [(test, "data.test")]
    for section, where in [
        (data, "data"),
        *tests,
        ((data or {}).get("validation") if isinstance(data, dict) else None, "data.validation"),
    ]:
        if isinstance(section, dict) and section.get("generator") is not None:
            known = sorted(registry.sources())
            if section["generator"] not in known:
                what, fix = registry.unknown_name_message("generator", str(section["generator"]), known)
                raise SpecError(what, f"{source}: {where}.generator", fix)
    if isinstance(data, dict) and len({"path", "generator", "benchmark"} & set(data)) > 1:
        given = " and ".join(f"'{k}'" for k in ("path", "generator", "benchmark") if k in data)
        raise SpecError(
            f"give one of 'path' (measured data), 'generator' or 'benchmark', not {given}",
            f"{source}: data",
            "remove all but one of them",
        )
    if isinstance(data, dict) and data.get("benchmark") is not None:
        _precheck_benchmark(data, source)


def _precheck_benchmark(data: dict[str, Any], source: str) -> None:
    """Name an unknown benchmark or test set with the installed alternatives."""
    known = registry.benchmarks()
    name = str(data["benchmark"])
    if name not in known:
        what, fix = registry.unknown_name_message("benchmark", name, sorted(known))
        raise SpecError(what, f"{source}: data.benchmark", fix)
    if data.get("validation") is not None:
        raise SpecError(
            "a benchmark has no separate validation recording",
            f"{source}: data.validation",
            "carve it from the training data, e.g. split: {train: 0.8, validation: 0.2}",
        )
    offered = list(known[name].test_sets)
    for i, t in enumerate(data.get("test") or []):
        if isinstance(t, str) and t not in offered:
            shown = ", ".join(offered) if offered else "none by name (it has a single test set: leave test out)"
            raise SpecError(
                f"benchmark '{name}' has no test set '{t}'", f"{source}: data.test[{i}]", f"its test sets: {shown}"
            )


def validate_spec(raw: dict[str, Any], source: str = "<spec>", base_dir: Path | None = None) -> Spec:
    """Validate a spec mapping; raises SpecError with one line on the first problem."""
    _precheck_plugins(raw, source)
    if isinstance(raw.get("data"), dict) and not ({"path", "generator", "benchmark"} & set(raw["data"])):
        raise SpecError(
            "data needs 'path' (a measured-data file), 'generator' (a built-in system) or 'benchmark'",
            f"{source}: data",
            "add 'path: file.csv' with input/output columns, 'generator: narx-system' or 'benchmark: silverbox'",
        )
    try:
        spec = spec_model().model_validate(raw)
    except ValidationError as err:
        raise format_validation_error(err, source) from None
    spec._base_dir = (base_dir or Path.cwd()).resolve()
    spec._source = source
    return spec


def read_spec_text(p: Path) -> str:
    """The text of a spec file: UTF-8 (with or without BOM), UTF-16 or Latin-1; one-line errors."""
    from .errors import DataError
    from .textfiles import read_text_file

    try:
        return read_text_file(p, "spec")
    except DataError as exc:
        from .paths import is_previous_output

        if is_previous_output(p, "model"):
            raise SpecError(
                "is a dynmodel model file, not a spec",
                str(p),
                "give the YAML spec the model was fitted from (`dynmodel inspect MODEL --spec` prints it); "
                "a model file goes to dynmodel predict, inspect or reliability-check",
            ) from None
        if exc.what.startswith("is not a text file"):  # a spec is YAML text, not data
            raise SpecError(exc.what, exc.where, "give the YAML spec file (a text file)") from None
        raise SpecError(exc.what, exc.where, exc.fix) from None


def load_spec(path: str | Path) -> Spec:
    """Load and validate a YAML spec file. Relative paths inside resolve against its folder."""
    p = Path(path)
    if not p.exists():
        raise SpecError("spec file not found", str(p), "check the path")
    if p.is_dir():
        raise SpecError("is a folder, not a spec file", str(p), "pass the YAML file")
    raw = parse_yaml(read_spec_text(p), str(p))
    raw.setdefault("name", p.stem)
    return validate_spec(raw, str(p), p.parent)


def spec_json_schema() -> dict[str, Any]:
    return spec_model().model_json_schema()
