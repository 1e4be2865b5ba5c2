"""The command blocks of README.md and docs/*.md run as written, or say why they do not.

Every fenced ```` ```bash ```` block is one of two kinds:

* **runnable** (the default): this test runs it, as written, with ``bash -euo pipefail``
  from a view of the checkout in a temporary folder (links to the repo's files, and
  ``.venv`` to the running venv), with ``HOME`` a temporary folder too, so nothing it
  writes lands in the repo or the user's home; it must exit 0. Only cheap commands
  (seconds) may stay unmarked.
* **illustrative**: the line before the block (blank lines aside) is
  ``<!-- illustrative: REASON -->`` with a reason (minutes of compute, a download, a
  planner built elsewhere, a cluster...). Its ``evaluate.py`` and ``train.py`` commands
  are still checked: each one's arguments must parse (argparse, and the ``--config`` /
  ``--tune`` files must exist), so a renamed option or a moved config fails here. A
  line with a ``...`` placeholder is left out of that check.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
BLOCK = re.compile(r"(?ms)^```bash\n(.*?)^```")
MARKER = re.compile(r"<!--\s*illustrative:\s*(.*?)\s*-->")
PLANNER_CHECKOUT = "CarND-Path-Planning-Project"
VIEW_SKIPS = {".git", ".venv", "results", "runs", ".pytest_cache", ".ruff_cache"}


@dataclass(frozen=True)
class Block:
    page: Path
    line: int
    text: str
    reason: str | None  # None: runnable

    @property
    def name(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def blocks() -> list[Block]:
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for match in BLOCK.finditer(text):
            before = text[:match.start()].rstrip().rsplit("\n", 1)[-1]
            marker = MARKER.fullmatch(before.strip())
            found.append(Block(page, text.count("\n", 0, match.start()) + 1, match.group(1),
                               marker.group(1) if marker else None))
    return found


BLOCKS = blocks()
RUNNABLE = [block for block in BLOCKS if block.reason is None]
ILLUSTRATIVE = [block for block in BLOCKS if block.reason is not None]


def test_blocks_are_found_and_every_illustrative_one_says_why():
    assert len(BLOCKS) >= 15 and RUNNABLE and ILLUSTRATIVE
    for block in ILLUSTRATIVE:
        assert len(block.reason.split()) >= 3, f"{block.name}: say why it is not run"
    for page in PAGES:  # a marker that does not stand before a bash block is a typo
        text = page.read_text(encoding="utf-8")
        markers = len(MARKER.findall(text))
        assert markers == sum(1 for b in ILLUSTRATIVE if b.page == page), page


@pytest.fixture(scope="module")
def view(tmp_path_factory) -> Path:
    """The checkout seen from a temporary folder: a link per top-level entry, ``.venv`` to
    the running venv, ``../shared`` to the data beside the checkout."""
    base = tmp_path_factory.mktemp("docs")
    checkout = base / "checkout"
    checkout.mkdir()
    for entry in ROOT.iterdir():
        if entry.name not in VIEW_SKIPS:
            (checkout / entry.name).symlink_to(entry)
    (checkout / ".venv").symlink_to(Path(sys.prefix))
    if (ROOT.parent / "shared").exists():
        (base / "shared").symlink_to(ROOT.parent / "shared")
    # The user's planner checkout the external planner commands name, built (an empty
    # stand-in: the commands are parsed, not run).
    (base / "home" / PLANNER_CHECKOUT / "build").mkdir(parents=True)
    return checkout


@pytest.mark.parametrize("block", RUNNABLE, ids=lambda block: block.name)
def test_a_runnable_block_runs_as_written(block, view):
    environment = {**{k: v for k, v in os.environ.items() if k != "PYTHONPATH"},
                   "HOME": str(view.parent / "home")}
    result = subprocess.run(["bash", "-euo", "pipefail", "-c", block.text], cwd=view,
                            env=environment, text=True, capture_output=True, check=False)
    assert result.returncode == 0, f"{block.name}:\n{result.stdout}\n{result.stderr}"


SEQ = re.compile(r"\$\(seq (\d+) (\d+)\)")


def script_commands(block: Block) -> list[tuple[str, list[str]]]:
    """``(script, arguments)`` of each ``.venv/bin/python evaluate.py|train.py`` line."""
    commands = []
    for line in block.text.replace("\\\n", " ").splitlines():
        words = line.split("#", 1)[0].split()
        if words[:1] != [".venv/bin/python"] or len(words) < 2 or "..." in words:
            continue
        if words[1] not in ("evaluate.py", "train.py"):
            continue
        text = SEQ.sub(lambda m: " ".join(map(str, range(int(m[1]), int(m[2]) + 1))),
                       " ".join(words[2:]))
        commands.append((words[1], shlex.split(text)))
    return commands


ILLUSTRATIVE_COMMANDS = [(block, script, arguments) for block in ILLUSTRATIVE
                         for script, arguments in script_commands(block)]


def test_the_illustrative_blocks_hold_script_commands_to_check():
    assert len(ILLUSTRATIVE_COMMANDS) >= 30


@pytest.mark.parametrize(("block", "script", "arguments"), ILLUSTRATIVE_COMMANDS,
                         ids=[f"{b.name}:{' '.join(a)[:40]}" for b, _, a in
                              ILLUSTRATIVE_COMMANDS])
def test_an_illustrative_command_parses(block, script, arguments, view, monkeypatch):
    import evaluate
    import train

    monkeypatch.chdir(view)
    monkeypatch.setenv("HOME", str(view.parent / "home"))
    if script == "train.py":
        train.parse_args(arguments)
    elif arguments[:1] == ["compare"]:
        evaluate.parse_compare_args(arguments[1:])
    else:
        evaluate.parse_args(arguments)
