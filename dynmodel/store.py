"""HDF5 model files (h5py): open in any HDF5 viewer, no pickle, no eval.

Layout (``format_version`` 1)::

    /                 attrs: format="dynmodel-model", format_version, family, family_params (JSON), name, created
    /spec             string dataset: the fully resolved spec as JSON
    /params/          family arrays as datasets; family attributes as attrs
    /preprocessing/   input/output offsets and scales, divergence bounds; names, delay lines as attrs
    /eval/            one group per split with metric attrs (group test_<name> for the metrics key test:<name>,
                      its attr "split" holds the key); attr "metrics_json" holds everything
    /provenance       attrs: dynmodel version, seed, sha256 of the training data, library versions
    /data/            training inputs and outputs (for reliability checks), gzip-compressed
    /search           (family: auto only) string dataset: the search record as JSON (docs/auto.md)

The file is written to a temporary name in the target folder (``.<name>.<pid>@<host>.<random>.tmp``)
and renamed, so a crash never leaves a half-written model behind; a temporary file left by a killed
write is removed by the next write to that path. The file gets the permissions of any new file
(0666 minus the user's umask), not the private 0600 of a temporary file.
"""

from __future__ import annotations

import json
import os
import re
import socket
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from . import registry
from .data.preprocess import Preprocessor
from .errors import ModelFileError
from .family import Family
from .model import FittedModel
from .paths import umask

FORMAT = "dynmodel-model"
FORMAT_VERSION = 1
_JSON_KEYS = "_json_keys"
_REQUIRED = ("spec", "params", "preprocessing", "eval", "provenance")


def _write_attrs(obj, attrs: dict[str, Any]) -> None:
    json_keys = []
    for key, value in attrs.items():
        if value is None:
            continue
        if isinstance(value, (str, bool, int, float, np.integer, np.floating)):
            obj.attrs[key] = value
        else:
            obj.attrs[key] = json.dumps(value, default=_json_default)
            json_keys.append(key)
    if json_keys:
        obj.attrs[_JSON_KEYS] = json.dumps(json_keys)


def _read_attrs(obj) -> dict[str, Any]:
    json_keys = set(json.loads(obj.attrs[_JSON_KEYS])) if _JSON_KEYS in obj.attrs else set()
    out: dict[str, Any] = {}
    for key, value in obj.attrs.items():
        if key == _JSON_KEYS:
            continue
        if isinstance(value, bytes):
            value = value.decode()
        if key in json_keys:
            value = json.loads(value)
        elif isinstance(value, np.generic):
            value = value.item()
        out[key] = value
    return out


def _json_default(o: Any):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def eval_group(split: str) -> str:
    """The /eval group of a metrics key: ``test:<name>`` -> ``test_<name>`` (no ':' in HDF5 names)."""
    return split.replace(":", "_")


#: a temporary file of another host (or of an unknown writer) counts as stale after this many seconds
STALE_AFTER = 3600.0


