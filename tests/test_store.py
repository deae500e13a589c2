"""HDF5 model files: layout, round trip, atomic writes, clear errors for bad files."""

from __future__ import annotations

import json
import os

import h5py
import numpy as np
import pytest
from conftest import make_spec, narx_spec

from dynmodel import engine, store
from dynmodel.errors import ModelFileError


@pytest.fixture(scope="module")
def model():
    return engine.fit(
        make_spec(
            narx_spec(
                mode="external", n=2000, test_n=800, transient=100, size=50, split={"train": 0.7, "validation": 0.3}
            )
        )
    )


def test_layout_opens_in_any_hdf5_reader(tmp_path, model):
    path = store.save(model, tmp_path / "m.h5")
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == "dynmodel-model" and f.attrs["format_version"] == 1
        assert f.attrs["family"] == "esn"
        spec = json.loads(f["spec"][()])
        assert spec["model"]["params"]["size"] == 50 and spec["data"]["generator"] == "narx-system"
        assert {"C_data", "C_indices", "C_indptr", "W", "w0", "B_in", "B_back"} <= set(f["params"])
        assert f["params"]["W"].shape == (1, 50)
        assert f["eval/test"].attrs["nmse"] == pytest.approx(model.metrics["test"]["nmse"])
        prov = f["provenance"].attrs
        assert prov["dynmodel_version"] and len(prov["training_data_sha256"]) == 64 and prov["seed"] == 0
        assert f["data/train_input"].shape == (1400, 1) and f["data/train_output"].shape == (1400, 1)
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def test_failed_write_leaves_the_previous_file_intact(tmp_path, model, monkeypatch):
    path = store.save(model, tmp_path / "m.h5")
    before = path.read_bytes()

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(type(model.family), "to_arrays", boom)
    with pytest.raises(RuntimeError):
        store.save(model, path)
    assert path.read_bytes() == before
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def test_truncated_file(tmp_path, model):
    path = store.save(model, tmp_path / "m.h5")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 3])
    with pytest.raises(ModelFileError, match="not a readable HDF5 model file"):
        store.load(path)


def test_not_hdf5_and_not_ours(tmp_path):
    (tmp_path / "x.h5").write_text("hello")
    with pytest.raises(ModelFileError, match='is text starting with "hello", not a model file'):
        store.load(tmp_path / "x.h5")
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["a"] = 1
    with pytest.raises(ModelFileError, match="not a dynmodel model file"):
        store.load(tmp_path / "other.h5")
    with pytest.raises(ModelFileError, match="not found"):
        store.load(tmp_path / "missing.h5")


def test_newer_format_and_missing_group(tmp_path, model):
    path = store.save(model, tmp_path / "m.h5")
    with h5py.File(path, "a") as f:
        f.attrs["format_version"] = 7
    with pytest.raises(ModelFileError, match="newer dynmodel \\(format version 7"):
        store.load(path)
    path = store.save(model, tmp_path / "n.h5")
    with h5py.File(path, "a") as f:
        del f["preprocessing"]
    with pytest.raises(ModelFileError, match="'/preprocessing' entry is missing"):
        store.load(path)
    path = store.save(model, tmp_path / "o.h5")
    with h5py.File(path, "a") as f:
        del f["params/W"]
    with pytest.raises(ModelFileError, match="corrupt model file"):
        store.load(path)


def test_round_trip_keeps_everything(tmp_path, model):
    loaded = store.load(store.save(model, tmp_path / "m.h5"))
    assert loaded.spec == model.spec and loaded.metrics == model.metrics
    assert loaded.provenance == model.provenance
    np.testing.assert_array_equal(loaded.train_input, model.train_input)
    np.testing.assert_array_equal(loaded.train_output, model.train_output)
    a, b = model.family.to_arrays(), loaded.family.to_arrays()
    for key in a[0]:
        np.testing.assert_array_equal(a[0][key], b[0][key])
    assert a[1] == b[1]


def test_a_model_built_in_python_loads(tmp_path):
    """The family's parameters come from the family, not from the spec (a model assembled in Python has
    no spec that names them: this failed with "corrupt model file (KeyError: 'model')")."""
    from conftest import narx

    from dynmodel.data import Dataset, Preprocessor, Recording, training_data
    from dynmodel.model import FittedModel, evaluate
    from dynmodel_plugins.narx import Narx

    u, y = narx(1200, 5)
    ds = Dataset([Recording("r", u[:, None], y[:, None])], {"train": [(0, 0, 900)], "validation": [(0, 900, 1200)]}, 0, ["u"], ["y"], 1.0)  # fmt: skip
    pre = Preprocessor.fit(ds, [], "standard")
    td = training_data(ds, pre)
    family = Narx(degree=2, lags={"u": [0, 1], "y": [1, 2]}).fit(td)
    model = FittedModel(family, pre, td.output_bounds(), spec={})
    model.metrics, _ = evaluate(model, ds)
    loaded = store.load(store.save(model, tmp_path / "m.h5"))
    assert loaded.family.params == family.params
    np.testing.assert_array_equal(loaded.predict(u, y[:2]), model.predict(u, y[:2]))


def test_files_without_family_params_read_them_from_the_spec(tmp_path, model):
    path = store.save(model, tmp_path / "m.h5")
    with h5py.File(path, "a") as f:
        assert json.loads(f.attrs["family_params"])["size"] == 50
        del f.attrs["family_params"]  # as written before the attribute existed
    loaded = store.load(path)
    assert loaded.family.params == model.family.params
