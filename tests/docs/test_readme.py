"""The README stands on its own (issue 16, finding 9): a user who clones the project has only
the repository, so every file the README names or shows is in it, and it names nothing beside it.
The same holds for the pages under ``docs/`` that the README links (issue 37: the README leads with
a first session; the papers' tables and the long reference moved to those pages), and every
``teleprog`` command the README or a page shows is one the command line accepts."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")
PAGES = {path: path.read_text(encoding="utf-8") for path in sorted((ROOT / "docs").glob("*.md"))}

# a repository path in backticks or a markdown link: has a slash, starts with a top-level folder
PATH = re.compile(r"`((?:\.\./|\./)?[A-Za-z_.][\w.-]*/[\w./*-]*)`|\]\(([^)#\s]+)\)")
LINK = re.compile(r"\]\(([^)#\s]+)\)")


def _skipped(path: str) -> bool:
    """URLs and API routes, the environment the commands create, elisions."""
    return path.startswith(("/", "http://", "https://", "ws://", ".venv/")) or "..." in path


def named_paths(text: str = README) -> list[str]:
    found = []
    for code, link in PATH.findall(text):
        path = code or link
        if not _skipped(path):
            found.append(path)
    return found


def _in_repository(path: str) -> bool:
    # a table row names sub-folders relative to its folder (`robots/` of `shared/`)
    return any(ROOT.glob(path.rstrip("/"))) or any(ROOT.glob("*/" + path.rstrip("/")))


def test_the_readme_opens_with_its_title_and_the_two_commands():
    lines = README.splitlines()
    assert lines[0].startswith("# teleprog")
    block = README[README.index("```bash"):README.index("```", README.index("```bash") + 3)]
    assert README.index("```bash") < README.index("\n## ")
    assert [line.split()[0] for line in block.splitlines()[1:] if line.strip()] == ["scripts/up", "scripts/test"]


def test_the_readme_names_nothing_outside_the_repository():
    outside = [p for p in named_paths() if p.startswith("../")] + re.findall(r"\.\./shared/\S*", README)
    assert outside == []


def test_every_file_the_readme_names_is_in_the_repository():
    paths = named_paths()
    assert "docs/console.png" in paths and "assets/programs/peg_transfer.tp" in paths
    missing = [p for p in paths if not _in_repository(p)]
    assert missing == []


@pytest.mark.parametrize("page", list(PAGES), ids=lambda p: p.name)
def test_every_file_a_docs_page_names_is_in_the_repository(page: Path):
    """Paths in backticks count from the repository's root (as in the README); links and images
    from the page's own folder, as a reader's browser follows them, and never lead out of it."""
    text = PAGES[page]
    links = {link for link in LINK.findall(text) if not _skipped(link)}
    missing = [p for p in named_paths(text) if p not in links and not _in_repository(p)]
    broken = []
    for link in links:
        target = (page.parent / link).resolve()
        if not target.is_relative_to(ROOT) or not target.exists():
            broken.append(link)
    assert missing == [] and broken == []


def test_the_readme_links_every_docs_page():
    """What moved out of the README is one click away: each page under docs/ is linked from it."""
    linked = {(ROOT / link).resolve() for link in LINK.findall(README)}
    assert PAGES and [p.name for p in PAGES if p.resolve() not in linked] == []


def test_the_readme_leads_with_a_first_session_with_pictures_of_it():
    first, what = README.index("## First session"), README.index("## What it is")
    assert README.index("\n## ") == first - 1 and first < what  # the first section after the commands
    session = README[first:what]
    for words in ("scripts/up", "Drive tab", "gizmo", "slider", "View", "Program tab", "Preview tab",
                  "Submit tab", "ONLINE", "OFFLINE", "SINGLE STEP", "newest first", "ghost", "STOP",
                  "Resume", "Skip", "Abort"):
        assert words in session, words
    pictures = re.findall(r"\]\((docs/session-[\w-]+\.png)\)", session)
    assert len(pictures) >= 3 and all((ROOT / p).is_file() for p in pictures)


def test_the_readme_says_what_the_product_does_before_the_reference():
    what = README.index("## What it is")
    assert what < README.index("## The command line")
    section = README[what:README.index("## The command line")]
    for words in ("teleprogramming", "virtual arm", "preview", "telerobot", "STOP"):
        assert words.lower() in section.lower(), words


def _shown_commands() -> list[tuple[str, str]]:
    """(where, command line) for every ``.venv/bin/teleprog ...`` line of a bash block."""
    shown = []
    for name, text in [("README.md", README)] + [(f"docs/{p.name}", t) for p, t in PAGES.items()]:
        for block in re.findall(r"```bash\n(.*?)```", text, re.S):
            for line in block.splitlines():
                line = line.split("  #")[0].strip()
                if line.startswith(".venv/bin/teleprog "):
                    shown.append((name, line))
    return shown


def test_every_command_shown_is_one_the_command_line_accepts():
    from server.cli import build_parser

    parser = build_parser()
    shown = _shown_commands()
    assert len(shown) > 20
    refused = []
    for where, line in shown:
        try:
            parser.parse_args(shlex.split(line)[1:])
        except SystemExit:
            refused.append(f"{where}: {line}")
    assert refused == []


def test_every_subcommand_named_in_the_text_exists():
    from server.cli import build_parser

    choices = next(a for a in build_parser()._actions if a.dest == "command").choices
    named = {m for text in [README, *PAGES.values()] for m in re.findall(r"`teleprog ([a-z]+)", text)}
    assert named and sorted(named - set(choices)) == []
