"""Base class of data-generator plugins (entry-point group ``dynmodel.sources``).

A generator produces one input/output recording of ``n`` samples from its validated
parameters and a ``numpy.random.Generator``; the same parameters and seed give the same data.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict


class GeneratorParams(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Generator:
    """Subclass, set the class attributes, and implement :meth:`generate`."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    Params: ClassVar[type[GeneratorParams]] = GeneratorParams
    input_names: ClassVar[tuple[str, ...]] = ("u",)
    output_names: ClassVar[tuple[str, ...]] = ("y",)

    @classmethod
    def sampling_time(cls, params: GeneratorParams) -> float:
        """Seconds (or time units) between samples."""
        return float(getattr(params, "sampling_time", 1.0))

    @classmethod
    def generate(cls, params: Any, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(u, y)`` with shapes ``(n, n_inputs)`` and ``(n, n_outputs)``; ``params`` is an instance of
        the generator's own ``Params``."""
        raise NotImplementedError

    #: optional: ``control_plant(params)`` returning a :class:`dynmodel.control.Plant`, which makes the
    #: generator a plant for ``dynmodel control`` (None: not a plant)
    control_plant: ClassVar[Any] = None  # a classmethod (params) -> Plant in a plant generator
