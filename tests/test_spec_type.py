"""``dynmodel.spec.Spec`` is a real type: every loaded spec is an instance, functions are annotated with it,
and validating through it goes through the installed plugins (never the generic base types)."""

from __future__ import annotations

import typing

import pytest
from conftest import ROOT, narx_spec
from pydantic import ValidationError

import dynmodel
from dynmodel import engine
from dynmodel.spec import DataCommon, ModelChoice, Spec, load_spec, spec_model, validate_spec


def test_loaded_and_validated_specs_are_instances_of_spec():
    spec = load_spec(ROOT / "specs/quickstart.yaml")
    assert isinstance(spec, Spec) and isinstance(spec, dynmodel.Spec)
    assert dynmodel.Spec is Spec and "Spec" in dynmodel.__all__
    assert isinstance(spec.data, DataCommon) and isinstance(spec.model, ModelChoice)
    assert spec.model.family == "esn" and spec.model.params.size == 200
    assert isinstance(validate_spec(narx_spec()), Spec)


def test_spec_model_is_a_cached_subclass_of_spec():
    built = spec_model()
    assert built is spec_model()
    assert issubclass(built, Spec) and built is not Spec
    assert built.__name__ == "Spec"  # the schema's title
    spec = built.model_validate(narx_spec())
    assert type(spec) is built and isinstance(spec, Spec)
    assert spec.cost == "mse1" and spec.model.params.size == 200


def test_functions_that_take_or_return_a_spec_are_annotated_with_it():
    hints = typing.get_type_hints(dynmodel.load_spec)
    assert hints["return"] is Spec
    assert typing.get_type_hints(dynmodel.validate_spec)["return"] is Spec
    assert "Spec" in str(engine.fit.__annotations__["spec"])
    assert "Spec" in str(engine.fit_dataset.__annotations__["spec"])

    def uses_the_type(spec: Spec) -> str:  # a user's own hint
        return spec.model.family

    assert typing.get_type_hints(uses_the_type)["spec"] is Spec
    assert uses_the_type(load_spec(ROOT / "specs/quickstart.yaml")) == "esn"


def test_spec_model_validate_goes_through_the_installed_plugins():
    spec = Spec.model_validate(narx_spec())
    assert type(spec) is spec_model()  # the registry-driven class, not the generic base
    assert spec.model.family == "esn" and type(spec.model).__name__ == "ModelSpec_esn"
    assert spec.model.params.size == 200

    unknown_family = narx_spec()
    unknown_family["model"] = {"family": "no-such-family", "params": {"size": 3}}
    with pytest.raises(ValidationError) as exc:
        Spec.model_validate(unknown_family)
    assert "no-such-family" in str(exc.value)

    bad_param = narx_spec()
    bad_param["model"]["params"]["no_such_param"] = 1
    with pytest.raises(ValidationError, match="no_such_param"):
        Spec.model_validate(bad_param)

    bad_generator = narx_spec()
    bad_generator["data"]["generator"] = "no-such-generator"
    with pytest.raises(ValidationError):
        Spec.model_validate(bad_generator)


def test_the_base_cannot_be_built_with_generic_types_and_gives_the_full_schema():
    with pytest.raises(TypeError, match="common base of specs"):
        Spec(**narx_spec())
    assert Spec.model_json_schema() == spec_model().model_json_schema()
    assert "ModelSpec_narx" in Spec.model_json_schema()["$defs"]
