"""The grid of a sweep: dotted spec keys and their values, expanded into validated point specs.

A grid file maps dotted keys of the spec to lists of values; the points are the Cartesian product
(the last key varies fastest). A ``zip:`` block (or a list of them) pairs its keys instead: its
lists have one length and their i-th values go together. Value lists may be written out or
generated::

    model.params.size: [100, 200, 400]
    seed: {range: [0, 20]}              # 0, 1, ..., 19 (Python's range: [stop], [start, stop], [start, stop, step])
    model.params.scale.value: {linspace: [0.8, 0.99, 4]}
    model.params.readout.ridge: {geomspace: [1e-6, 1e-2, 5]}
    data.delay_lines: [[], [80, 160]]   # a list-valued key takes a list of lists
    zip:
      model.params.connectivity: [0.02, 0.01]
      model.params.input_connectivity: [0.2, 0.1]

Seeds (:func:`point_seed`): a grid that sweeps ``seed`` uses its values as given; otherwise every
point gets its own seed, derived with ``numpy.random.SeedSequence`` from the spec's seed and the
point's swept values, so a configuration keeps its seed when the grid around it changes. The seed
used is written into each point's spec, which ``dynmodel fit`` reproduces bit for bit.

Every key and value is validated against the spec before anything runs, and so is every point.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import SpecError
from ..spec import read_yaml, validate_spec

GENERATORS = ("range", "linspace", "geomspace")


@dataclass
class Axis:
    """One factor of the product: a key, or several keys paired by ``zip``; ``levels[i]`` holds one
    value per key."""

    keys: list[str]
    levels: list[tuple[Any, ...]]


@dataclass
class Grid:
    axes: list[Axis]
    source: str

    @property
    def keys(self) -> list[str]:
        return [k for axis in self.axes for k in axis.keys]

    @property
    def sweeps_seed(self) -> bool:
        return "seed" in self.keys

    def __len__(self) -> int:
        n = 1
        for axis in self.axes:
            n *= len(axis.levels)
        return n

    def combinations(self) -> list[dict[str, Any]]:
        """Every point's swept values, in order (the last axis varies fastest)."""
        out = []
        for levels in itertools.product(*(axis.levels for axis in self.axes)):
            values: dict[str, Any] = {}
            for axis, level in zip(self.axes, levels):
                values.update(zip(axis.keys, level))
            out.append(values)
        return out

    def to_json(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "axes": [{"keys": a.keys, "levels": [list(v) for v in a.levels]} for a in self.axes],
        }


@dataclass
class Point:
    """One point of a sweep: its key (``p0007``), swept values, the seed its spec uses, and the
    complete resolved spec mapping it runs (absolute paths, every default written out)."""

    key: str
    values: dict[str, Any]
    seed: int
    raw: dict[str, Any]

    def label(self, short: dict[str, str] | None = None) -> str:
        return ", ".join(f"{(short or {}).get(k, k)}={shown(v)}" for k, v in self.values.items())


def shown(value: Any, width: int = 40) -> str:
    """A value as a short text (JSON for lists and mappings)."""
    text = value if isinstance(value, str) else json.dumps(value, separators=(", ", ": "))
    return text if len(text) <= width else text[: width - 3] + "..."


def short_names(keys: list[str]) -> dict[str, str]:
    """The last part of each dotted key where that is unambiguous, else the whole key."""
    last = [k.rsplit(".", 1)[-1] for k in keys]
    return {k: (s if last.count(s) == 1 else k) for k, s in zip(keys, last)}


# ---------------------------------------------------------------- parsing


def load_grid(path: str | Path) -> Grid:
    p = Path(path)
    if not p.is_file():
        raise SpecError(
            "grid file not found" if not p.exists() else "is a folder, not a grid file", str(p), "check the path"
        )
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(f"cannot read the grid ({exc})", str(p), "check the file") from None
    return parse_grid(read_yaml(text, str(p)), str(p))


