"""Feed-forward control with a saved model (thesis 6.4): the tracking task of fig. 6.19 / 6.20.

A plant under P-control follows a reference; from the switch time on, a saved model driven by the
reference (through its own delay lines) adds its force as feed-forward. The tracking error
e = P - P_r is scored before and after the switch (eq. 6.32 - 6.37):

    NMSE_P  = 100 % mean(e^2 over [skip, switch))        / var(P_r)
    NMSE_ff = 100 % mean(e^2 over [switch + skip, end))  / var(P_r)
    MAX_P   = max |e| over [skip, switch)       / std(P_r)
    MAX_ff  = max |e| over [switch + skip, end) / std(P_r)
    alpha   = 100 % (NMSE_P - NMSE_ff) / NMSE_P,   beta = 100 % (MAX_P - MAX_ff) / MAX_P

Eq. 6.32 / 6.33 as printed divide the sum over a 30000-sample window by N = 100000, and eq. 6.35 /
6.36 divide by sigma_F; here both are plain means resp. std(P_r) (the thesis's MAX values are only
consistent with the latter). alpha and beta do not depend on either choice.

Every noise realization is simulated with P-control up to the switch once; from the state there it
continues twice with the same noise: with the model's feed-forward and with the perfect model's
(the plant's own law driven by the reference, fig. 6.23), whose alpha / beta bound what any model
can reach. The model's feed-forward depends only on the reference, so it is computed once (by a
free run over the whole reference, as a model block running in the loop from t = 0 would) and
enters the compiled closed-loop simulation as a sequence. A plant comes from a data generator that
offers ``control_plant(params)`` (see :class:`Plant`); the core never names one.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from . import registry
from .errors import DataError, FreeRunDiverged, SpecError
from .family import Progress, no_progress

CRITERIA = ("nmse_p", "nmse_ff", "max_p", "max_ff", "alpha", "beta")
LABELS = {
    "nmse_p": "NMSE_P %",
    "nmse_ff": "NMSE_ff %",
    "max_p": "MAX_P",
    "max_ff": "MAX_ff",
    "alpha": "alpha %",
    "beta": "beta %",
}


class TrackingRun(Protocol):
    position: np.ndarray  # [0, switch)
    force: np.ndarray  # control force over [0, switch)

    def resume(self, feedforward: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(position, force) over [switch, n) with ``feedforward`` (n,) active from the switch."""


class TrackingTask(Protocol):
    reference: np.ndarray  # (n,)

    def perfect_feedforward(self) -> np.ndarray: ...

    def start(self, switch: int, rng: np.random.Generator, hold: int = 1) -> TrackingRun: ...


class Plant(Protocol):
    """What a generator's ``control_plant(params)`` returns."""

    sampling_time: float
    reference_inputs: tuple[str, ...]  # model inputs that receive the reference position
    force_output: str  # the model output used as feed-forward force
    description: str

    def tracking_task(self, n: int, rng: np.random.Generator) -> TrackingTask: ...


@dataclass
class Settings:
    duration: float = 100.0
    switch: float = 50.0
    skip: float = 20.0
    realizations: int = 20
    seed: int = 0
    hold: str = "linear"  # linear | zero
    workers: int = 0


@dataclass
class Report:
    plant: dict[str, Any]
    settings: dict[str, Any]
    model: list[dict[str, float]]
    perfect: list[dict[str, float]]
    notes: list[str] = field(default_factory=list)
    series: dict[str, np.ndarray] = field(default_factory=dict)  # first realization, for the plot

    @staticmethod
    def _stats(rows: list[dict[str, float]]) -> dict[str, dict[str, float]]:
        return {
            c: {"mean": float(np.mean([r[c] for r in rows])), "std": float(np.std([r[c] for r in rows]))}
            for c in CRITERIA
        }

    def summary(self) -> dict[str, dict[str, dict[str, float]]]:
        return {"model": self._stats(self.model), "perfect": self._stats(self.perfect)}

    def to_json(self) -> dict[str, Any]:
        return {
            "plant": self.plant,
            "settings": self.settings,
            **self.summary(),
            "realizations": [{"model": m, "perfect": p} for m, p in zip(self.model, self.perfect)],
            "notes": self.notes,
        }


def criteria(reference: np.ndarray, error: np.ndarray, switch: int, skip: int) -> dict[str, float]:
    """Eq. 6.32 - 6.37 for one run (see the module docstring for the normalisation)."""
    var = float(np.var(reference))
    std = float(np.sqrt(var))
    before, after = error[skip:switch], error[switch + skip :]
    if before.size == 0 or after.size == 0:
        raise ValueError("empty scoring window: need skip < switch and switch + skip < length")
    nmse_p = 100.0 * float(np.mean(before**2)) / var
    nmse_ff = 100.0 * float(np.mean(after**2)) / var
    max_p = float(np.max(np.abs(before))) / std
    max_ff = float(np.max(np.abs(after))) / std
    return {
        "nmse_p": nmse_p,
        "nmse_ff": nmse_ff,
        "max_p": max_p,
        "max_ff": max_ff,
        "alpha": 100.0 * (nmse_p - nmse_ff) / nmse_p,
        "beta": 100.0 * (max_p - max_ff) / max_p,
    }