def _host() -> str:
    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname())[:32] or "host"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def remove_stale_temporaries(path: str | Path) -> list[Path]:
    """Remove the temporary files that killed writes to ``path`` left behind: those of a process
    of this host that no longer runs, and any other one older than :data:`STALE_AFTER`."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    prefix = f".{path.name}."
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    pattern = re.compile(r"^(?P<pid>\d+)@(?P<host>[A-Za-z0-9-]+)\.[^.]+$")
    host, now = _host(), time.time()
    for entry in entries:
        name = entry.name
        if not (name.startswith(prefix) and name.endswith(".tmp")) or not entry.is_file(follow_symlinks=False):
            continue
        m = pattern.match(name[len(prefix) : -len(".tmp")])
        try:
            age = now - entry.stat(follow_symlinks=False).st_mtime
        except OSError:
            continue
        stale = age > STALE_AFTER
        if m is not None and m.group("host") == host:
            stale = not _pid_alive(int(m.group("pid")))
        if stale:
            try:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
            except OSError:
                pass
    return removed


def save(model: FittedModel | Family, path: str | Path) -> Path:
    """Write ``model`` (a FittedModel, or a family fitted on arrays) to ``path`` atomically; returns the path."""
    import h5py

    if isinstance(model, Family):
        model = model._fitted_model()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}@{_host()}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    os.chmod(tmp, 0o666 & ~umask())
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["format"] = FORMAT
            f.attrs["format_version"] = FORMAT_VERSION
            f.attrs["family"] = model.family.name
            # the family's own parameters: a model built in Python has no spec that names them
            f.attrs["family_params"] = json.dumps(model.family.params.model_dump(mode="json"))
            f.attrs["name"] = str(model.spec.get("name", ""))
            f.attrs["created"] = str(model.provenance.get("created", ""))
            f.create_dataset("spec", data=json.dumps(model.spec, indent=1))
            arrays, attrs = model.family.to_arrays()
            g = f.create_group("params")
            for key, arr in arrays.items():
                g.create_dataset(key, data=np.asarray(arr))
            _write_attrs(g, attrs)
            pre_arrays, pre_attrs = model.preprocessor.to_arrays()
            pg = f.create_group("preprocessing")
            for key, arr in pre_arrays.items():
                pg.create_dataset(key, data=np.asarray(arr, dtype=np.float64))
            pg.create_dataset("bounds_low", data=np.asarray(model.bounds[0], dtype=np.float64))
            pg.create_dataset("bounds_high", data=np.asarray(model.bounds[1], dtype=np.float64))
            _write_attrs(pg, pre_attrs)
            eg = f.create_group("eval")
            eg.attrs["metrics_json"] = json.dumps(model.metrics, default=_json_default)
            for split, values in model.metrics.items():
                sg = eg.create_group(eval_group(split))
                _write_attrs(sg, {"split": split, **{k: v for k, v in values.items() if k != "per_output"}})
            if model.search is not None:  # family: auto: every candidate, its metrics and verdict (docs/auto.md)
                f.create_dataset("search", data=json.dumps(model.search, default=_json_default))
            prov = f.create_group("provenance")
            _write_attrs(prov, model.provenance)
            if model.train_input is not None:
                dg = f.create_group("data")
                dg.create_dataset("train_input", data=model.train_input, compression="gzip", shuffle=True)
                if model.train_input_lengths is not None:
                    dg.create_dataset("train_input_lengths", data=model.train_input_lengths)
                if model.train_output is not None:
                    dg.create_dataset("train_output", data=model.train_output, compression="gzip", shuffle=True)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def load(path: str | Path, families: Mapping[str, type[Family]] | None = None) -> FittedModel:
    """Read a model file; corrupt, incomplete or newer files raise ModelFileError.

    ``families``: family classes by id to use instead of the installed plugins (a family under
    development, not yet registered)."""
    import h5py

    path = Path(path)
    if not path.exists():
        raise ModelFileError("model file not found", str(path), "check the path (dynmodel fit writes it)")
    if path.is_dir():
        raise ModelFileError("is a folder, not a model file", str(path), "give the .h5 file written by `dynmodel fit`")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        from .paths import describe_file

        looks = describe_file(path)
        if looks.startswith("text"):  # a spec or a data file given where the model goes
            spec = path.suffix.lower() in (".yaml", ".yml")
            raise ModelFileError(
                f"is {'a YAML spec' if spec else looks}, not a model file",
                str(path),
                f"fit the spec first (`dynmodel fit {path.name}`) and give the model file it writes"
                if spec
                else "give the model file (.h5) that `dynmodel fit` wrote",
            ) from None
        raise ModelFileError(
            f"not a readable HDF5 model file ({str(exc).split('(')[0].strip()})",
            str(path),
            "the file is truncated or not written by dynmodel; refit with `dynmodel fit`",
        ) from None
    try:
        with f:
            if f.attrs.get("format") != FORMAT:
                raise ModelFileError(
                    "not a dynmodel model file (no format='dynmodel-model' attribute)",
                    str(path),
                    "pass a file written by `dynmodel fit`",
                )
            version = int(f.attrs.get("format_version", -1))
            if version > FORMAT_VERSION:
                raise ModelFileError(
                    f"written by a newer dynmodel (format version {version}, this version reads "
                    f"up to {FORMAT_VERSION})",
                    str(path),
                    "upgrade dynmodel: pip install -U dynmodel",
                )
            if version < 1:
                raise ModelFileError(f"unknown format version {version}", str(path), "refit the model")
            for group in _REQUIRED:
                if group not in f:
                    raise ModelFileError(
                        f"the '/{group}' entry is missing",
                        str(path),
                        "the file is incomplete; refit with `dynmodel fit`",
                    )
            spec = json.loads(f["spec"][()])
            family_name = str(f.attrs["family"])
            family_cls = (families if families is not None else registry.families()).get(family_name)
            if family_cls is None:
                raise ModelFileError(
                    f"the model needs the family plugin '{family_name}', which is not installed",
                    str(path),
                    "install the package that provides it",
                )
            arrays = {k: np.asarray(v[()]) for k, v in f["params"].items()}
            attrs = _read_attrs(f["params"])
            if "family_params" in f.attrs:
                params = json.loads(f.attrs["family_params"])
            else:  # files written before family_params: the spec's model section holds them
                params = spec["model"]["params"]
            family = family_cls.from_arrays(params, arrays, attrs)
            pg = f["preprocessing"]
            pre = Preprocessor.from_arrays({k: pg[k][()] for k in pg}, _read_attrs(pg))
            bounds = (np.asarray(pg["bounds_low"][()]), np.asarray(pg["bounds_high"][()]))
            metrics = json.loads(f["eval"].attrs["metrics_json"])
            provenance = _read_attrs(f["provenance"])
            search = json.loads(f["search"][()]) if "search" in f else None
            train_input = lengths = train_output = None
            if "data" in f and "train_input" in f["data"]:
                train_input = np.asarray(f["data/train_input"][()])
                if "train_input_lengths" in f["data"]:
                    lengths = np.asarray(f["data/train_input_lengths"][()])
                if "train_output" in f["data"]:
                    train_output = np.asarray(f["data/train_output"][()])
    except ModelFileError:
        raise
    except (OSError, KeyError, ValueError, TypeError, json.JSONDecodeError) as exc:
        raise ModelFileError(
            f"corrupt model file ({type(exc).__name__}: {exc})", str(path), "refit with `dynmodel fit`"
        ) from None
    return FittedModel(family, pre, bounds, spec, metrics, provenance, train_input, lengths, train_output, search)