def parse_grid(raw: Any, source: str = "<grid>") -> Grid:
    """Axes of a grid mapping (see the module docstring); SpecError on the first problem."""
    example = "model.params.size: [100, 200]"
    if raw is None:
        raise SpecError("the grid is empty", source, f"list at least one key and its values, e.g. {example}")
    if not isinstance(raw, dict):
        raise SpecError(
            f"the grid must be a mapping of dotted spec keys to lists of values, not a {type(raw).__name__}",
            source,
            f"write e.g. {example}",
        )
    axes: list[Axis] = []
    seen: set[str] = set()

    def claim(key: str) -> None:
        if key in seen:
            raise SpecError(f"'{key}' is swept twice", f"{source}: {key}", "keep it in one place (plain or zip)")
        # a key inside another swept key (model.params.size and model.params): one would override the other,
        # and the results table would show a value the point never used
        nested = next((k for k in seen if key.startswith(k + ".") or k.startswith(key + ".")), None)
        if nested is not None:
            raise SpecError(
                f"'{key}' and '{nested}' overlap: one holds the other, so a point would not use the value its "
                "row shows",
                f"{source}: {key}",
                "sweep the inner key alone, or the outer one alone",
            )
        seen.add(key)

    for key, value in raw.items():
        key = str(key)
        if key == "zip":
            blocks = value if isinstance(value, list) else [value]
            for i, block in enumerate(blocks):
                where = f"{source}: zip" + (f"[{i}]" if isinstance(value, list) else "")
                if not isinstance(block, dict) or not block:
                    raise SpecError(
                        "a zip block maps dotted keys to lists of one length",
                        where,
                        "write zip: {model.params.size: [100, 200], model.params.connectivity: [0.02, 0.01]}",
                    )
                keys = [str(k) for k in block]
                lists = [expand(k, block[k], f"{where}.{k}") for k in keys]
                lengths = {len(v) for v in lists}
                if len(lengths) > 1:
                    sizes = ", ".join(f"{k}: {len(v)}" for k, v in zip(keys, lists))
                    raise SpecError(
                        f"the lists of a zip block differ in length ({sizes})", where, "give every key as many values"
                    )
                for k in keys:
                    _check_key(k, f"{where}.{k}")
                    claim(k)
                axes.append(Axis(keys, list(zip(*lists))))
            continue
        _check_key(key, f"{source}: {key}")
        claim(key)
        axes.append(Axis([key], [(v,) for v in expand(key, value, f"{source}: {key}")]))
    if not axes:
        raise SpecError("the grid sweeps no key", source, f"list at least one key and its values, e.g. {example}")
    return Grid(axes, source)


def _check_key(key: str, where: str) -> None:
    parts = key.split(".")
    if not key or any(not p.strip() for p in parts):
        raise SpecError(f"'{key}' is not a dotted spec key", where, "write keys like model.params.size")