def _set_dotted(target: dict[str, Any], key: str, value: Any) -> None:
    parts = key.split(".")
    node = target
    for p in parts[:-1]:
        if not isinstance(node.get(p), dict):
            node[p] = {}
        node = node[p]
    node[parts[-1]] = value


def read_plant(path: Path) -> dict[str, Any]:
    """The plant description of a YAML file (``generator:`` and ``params:``, or a whole dynmodel spec);
    one-line SpecErrors for a missing file, malformed YAML or a file that is not a mapping."""
    from .spec import read_spec_text, read_yaml

    if not path.is_file():
        raise SpecError("plant description not found", str(path), "check the path")
    described = read_yaml(read_spec_text(path), str(path))
    if not isinstance(described, dict):
        raise SpecError("the plant description must be a mapping", str(path), "write generator: NAME and params: {...}")
    return described


def plant_source(model, plant: dict[str, Any] | None) -> tuple[str, dict[str, Any]]:
    """(generator name, params) of the plant: the given description, else the model's training source."""
    if plant is None:
        data = (model.spec or {}).get("data") or {}
        if not data.get("generator"):
            raise SpecError(
                "the model was fitted on recorded data, so there is no plant to simulate",
                "--plant",
                "pass --plant FILE.yaml with 'generator:' and 'params:' of a plant generator",
            )
        plant = {"generator": data["generator"], "params": data.get("params") or {}}
    elif "data" in plant and isinstance(plant["data"], dict):  # a whole dynmodel spec
        plant = {"generator": plant["data"].get("generator"), "params": plant["data"].get("params") or {}}
    name = plant.get("generator")
    if not name:
        raise SpecError(
            "the plant description has no 'generator'", "--plant", "write generator: NAME and params: {...}"
        )
    unknown = set(plant) - {"generator", "params"}
    if unknown:
        raise SpecError(
            f"unknown key '{sorted(unknown)[0]}' in the plant description",
            "--plant",
            "use generator: and params: (or a dynmodel spec with a data section)",
        )
    return str(name), dict(plant.get("params") or {})


def make_plant(
    name: str, params: dict[str, Any], overrides: dict[str, Any] | None = None
) -> tuple[Plant, dict[str, Any]]:
    """The controllable plant of generator ``name``: ``params`` validated (defaults filled in), then
    the dotted ``overrides`` applied to the full parameters; returns the plant and its parameters."""
    from .spec import validation_summary

    gen = registry.source(name)
    if getattr(gen, "control_plant", None) is None:
        able = sorted(n for n, g in registry.sources().items() if getattr(g, "control_plant", None) is not None)
        raise SpecError(
            f"generator '{name}' describes no controllable plant",
            "--plant",
            f"use one of: {', '.join(able) or '(none installed)'}",
        )
    try:
        full = gen.Params.model_validate(params).model_dump(mode="json")
        for key, value in (overrides or {}).items():
            _set_dotted(full, key, value)
        validated = gen.Params.model_validate(full)
    except ValueError as exc:
        raise SpecError(
            f"invalid plant parameter ({validation_summary(exc)})",
            "--plant / --param",
            f"see the '{name}' entry of `dynmodel schema`",
        ) from None
    return gen.control_plant(validated), validated.model_dump(mode="json")


def _where(model) -> str:
    """The model file, for messages (the path fit wrote it to), else 'the model'."""
    spec = getattr(model, "spec", None) or {}
    return str(spec.get("output") or "the model")


def _feedforward_layout(model, plant: Plant) -> tuple[int, list[str]]:
    """The model output that is the feed-forward force, and notes; every model input gets the reference."""
    notes = []
    bad = [n for n in model.input_names if n not in plant.reference_inputs]
    if bad:
        raise DataError(
            f"the model's input '{bad[0]}' is not a position signal of the plant (it offers "
            f"{', '.join(plant.reference_inputs)})",
            _where(model),
            "fit a model whose inputs are position signals, e.g. data.input: [position]",
        )
    outs = list(model.output_names)
    if plant.force_output in outs:
        k = outs.index(plant.force_output)
    elif len(outs) == 1:
        k = 0
        notes.append(
            f"the model predicts '{outs[0]}', not the plant's actuator force '{plant.force_output}'; "
            "it is used as the feed-forward force as it is"
        )
    else:
        raise DataError(
            f"the model has outputs {outs} and none is the plant's force '{plant.force_output}'",
            _where(model),
            f"fit a model of the output '{plant.force_output}'",
        )
    return k, notes


