"""``dynmodel diagnose`` as a library function: a spec file diagnosed, its report folder written."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..diagnose import Diagnosis, Settings
from ..family import Progress, no_progress


@dataclass
class DiagnoseResult:
    """The diagnosis and the files written: the report's index, the extended spec (None when nothing
    was extended) and the JSON summary."""

    diagnosis: Diagnosis
    folder: Path
    index: Path
    extended: Path | None
    json_path: Path | None


def diagnose_spec_file(
    spec: str | Path,
    report: str | Path | None = None,
    json_path: str | Path | None = None,
    settings: Settings | None = None,
    force: bool = False,
    progress: Progress = no_progress,
) -> DiagnoseResult:
    """``dynmodel diagnose``: what the model's free run gets wrong, the cause named, the model extended and
    the gain measured on the held-out test split; the report folder (default ``<name>-diagnosis`` next to the
    spec) and ``json_path`` are checked before any work."""
    from ..diagnose import diagnose
    from ..diagnose.report import write_json, write_report_folder
    from ..paths import check_outputs, safe_name, spec_inputs
    from ..spec import load_spec, parse_yaml, read_spec_text

    spec_file = Path(spec)
    json_file = Path(json_path) if json_path is not None else None
    s = load_spec(spec_file)  # one-line errors for a bad spec before any work
    folder = Path(report) if report is not None else spec_file.resolve().parent / f"{safe_name(s.name)}-diagnosis"
    check_outputs([(folder, "report", "--report"), (json_file, "json", "--json")], spec_inputs(s, spec_file), force)
    raw = parse_yaml(read_spec_text(spec_file), str(spec_file))
    raw.setdefault("name", spec_file.stem)
    result = diagnose(raw, str(spec_file), spec_file.resolve().parent, settings or Settings(), progress)
    progress("report", None, str(folder))
    index, extended = write_report_folder(result, folder)  # a temporary sibling renamed into place at the end
    if json_file is not None:
        write_json(result, json_file)
    return DiagnoseResult(result, folder, index, extended, json_file)
