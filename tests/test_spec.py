"""The YAML spec: the issue's examples validate, defaults resolve, mistakes get one clear line."""

from __future__ import annotations

import json

import pytest
from conftest import ROOT, narx_spec

from dynmodel.errors import SpecError
from dynmodel.spec import load_spec, parse_yaml, spec_json_schema, validate_spec


def test_issue_examples_validate_with_resolved_defaults():
    file_spec = load_spec(ROOT / "specs/examples/file-example.yaml")
    assert file_spec.cost == "mse_inf" and file_spec.seed == 3
    assert file_spec.data.noise.std == 0.5 and file_spec.data.noise.splits == ["train", "validation"]
    assert file_spec.model.params.mode == "external" and file_spec.model.params.scale.by == "singular"
    assert file_spec.output_path() == (ROOT / "specs/examples/model.h5").resolve()
    gen_spec = load_spec(ROOT / "specs/examples/generator-example.yaml")
    assert gen_spec.data.split.test == (10000, 20000)
    params = gen_spec.model.params
    # defaults: the thesis 5.3.2 networks, with the input reaching half the elements and leaky elements (issue 14)
    assert (params.size, params.connectivity, params.input_connectivity, params.bias_connectivity) == (
        200,
        0.01,
        0.5,
        0.8,
    )
    assert params.relaxation == (0.0, 0.99) and params.relaxation_gain and params.bounds == 0.5
    assert params.tune_in == 20
    assert params.scale.by == "singular" and params.scale.value == 0.95
    resolved = gen_spec.resolved()
    assert resolved["model"]["params"]["connectivity"] == 0.01
    assert resolved["output"].endswith("generator-example.h5")
    assert validate_spec(json.loads(json.dumps(resolved))).resolved() == resolved  # resolved spec is a fixed point


def test_resolved_spec_with_separate_sources_is_a_fixed_point():
    raw = narx_spec(split={"train": 0.8, "validation": 0.2})
    resolved = validate_spec(raw).resolved()
    assert resolved["data"]["test"]["generator"] is None  # unset keys of the separate test source are dumped as null
    assert validate_spec(json.loads(json.dumps(resolved))).resolved() == resolved


def test_every_bundled_spec_validates():
    for path in sorted((ROOT / "specs").rglob("*.yaml")):
        load_spec(path)


def _error(raw) -> str:
    with pytest.raises(SpecError) as info:
        validate_spec(raw, "spec.yaml")
    line = str(info.value)
    assert "\n" not in line
    return line


def test_unknown_keys_are_named_with_a_suggestion():
    raw = narx_spec()
    raw["data"]["splt"] = raw["data"].pop("split")
    line = _error(raw)
    assert "unknown key 'splt'" in line and "did you mean 'split'" in line and "spec.yaml: data" in line
    raw = narx_spec(sise=10)
    line = _error(raw)
    assert "unknown key 'sise'" in line and "model.params" in line and "'size'" in line
    raw = narx_spec()
    raw["modle"] = {}
    assert "did you mean 'model'" in _error(raw)


def test_unknown_family_and_generator_list_the_installed_ones():
    raw = narx_spec()
    raw["model"]["family"] = "esm"
    line = _error(raw)
    assert "unknown family 'esm'" in line and "did you mean 'esn'" in line
    raw = narx_spec()
    raw["data"]["generator"] = "lorenz"
    line = _error(raw)
    assert "unknown generator 'lorenz'" in line and "narx-system" in line and "rossler-lorenz" in line


def test_wrong_values_say_where_and_what():
    raw = narx_spec()
    raw["model"]["params"]["size"] = "many"
    line = _error(raw)
    assert "model.params.size" in line and "integer" in line and '"many"' in line
    raw = narx_spec(split={"train": 0.8, "validation": 0.4})
    assert "add up to 1.2" in _error(raw)
    raw = narx_spec(split={"train": [0, 5000], "test": [4000, 9000]})
    assert "overlap" in _error(raw)
    raw = narx_spec(split={"train": 400, "test": 100})  # sample counts where fractions go
    line = _error(raw)
    assert "data.split.train" in line and "write the range [start, stop], e.g. [0, 400]" in line
    raw = narx_spec(cost="mse2")
    assert "cost" in _error(raw)
    raw = narx_spec()
    raw["data"]["params"] = {"a0": 2.0}  # |a0| of the linear generator is fine here, but b0 must be a number
    raw["data"]["params"]["b0"] = "x"
    assert "data.params.b0" in _error(raw)


def test_relaxation_and_explicit_weights_are_checked():
    raw = narx_spec(relaxation=1.5)
    assert "relaxation must lie in (-1, 1)" in _error(raw)
    raw = narx_spec(weights={"C": [[0.1, 0.2], [0.3]]})
    assert "C must be square" in _error(raw)
    raw = narx_spec(weights={"C": [[0.34, 2.31], [-0.56, -1.93]]})
    for key in ("size", "scale"):
        raw["model"]["params"].pop(key)
    spec = validate_spec(raw)
    assert spec.model.params.size == 2 and spec.model.params.scale.by == "none"


