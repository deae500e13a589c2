"""dynmodel.control.read_plant: the plant file of `dynmodel control`, read by the library."""

from __future__ import annotations

import pytest

from dynmodel.control import plant_source, read_plant
from dynmodel.errors import SpecError


def test_a_plant_file_and_a_whole_spec_give_the_same_plant(tmp_path):
    (tmp_path / "plant.yaml").write_text("generator: gms-plant\nparams: {m: 2.0}\n")
    (tmp_path / "spec.yaml").write_text(
        "name: s\ndata: {generator: gms-plant, params: {m: 2.0}}\nmodel: {family: narx}\n"
    )
    for f in ("plant.yaml", "spec.yaml"):
        assert plant_source(None, read_plant(tmp_path / f)) == ("gms-plant", {"m": 2.0})


@pytest.mark.parametrize(
    "text, what",
    [(None, "plant description not found"), ("generator: [a\n", "malformed YAML"), ("- a\n- b\n", "must be a mapping")],
)
def test_a_bad_plant_file_is_one_spec_error(tmp_path, text, what):
    path = tmp_path / "plant.yaml"
    if text is not None:
        path.write_text(text)
    with pytest.raises(SpecError, match=what) as info:
        read_plant(path)
    assert str(path) in str(info.value)