def run(model, plant: Plant, settings: Settings, progress: Progress = no_progress) -> Report:
    """The tracking task of 6.4.4 over ``settings.realizations`` noise realizations."""
    st = plant.sampling_time
    if abs(model.sampling_time - st) > 1e-9 * st:
        raise DataError(
            f"the model was fitted at a sampling time of {model.sampling_time:g} s and the plant "
            f"samples every {st:g} s",
            _where(model),
            "fit the model on data sampled like the plant",
        )
    n = int(round(settings.duration / st))
    switch = int(round(settings.switch / st))
    skip = int(round(settings.skip / st))
    if not 0 < skip < switch < n - skip:
        raise SpecError(
            f"need 0 < skip ({settings.skip:g} s) < switch ({settings.switch:g} s) < duration - skip "
            f"({settings.duration - settings.skip:g} s)",
            "--switch / --skip / --duration",
            "e.g. --duration 100 --switch 50 --skip 20 (thesis 6.4.4)",
        )
    k_out, notes = _feedforward_layout(model, plant)
    seq = np.random.SeedSequence([settings.seed, 0x636F6E74726F6C])
    ref_seq, *noise_seqs = seq.spawn(1 + settings.realizations)
    progress("control", 0.0, "reference and perfect feed-forward")
    task = plant.tracking_task(n, np.random.default_rng(ref_seq))
    reference = task.reference
    u = np.repeat(reference[:, None], len(model.input_names), axis=1)
    if model.train_input is not None:
        lo, hi = np.min(model.train_input, axis=0), np.max(model.train_input, axis=0)
        if reference.min() < lo.min() or reference.max() > hi.max():
            notes.append(
                f"the reference spans [{reference.min():.4g}, {reference.max():.4g}], beyond the training "
                f"input range [{lo.min():.4g}, {hi.max():.4g}]"
            )
    ff_perfect = task.perfect_feedforward()
    hold = 1 if settings.hold == "linear" else 0

    def model_feedforward(force_before: np.ndarray | None) -> np.ndarray:
        tune = None
        if model.warmup:
            assert force_before is not None  # a model with a tune-in gets the P-controlled start
            y = np.zeros((model.warmup, len(model.output_names)))
            y[:, k_out] = force_before[: model.warmup]
            tune = y
        res = model.run(u, tune)
        if res.diverged_at is not None:
            k = res.diverged_at
            raise FreeRunDiverged(
                f"the model's free run on the reference diverged at sample {k} (t = {k * st:.6g} s)",
                _where(model),
                "use a model that stays stable on this reference (e.g. the internal mode)",
                sample=k,
            )
        return res.y[:, k_out]

    ff_model = None if model.warmup else model_feedforward(None)
    if model.warmup:
        notes.append(
            f"the model tunes in on its first {model.warmup} outputs: taken from the control force of "
            "each realization's P-controlled start"
        )

    def one(r: int):
        trk = task.start(switch, np.random.default_rng(noise_seqs[r]), hold)
        ffm = ff_model if ff_model is not None else model_feedforward(trk.force)
        pos_m, _ = trk.resume(ffm)
        pos_p, _ = trk.resume(ff_perfect)
        e_m = np.concatenate([trk.position, pos_m]) - reference
        e_p = np.concatenate([trk.position, pos_p]) - reference
        return criteria(reference, e_m, switch, skip), criteria(reference, e_p, switch, skip), e_m, e_p, ffm

    workers = max(1, min(settings.realizations, settings.workers or (os.cpu_count() or 1)))
    results: list = [None] * settings.realizations
    done = 0
    with ThreadPoolExecutor(workers) as pool:
        for r, res in zip(range(settings.realizations), pool.map(one, range(settings.realizations))):
            results[r] = res
            done += 1
            progress("control", done / settings.realizations, f"realization {done}/{settings.realizations}")
    _, _, e_m, e_p, ffm = results[0]
    series = {
        "t": np.arange(n) * st,
        "reference": reference,
        "error_model": e_m,
        "error_perfect": e_p,
        "feedforward_model": ffm,
        "feedforward_perfect": ff_perfect,
    }
    return Report(
        plant={"description": plant.description},
        model=[x[0] for x in results],
        perfect=[x[1] for x in results],
        notes=notes,
        series=series,
        settings={
            "duration": settings.duration,
            "switch": settings.switch,
            "skip": settings.skip,
            "realizations": settings.realizations,
            "seed": settings.seed,
            "hold": settings.hold,
            "sampling_time": st,
            "samples": n,
        },
    )
