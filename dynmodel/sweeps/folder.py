"""A sweep's output folder: what is in it, checked before anything runs, written atomically.

Layout::

    DIR/sweep.json         the sweep: spec, grid, points (swept values, seed), identity hash
    DIR/specs/<point>.yaml each point's complete spec (dynmodel fit reproduces it bit for bit)
    DIR/points/<point>.json one result per finished point, written when it finishes (--resume reads them)
    DIR/models/<point>.h5  kept models (--keep best: the best point's; --keep all: every one)
    DIR/results.csv, DIR/results.json, DIR/sweep.png

Every file is written to a temporary name and renamed. A folder holding another sweep, or files
that are not a sweep's, is refused before any fit; nothing in it is overwritten.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from ..errors import SpecError
from ..paths import write_text

FORMAT = "dynmodel-sweep"
FORMAT_VERSION = 1
#: statuses a --resume does not run again (errors are retried: they may have been transient)
FINISHED = ("ok", "diverged")


class SweepFolder:
    def __init__(self, path: str | Path):
        self.path = Path(path).resolve()

    @property
    def manifest_path(self) -> Path:
        return self.path / "sweep.json"

    def point_path(self, key: str) -> Path:
        return self.path / "points" / f"{key}.json"

    def spec_path(self, key: str) -> Path:
        return self.path / "specs" / f"{key}.yaml"

    def model_path(self, key: str) -> Path:
        return self.path / "models" / f"{key}.h5"

    # -- before the run ------------------------------------------------------------------
    def check(
        self, identity: str, resume: bool, n_points: int, data: dict[str, str] | None = None
    ) -> dict[str, dict[str, Any]]:
        """Refuse a folder that is not this sweep's (or is, without ``resume``); return the records
        of the points a resume skips. Writes nothing."""
        where = str(self.path)
        if not self.path.exists():
            return {}
        if not self.path.is_dir():
            raise SpecError("the output folder is a file", where, "choose another --out")
        if not self.manifest_path.exists():
            if any(self.path.iterdir()):
                raise SpecError(
                    "the output folder exists, is not empty and holds no sweep (no sweep.json)",
                    where,
                    "choose another --out (nothing in it was touched)",
                )
            return {}
        manifest = self.read_manifest()
        if manifest.get("identity") != identity:
            raise SpecError(
                f"the output folder holds another sweep ({manifest.get('n_points', '?')} points of "
                f"{manifest.get('spec', '?')} with grid {manifest.get('grid', '?')}, created {manifest.get('created', '?')})",
                where,
                "choose another --out; nothing in it was touched",
            )
        changed = [f for f, sha in (manifest.get("data_sha256") or {}).items() if (data or {}).get(f) != sha]
        if changed and resume:  # finished points were scored on other data
            raise SpecError(
                f"the data file {changed[0]} changed since this sweep started: its finished points were scored on "
                "the data as it was",
                where,
                "rerun the sweep into a new --out (or restore the file)",
            )
        records = self.records()
        done = {k: r for k, r in records.items() if r.get("status") in FINISHED}
        if not resume:
            raise SpecError(
                f"the output folder already holds this sweep ({len(done)} of {n_points} points finished)",
                where,
                "add --resume to run only the missing points, or choose another --out",
            )
        return done

    def read_manifest(self) -> dict[str, Any]:
        try:
            manifest = json.loads(self.manifest_path.read_text(encoding="utf-8"))
            if manifest.get("format") != FORMAT:
                raise ValueError("not a dynmodel sweep")
        except (OSError, ValueError) as exc:
            raise SpecError(f"unreadable sweep.json ({exc})", str(self.manifest_path), "choose another --out") from None
        if int(manifest.get("format_version", 0)) > FORMAT_VERSION:
            raise SpecError(
                "the sweep was written by a newer dynmodel",
                str(self.manifest_path),
                "upgrade dynmodel or choose another --out",
            )
        return manifest

    def records(self) -> dict[str, dict[str, Any]]:
        """Every result file in the folder, by point key (unreadable ones are ignored: rerun)."""
        out: dict[str, dict[str, Any]] = {}
        folder = self.path / "points"
        if not folder.is_dir():
            return out
        for f in sorted(folder.glob("*.json")):
            try:
                record = json.loads(f.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                continue
            if isinstance(record, dict) and record.get("key") == f.stem:
                out[f.stem] = record
        return out

    # -- writing -------------------------------------------------------------------------
    def create(self, manifest: dict[str, Any], specs: dict[str, dict[str, Any]]) -> None:
        """Write sweep.json and each point's spec (first run; a resume keeps them)."""
        if self.manifest_path.exists():
            return
        for key, raw in specs.items():
            header = f"# point {key} of the sweep in {self.path} (run it alone: dynmodel fit {self.spec_path(key)})\n"
            write_text(self.spec_path(key), header + yaml.safe_dump(raw, sort_keys=False))
        body = {"format": FORMAT, "format_version": FORMAT_VERSION, **manifest}
        write_text(self.manifest_path, json.dumps(body, indent=1, default=str) + "\n")

    def write_record(self, record: dict[str, Any]) -> None:
        write_text(self.point_path(record["key"]), json.dumps(record, indent=1, default=str) + "\n")
