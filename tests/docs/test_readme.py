"""The README stands on its own (issue 16, finding 9): a user who clones the project has only
the repository, so every file the README names or shows is in it, and it names nothing beside it."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")

# a repository path in backticks or a markdown link: has a slash, starts with a top-level folder
PATH = re.compile(r"`((?:\.\./|\./)?[A-Za-z_.][\w.-]*/[\w./*-]*)`|\]\(([^)#\s]+)\)")


def named_paths() -> list[str]:
    found = []
    for code, link in PATH.findall(README):
        path = code or link
        if path.startswith(("/", "http://", "https://", "ws://", ".venv/")) or "..." in path:
            continue  # URLs and API routes, the environment the commands create, elisions
        found.append(path)
    return found


def test_the_readme_names_nothing_outside_the_repository():
    outside = [p for p in named_paths() if p.startswith("../")] + re.findall(r"\.\./shared/\S*", README)
    assert outside == []


def test_every_file_the_readme_names_is_in_the_repository():
    paths = named_paths()
    assert "docs/console.png" in paths and "assets/programs/peg_transfer.tp" in paths
    # a table row names sub-folders relative to its folder (`robots/` of `shared/`)
    missing = [p for p in paths if not any(ROOT.glob(p.rstrip("/"))) and not any(ROOT.glob("*/" + p.rstrip("/")))]
    assert missing == []


def test_the_readme_says_what_the_product_does_before_the_reference():
    what = README.index("## What it is")
    assert what < README.index("## The command line")
    section = README[what:README.index("## The command line")]
    for words in ("teleprogramming", "virtual arm", "preview", "telerobot", "STOP"):
        assert words.lower() in section.lower(), words