def _number(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ValueError
    return v


def expand(key: str, value: Any, where: str) -> list[Any]:
    """The list of values a grid entry stands for."""
    if isinstance(value, list):
        if not value:
            raise SpecError("the list of values is empty", where, f"give at least one value, e.g. {key}: [VALUE]")
        return list(value)
    if isinstance(value, dict) and len(value) == 1 and next(iter(value)) in GENERATORS:
        kind, args = next(iter(value.items()))
        try:
            if not isinstance(args, list):
                raise ValueError
            if kind == "range":
                if not 1 <= len(args) <= 3 or any(isinstance(a, bool) or not isinstance(a, int) for a in args):
                    raise ValueError
                values: list[Any] = list(range(*args))
            else:
                import numpy as np

                a, b, n = (_number(args[0]), _number(args[1]), args[2]) if len(args) == 3 else (None, None, None)
                if a is None or b is None or isinstance(n, bool) or not isinstance(n, int) or n < 1:
                    raise ValueError
                if kind == "geomspace" and (a <= 0 or b <= 0):
                    raise ValueError
                gen = np.linspace if kind == "linspace" else np.geomspace
                values = [float(f"{x:.12g}") for x in gen(a, b, n)]
        except ValueError:
            forms = {
                "range": "{range: [STOP]}, {range: [START, STOP]} or {range: [START, STOP, STEP]} with integers",
                "linspace": "{linspace: [FIRST, LAST, COUNT]}",
                "geomspace": "{geomspace: [FIRST, LAST, COUNT]} with positive ends",
            }
            raise SpecError(f"malformed {kind} ({shown(args)})", where, f"write {forms[kind]}") from None
        if not values:
            raise SpecError(f"{kind} {shown(args)} gives no values", where, "check start, stop and step")
        return values
    if isinstance(value, dict):
        raise SpecError(
            "a grid key takes a list of values (or {range: ...}, {linspace: ...}, {geomspace: ...}), not a mapping",
            where,
            f"write dotted keys with a list each, e.g. {key}.KEY: [A, B], or {key}: [{{...}}, {{...}}] for mappings",
        )
    raise SpecError(
        f"a grid key takes a list of values, got the single value {shown(value)}",
        where,
        f"write {key}: [{shown(value)}] (a list-valued key takes a list of lists)",
    )


# ---------------------------------------------------------------- points


def set_dotted(raw: dict[str, Any], key: str, value: Any, where: str) -> None:
    """Set ``raw[a][b][c] = value`` for key ``a.b.c``, creating sections that are missing."""
    parts = key.split(".")
    node = raw
    for i, part in enumerate(parts[:-1]):
        nxt = node.get(part)
        if nxt is None:
            nxt = node[part] = {}
        elif not isinstance(nxt, dict):
            held = ".".join(parts[: i + 1])
            raise SpecError(
                f"'{held}' holds a value ({shown(nxt)}) in the spec, not a section with keys",
                where,
                f"sweep '{held}' itself, or a key that exists under it (see `dynmodel schema`)",
            )
        node = nxt
    node[parts[-1]] = copy.deepcopy(value)


def point_seed(base_seed: int, values: dict[str, Any]) -> int:
    """The seed of a point when the grid does not sweep ``seed``: the first 32-bit word of
    ``SeedSequence([base_seed, *sha256(values)])``, ``values`` being the point's swept values as
    canonical JSON (so the seed follows the configuration, not its position in the grid; a whole number
    counts the same written 1 or 1.0)."""
    import numpy as np

    text = json.dumps(_canonical(values), sort_keys=True, separators=(",", ":"), default=str)
    digest = hashlib.sha256(text.encode()).digest()
    words = [int.from_bytes(digest[i : i + 4], "little") for i in range(0, 16, 4)]
    return int(np.random.SeedSequence([int(base_seed), *words]).generate_state(1, np.uint32)[0])


def _canonical(value: Any) -> Any:
    """``value`` with whole floats as ints (1.0 -> 1), inside lists and mappings too."""
    if isinstance(value, float) and value.is_integer():
        return int(value)
    if isinstance(value, dict):
        return {k: _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    return value


def _validate(raw: dict[str, Any], source: str, base_dir: Path, key_values: dict[str, Any]):
    """validate_spec, with a hint when a list-valued key was given bare values."""
    try:
        return validate_spec(raw, source, base_dir)
    except SpecError as err:
        for key, value in key_values.items():
            if isinstance(value, list):
                continue
            trial = copy.deepcopy(raw)
            set_dotted(trial, key, [value], source)
            try:
                validate_spec(trial, source, base_dir)
            except SpecError:
                continue
            raise SpecError(
                err.what,
                err.where,
                f"'{key}' takes a list: write its grid values as a list of lists, e.g. {key}: [[{shown(value)}]]",
            ) from None
        raise


def build_points(base_raw: dict[str, Any], base_dir: Path, grid: Grid, name: str | None = None) -> list[Point]:
    """Validate every key, value and combination of ``grid`` against the spec ``base_raw`` and return
    the points (SpecError, one line, on the first problem; nothing runs before this succeeds)."""
    base = copy.deepcopy(base_raw)
    base.pop("output", None)  # a sweep never writes the spec's own model file
    base_spec = validate_spec(base, grid.source, base_dir)
    base_seed = int(base_spec.seed)
    name = name or base_spec.name
    combos = grid.combinations()
    width = max(4, len(str(len(combos) - 1)))
    points = []
    for i, values in enumerate(combos):
        key = f"p{i:0{width}d}"
        raw = copy.deepcopy(base)
        where = f"{grid.source}: point {key} (" + ", ".join(f"{k}={shown(v)}" for k, v in values.items()) + ")"
        for k, v in values.items():
            set_dotted(raw, k, v, where)
        if not grid.sweeps_seed:
            raw["seed"] = point_seed(base_seed, values)
        raw["name"] = f"{name}-{key}"
        try:
            spec = _validate(raw, where, base_dir, values)
        except SpecError:
            _blame_one_value(base, base_dir, grid.source, values)
            raise
        resolved = spec.resolved()
        resolved.pop("output", None)
        points.append(Point(key, values, int(spec.seed), resolved))
    return points


def _blame_one_value(base: dict[str, Any], base_dir: Path, source: str, values: dict[str, Any]) -> None:
    """Raise the error of the first swept value that is invalid on its own (the error then names
    that grid entry, e.g. a misspelt key); return when only the combination is invalid."""
    for key, value in values.items():
        raw = copy.deepcopy(base)
        where = f"{source}: {key}={shown(value)}"
        set_dotted(raw, key, value, where)
        _validate(raw, where, base_dir, {key: value})


def identity(points: list[Point]) -> str:
    """SHA-256 of what the points compute (their specs without name and output): two sweeps with one
    identity give the same results."""
    h = hashlib.sha256()
    for p in points:
        body = {k: v for k, v in p.raw.items() if k not in ("name", "output")}
        h.update(json.dumps([p.key, body], sort_keys=True, default=str).encode())
    return h.hexdigest()
