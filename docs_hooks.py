"""mkdocs hook (mkdocs.yml ``hooks:``): the site's home page is README.md and its changelog page
CHANGELOG.md, generated at build time so that each text lives in one file. Links are rewritten for
their place in the site: ``docs/x.md`` -> ``x.md``; a link to another file of the repository (specs,
examples, benchmarks), which the site does not hold, becomes its name in code."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

GENERATED = {"index.md": "README.md", "changelog.md": "CHANGELOG.md"}


def relink(text: str) -> str:
    """Links of a file at the repository root, as seen from the docs folder."""

    def fix(m: re.Match[str]) -> str:
        label, target = m.group(1), m.group(2)
        if target.startswith(("#", "http://", "https://", "mailto:")):
            return m.group(0)
        if target.startswith("docs/"):
            return f"[{label}]({target[len('docs/') :]})"
        return label if label.startswith("`") else f"`{label}`"  # a repository file: named, not linked

    return re.sub(r"\[([^\]]+)\]\(([^)\s]+)\)", fix, text)


def on_files(files: Files, config: Any) -> Files:
    root = Path(config.config_file_path).parent
    for page, source in GENERATED.items():
        files.append(File.generated(config, page, content=relink((root / source).read_text())))
    return files
