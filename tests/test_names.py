"""The cost names have one home (dynmodel.metrics.COSTS); the spec schema and the array API's
signature, which spell them out for help and validation, must agree with it."""

from __future__ import annotations

import inspect
from typing import get_args

import pytest

from dynmodel.errors import ParameterError
from dynmodel.metrics import COSTS
from dynmodel.spec import spec_json_schema
from dynmodel_plugins.narx import Narx


def test_the_spec_schema_and_the_fit_signature_name_the_same_costs():
    enum = next(a["enum"] for a in spec_json_schema()["properties"]["cost"]["anyOf"] if "enum" in a)
    assert tuple(enum) == COSTS == ("mse1", "mse_inf")
    annotation = inspect.signature(Narx.fit).parameters["cost"].annotation
    assert all(f"'{c}'" in annotation for c in COSTS) or set(COSTS) <= set(get_args(annotation))


def test_an_unknown_cost_is_refused_before_the_fit():
    with pytest.raises(ParameterError, match="unknown cost 'mse2'"):
        Narx().fit([[0.0]] * 50, [[0.0]] * 50, cost="mse2")
