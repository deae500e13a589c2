"""Evaluation protocols of the benchmarks: initialization windows, score-everything splits, units.

A protocol fixes, per validation / test split, how many measured samples at the start of each
recording may initialize a model (``data.init_window``, a benchmark's window) or that every sample
is scored from the input alone (``score: all``). Families say how many measured outputs they need
through :attr:`dynmodel.family.Family.warmup`; :func:`check_warmup` refuses a model that needs
more than a split allows, in one line, instead of silently reading the test outputs.

Reporting: ``evaluation.units`` (or a benchmark source's units) converts the RMSE of an output,
reported = scale x value in the data's units; entries of such splits carry ``rmse_units``.
The metrics keep the flat shape ``{split key: entry}`` with keys ``train``, ``validation``,
``test`` (one unnamed test set) or ``test:<name>`` (each named one); see docs/benchmarks.md.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .data.dataset import Dataset
from .errors import SpecError

if TYPE_CHECKING:
    from .api import ArraySpec
    from .spec import Spec


def check_warmup(family: Any, ds: Dataset, source: str) -> None:
    """Raise a one-line SpecError when ``family`` needs more measured outputs than a split's protocol allows."""
    need = int(family.warmup)
    if need <= 0:
        return
    for key, allowed in ds.allowed_warmup().items():
        if need > allowed:
            rule = (
                "scores every sample, so no measured output may be used"
                if key in ds.score_all
                else f"allows the first {allowed} (its initialization window)"
            )
            hint = getattr(family, "warmup_hint", "") or "use a model that needs fewer measured outputs"
            raise SpecError(
                f"the {family.name} model starts a run from its first {need} measured outputs, but the {key} "
                f"split {rule}",
                f"{source}: model.params",
                hint.format(window=allowed),
            )


def units_of(spec: Spec | ArraySpec, ds: Dataset) -> dict[str, tuple[float, str]]:
    """Reporting units per output: the spec's ``evaluation.units`` over the source's own."""
    units = dict(ds.units)
    units.update({name: (u.scale, u.name) for name, u in spec.evaluation.units.items()})
    return units


def report(metrics: dict[str, Any], ds: Dataset, units: dict[str, tuple[float, str]]) -> dict[str, Any]:
    """The metrics with each split's protocol recorded (``init_window`` or ``score: all``, and a
    steady-state ``lead_in``) and the
    RMSE in the reporting units (``rmse_units``: the unit's name, when every output has one)."""
    outputs = ds.output_names
    out: dict[str, Any] = {}
    for key, entry in metrics.items():
        e = dict(entry)
        if key in ds.score_all:
            e["score"] = "all"
        elif key in ds.windows:
            e["init_window"] = ds.windows[key]
        if ds.lead_in.get(key):
            e["lead_in"] = ds.lead_in[key]
        if units and "rmse" in e:
            per = e.get("per_output")
            if per:
                e["per_output"] = {name: dict(v) for name, v in per.items()}
                for name, v in e["per_output"].items():
                    if name in units and v.get("rmse") is not None:
                        v["rmse"] = v["rmse"] * units[name][0]
                        v["rmse_units"] = units[name][1]
                values = [v.get("rmse") for v in e["per_output"].values()]
                e["rmse"] = None if any(v is None for v in values) else sum(values) / len(values)
            elif outputs[0] in units and e["rmse"] is not None:
                e["rmse"] = e["rmse"] * units[outputs[0]][0]
            names = {units[n][1] for n in outputs if n in units}
            if len(names) == 1 and all(n in units for n in outputs):
                e["rmse_units"] = names.pop()
        out[key] = e
    return out
