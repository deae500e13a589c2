"""Data that cannot give a meaningful model, caught when the data are loaded (so at `validate` time):
an output constant on a split (NMSE 0/0), an input constant over training (its effect cannot be
learned), a column that is both input and output, values too large for float64 statistics, a
series that grows over many orders of magnitude (a diverging simulation or a corrupt column), and a
model tune-in that leaves a split without scored samples. Each is one :class:`DataError` line."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import DataError

if TYPE_CHECKING:
    from .dataset import Dataset

#: a magnitude whose square (variance, NMSE) still fits in float64 with room to spare
OVERFLOW = 1e150
#: a column whose typical deviation is below this has a variance that underflows float64 (1e-308)
UNDERFLOW = 1e-150
#: a column whose largest deviation from its median exceeds this many typical deviations spans
#: too many orders of magnitude to be a measured signal
GROWTH = 1e8


def _columns(ds: Dataset, rec, kind: str) -> list[str]:
    own = rec.input_columns if kind == "input" else rec.output_columns
    return list(own) if own else list(ds.input_names if kind == "input" else ds.output_names)


def _check_magnitudes(ds: Dataset, source: str) -> None:
    for rec in ds.recordings:
        for kind, values in (("input", rec.u), ("output", rec.y)):
            names = _columns(ds, rec, kind)
            for j in range(values.shape[1]):
                col = values[:, j]
                big = np.flatnonzero(np.abs(col) > OVERFLOW)
                if big.size:
                    k = int(big[0])
                    raise DataError(
                        f"{kind} column '{names[j]}' holds {col[k]:.3g} at sample {rec.offset + k} of "
                        f"'{rec.name}', too large for float64 statistics (its square overflows)",
                        source,
                        "rescale the column (other units) or remove that sample",
                    )
                med = np.median(col)
                dev = np.abs(col - med)
                scale = np.median(dev)
                if scale == 0:
                    scale = dev.mean()
                if scale == 0:
                    continue
                if scale < UNDERFLOW:  # its variance underflows: every NMSE of it would read 0 or nonsense
                    raise DataError(
                        f"{kind} column '{names[j]}' of '{rec.name}' varies by about {scale:.3g}, too little for "
                        "float64 statistics (its variance underflows)",
                        source,
                        "rescale the column (other units)",
                    )
                k = int(np.argmax(dev))
                ratio = dev[k] / scale
                if ratio > GROWTH:
                    raise DataError(
                        f"{kind} column '{names[j]}' reaches {col[k]:.3g} at sample {rec.offset + k} of "
                        f"'{rec.name}', {ratio:.1e} times its typical deviation from the median: the series "
                        "diverges or holds a corrupt value",
                        source,
                        "check the recording (units, a diverging simulation or generator parameters, an outlier)",
                    )


def _check_same_columns(ds: Dataset, source: str) -> None:
    if not ds.recordings:
        return
    first = ds.recordings[0]
    ins, outs = _columns(ds, first, "input"), _columns(ds, first, "output")
    for j, a in enumerate(ins):
        for k, b in enumerate(outs):
            if a == b:
                raise DataError(
                    f"column '{a}' is both an input and an output: the model would be given the answer",
                    source,
                    "remove it from data.input or data.output",
                )
            if all(np.array_equal(r.u[:, j], r.y[:, k]) for r in ds.recordings):
                raise DataError(
                    f"input '{a}' and output '{b}' hold identical values in every recording",
                    source,
                    "select the measured output in data.output (two columns hold the same signal)",
                )


def _check_constant(ds: Dataset, source: str) -> None:
    for split in ds.ranges:
        rows = ds.scored(split)
        if not rows:
            continue
        y = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in rows])
        for k in range(y.shape[1]):
            if np.ptp(y[:, k]) == 0:
                name = _columns(ds, ds.recordings[rows[0][0]], "output")[k]
                raise DataError(
                    f"output '{name}' is constant ({y[0, k]:.6g}) on every scored sample of the {split} split: "
                    "there is nothing to model and the NMSE is undefined",
                    source,
                    "check data.output and the split (the output must vary where it is scored)",
                )
    rows = ds.scored("train")
    if rows:
        u = np.concatenate([ds.recordings[r].u[a:b] for r, a, b in rows])
        for j in range(u.shape[1]):
            if np.ptp(u[:, j]) == 0:
                name = _columns(ds, ds.recordings[rows[0][0]], "input")[j]
                raise DataError(
                    f"input '{name}' is constant ({u[0, j]:.6g}) on every training sample: the model cannot learn "
                    "its effect",
                    source,
                    "remove it from data.input, or train on data where it varies",
                )


def check_signals(ds: Dataset, source: str) -> None:
    """Raise DataError for data no model can be fitted to or scored on (see the module docstring)."""
    _check_magnitudes(ds, source)
    _check_same_columns(ds, source)
    _check_constant(ds, source)


def check_warmup(ds: Dataset, warmup: int, source: str) -> None:
    """A model that tunes in on its first ``warmup`` measured samples of every recording must leave
    scored samples in every split."""
    if warmup <= 0:
        return
    for split in ds.ranges:
        if ds.ranges[split] and ds.n_scored(split, warmup) == 0:
            # the tune-in counts from a recording's start: a split's range ending at sample b needs it below b
            longest = max(stop for _, _, stop in ds.ranges[split])
            raise DataError(
                f"the model tunes in on the first {warmup} samples of every recording, which leaves no scored "
                f"sample in the {split} split (it ends at sample {longest} of its longest recording)",
                f"{source}: model.params",
                f"shorten the model's tune-in below {longest} samples, or give longer recordings",
            )