@pytest.mark.parametrize(
    "text, expected",
    [
        ("name: x\ndata:\n  path: a.csv\n   input: [u]\n", "spec.yaml:4:"),
        ("name: x\ndata: {path: a.csv\n", "malformed YAML"),
        ("name: x\nname: y\n", "duplicate key 'name'"),
        ("", "the spec is empty"),
        ("- a\n- b\n", "must be a mapping"),
        ("yes: 1\n", "the key True is not a name"),
        ("1: 2\n", "the key 1 is not a name"),
        ("? [a, b]\n: 1\n", "a list is used as a key"),
    ],
)
def test_yaml_problems(text, expected):
    with pytest.raises(SpecError) as info:
        parse_yaml(text, "spec.yaml")
    assert expected in str(info.value)


def test_json_schema_shows_every_family_and_generator_parameter():
    schema = json.dumps(spec_json_schema())
    for needle in [
        "input_connectivity",
        "relaxation_gain",
        "tune_in",
        "narx-system",
        "rossler-cross",
        "horizon",
        "integration_step",
        "delay_lines",
        "transient",
    ]:
        assert needle in schema, needle


def test_a_spec_without_cost_takes_its_familys_default_cost():
    data = {"generator": "narx-system", "n": 500}
    narx_spec_ = validate_spec({"data": data, "model": {"family": "narx"}})
    esn_spec = validate_spec({"data": data, "model": {"family": "esn"}})
    assert narx_spec_.cost == "mse_inf" and esn_spec.cost == "mse1"  # narx is estimated where it is used: free run
    assert validate_spec({"data": data, "model": {"family": "narx"}, "cost": "mse1"}).cost == "mse1"
    resolved = narx_spec_.resolved()
    assert resolved["cost"] == "mse_inf" and validate_spec(resolved).resolved() == resolved


def test_yaml_merge_keys_and_named_delimiters():
    """A shared block merged with <<: *anchor (its keys may be overridden, as YAML allows), and a delimiter
    written '\\t' in single quotes or by name."""
    raw = parse_yaml(
        "defaults: &d {input: [u], output: [y]}\ndata:\n  <<: *d\n  path: a.csv\n  output: [z]\n", "spec.yaml"
    )
    assert raw["data"] == {"input": ["u"], "output": ["z"], "path": "a.csv"}
    for written in ("'\\t'", "tab", "'\t'"):
        text = f"data: {{path: a.csv, input: [u], output: [y], delimiter: {written}}}\nmodel: {{family: narx}}\n"
        spec = validate_spec(parse_yaml(text, "s"))
        assert spec.data.delimiter == "\t"
    with pytest.raises(SpecError, match="is not one character"):
        validate_spec(
            {"data": {"path": "a.csv", "input": ["u"], "output": ["y"], "delimiter": ",,"}, "model": {"family": "narx"}}
        )


def test_the_default_model_file_stays_next_to_the_spec():
    for name, file in (
        ("a/b/c", "a-b-c.h5"),
        ("../escape", "escape.h5"),
        ("", "model.h5"),
        ("tanks-auto", "tanks-auto.h5"),
    ):
        spec = validate_spec({"name": name, "data": {"generator": "narx-system"}, "model": {"family": "narx"}})
        assert spec.output_path().name == file and spec.output_path().parent == spec.resolve_path(".")


def test_a_misspelt_key_of_a_derived_input_names_that_kinds_keys():
    with pytest.raises(SpecError) as info:
        validate_spec(
            {
                "data": {
                    "path": "a.csv",
                    "input": ["u"],
                    "output": ["y"],
                    "derived_inputs": [{"direction": "u", "deadbnad": 1}],
                },
                "model": {"family": "narx"},
            }
        )
    text = str(info.value)
    assert "data.derived_inputs[0]: unknown key 'deadbnad'" in text and "did you mean 'deadband'" in text
    assert "Allowed keys here: direction, deadband, name" in text


@pytest.mark.parametrize(
    "text, where",
    [
        ("seed: on", "seed"),
        ("model: {family: narx, params: {degree: yes}}", "model.params.degree"),
        ("model: {family: esn, params: {size: true}}", "model.params.size"),
        ("data: {generator: narx-system, n: 2000, noise: {std: no}}", "data.noise.std"),
        ("data: {generator: narx-system, n: 2000, split: {train: yes}}", "data.split.train"),
    ],
)
def test_a_boolean_for_a_number_is_refused(text, where):
    """pydantic reads true as 1: ``degree: yes`` silently fitted degree 1."""
    base = "name: t\n"
    base += "" if text.startswith("data") else "data: {generator: narx-system, n: 2000}\n"
    base += "" if text.startswith("model") else "model: {family: narx}\n"
    raw = parse_yaml(base + text + "\n", "s.yaml")
    with pytest.raises(SpecError) as err:
        validate_spec(raw, "s.yaml")
    assert err.value.where == f"s.yaml: {where}" and "a number, not true or false" in err.value.what


def test_yaml_exponents_are_numbers():
    raw = parse_yaml(
        "name: t\ndata: {generator: narx-system, n: 2000}\nmodel: {family: narx, params: {ridge: 1e-6}}\n", "s"
    )
    assert raw["model"]["params"]["ridge"] == 1e-6
