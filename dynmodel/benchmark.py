"""Base class of benchmark-source plugins (entry-point group ``dynmodel.sources``, ``kind = "benchmark"``).

A benchmark source reads one standard system-identification benchmark from files in a local
folder and returns it laid out by its protocol: the training recordings, the test sets (each
with its state-initialization window, or scored on every sample) and the units the field
reports it in. The protocols are those of the ``nonlinear-benchmarks`` package 1.0.1 (or, where
that package fixes none, of the benchmark's own document). A source never downloads anything:
a missing file is one line naming what to fetch and from where.

In a spec::

    data: {benchmark: silverbox, root: ../data/silverbox, split: {train: 0.8, validation: 0.2}}
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from .data.dataset import Recording
from .errors import DataError


@dataclass
class TestSet:
    """One test set of a benchmark: its recordings and how the protocol scores them."""

    name: str | None  # None: the benchmark's only test set (metrics key "test"), else key "test:<name>"
    recordings: list[Recording]
    window: int = 0  # samples at the start of each recording that may initialize the model, not scored
    score_all: bool = False  # every sample is scored and no measured output may be used
    #: with score_all: samples at the start of each recording that are simulated from the input alone and
    #: not scored (a steady-state test period preceded by a copy of itself, so that the run reaches the
    #: periodic steady state the recording was measured in)
    lead_in: int = 0


@dataclass
class BenchmarkData:
    """A benchmark laid out by its protocol, in the data's units."""

    train: list[Recording]
    tests: list[TestSet]
    input_names: list[str]
    output_names: list[str]
    sampling_time: float
    #: reporting units per output: {output: (scale, unit name)}, reported = scale x value in the data's units
    units: dict[str, tuple[float, str]] = field(default_factory=dict)
    #: the protocol's window for a validation split carved from the training data (that of the tests);
    #: None: no protocol, a validation range continues the free run of its training recording
    window: int | None = 0
    score_all: bool = False


class BenchmarkSource:
    """Subclass, set the class attributes, implement :meth:`load`."""

    kind: ClassVar[str] = "benchmark"
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    #: the names of the test sets (empty: a single unnamed test set)
    test_sets: ClassVar[tuple[str, ...]] = ()
    #: where the files come from (a web page or archive), for the missing-file message
    fetch: ClassVar[str] = ""
    #: the reference to cite
    citation: ClassVar[str] = ""

    @classmethod
    def load(cls, root: Path) -> BenchmarkData:
        """Read the benchmark's files from ``root`` and lay them out by the protocol."""
        raise NotImplementedError

    # -- helpers for subclasses ------------------------------------------------------------
    @classmethod
    def require(cls, root: Path, *alternatives: str) -> Path:
        """The first of ``alternatives`` (file names in ``root``) that exists, else a one-line DataError."""
        for name in alternatives:
            path = root / name
            if path.is_file():
                return path
        wanted = " or ".join(alternatives)
        where = str(root) if root.is_dir() else f"{root} (no such folder)"
        raise DataError(
            f"benchmark '{cls.name}' needs {wanted}, which is not in its root folder",
            where,
            f"fetch it from {cls.fetch} and put it there (or point data.root to the folder that holds it)",
        )

    @classmethod
    def steady_state(cls, name: str, u: np.ndarray, y: np.ndarray) -> TestSet:
        """A test set holding one period of a periodic steady-state response: simulated over the input
        repeated twice from rest, scored on the second period (the model sees the test input only)."""
        rec = cls.recording(name, np.concatenate([u, u]), np.concatenate([y, y]))
        return TestSet(name=None, recordings=[rec], window=0, score_all=True, lead_in=len(u))

    @staticmethod
    def recording(name: str, u: np.ndarray, y: np.ndarray) -> Recording:
        """A recording from 1-D or 2-D arrays (copied, float64, one column per channel)."""
        u = np.asarray(u, dtype=np.float64).reshape(len(u), -1).copy()
        y = np.asarray(y, dtype=np.float64).reshape(len(y), -1).copy()
        if len(u) != len(y):
            raise DataError(f"input has {len(u)} samples, output {len(y)}", name, "check the benchmark's files")
        return Recording(name, u, y)
