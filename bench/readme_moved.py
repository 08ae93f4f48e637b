"""Nothing of the old README lost (issue 45 item 1): every non-blank line of the README as it
was at REV appears in a page under docs/ or in today's README.

    python bench/readme_moved.py [REV]      # REV: default 7ae678e, the last 1,075-line README

Lines are compared after stripping surrounding blanks and heading markers (``## The logic`` and
``# The logic`` are the same line) and rewriting links into docs/ the way the pages write them
(``](docs/x.md`` is ``](x.md``). The few lines changed on purpose are listed in ``REWORDED``,
each with the text that replaced it, which must be there instead. Exit status 1 if a line is
missing.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_REV = "7ae678e"

# An old line changed on purpose -> the text now in its place (checked like any other line).
REWORDED = dict(
    [
        # make test now also builds the site, and installs every extra.
        (
            ("make test   # set up .venv and run the whole test suite, ruff and mypy"),
            (
                "make test   # set up .venv and run the whole test suite, ruff, "
                "mypy and the documentation site's build"
            ),
        ),
        (
            (
                "Stable-Baselines3 and sweep extras (torch 2.13.0, CPU build; Ray "
                "Tune and rliable). `.ci/run` is `make test`. `bench/fresh_clone.sh"
            ),
            (
                "Stable-Baselines3, sweep, env-package, team and documentation "
                "extras (torch 2.13.0, CPU build; Ray Tune and rliable; MiniGrid, "
                "highway-env, gymnasium-robotics; PettingZoo; Sphinx, furo, MyST). "
                "`.ci/run` is `make test`. `bench/fresh_clone.sh"
            ),
        ),
        # "this README" and "the next section" no longer read right on the pages they moved to.
        (
            (
                "The pages under `docs/` go deeper than this README: "
                "[episodes](docs/episodes.md) (what an"
            ),
            "The deeper pages of this site: [episodes](episodes.md) (what an",
        ),
        (
            (
                "`mitlc/Product-v0`, passes `check_env`): the task wrapper of the "
                "next section around the grid"
            ),
            (
                "`mitlc/Product-v0`, passes `check_env`): the task wrapper "
                "([gymnasium.md](gymnasium.md)) around the grid"
            ),
        ),
        # A page that links to itself: teams.md, sweeps.md, limits.md.
        (
            (
                "success after 300,000 agent-steps). "
                "[docs/teams.md](docs/teams.md) has the file format, the"
            ),
            ("success after 300,000 agent-steps). The sections below have the file format, the"),
        ),
        (
            (
                "`specs/sweeps/case1-learners.yaml` is an example. "
                "[docs/sweeps.md](docs/sweeps.md) has the"
            ),
            ("`specs/sweeps/case1-learners.yaml` is an example. The sections below have the"),
        ),
        (
            (
                "[docs/limits.md](docs/limits.md) says how the memory limit is "
                "enforced, and lists the caps on"
            ),
            ("The sections below say how the memory limit is enforced, and list the caps on"),
        ),
        (
            (
                "comes first, in one line (measured through every command in "
                "[docs/limits.md](docs/limits.md))."
            ),
            (
                "comes first, in one line (measured through every command in [the "
                "sections below](#time-and-memory))."
            ),
        ),
        # Headings whose section became (part of) a page with its own title.
        (
            "## Worlds and exact checking",
            "# Worlds",
        ),
        (
            "## Teams of robots (`pip install 'mitlc[teams]'`)",
            "# Teams of robots",
        ),
        (
            "## Limits",
            "# Limits: time, memory, files and settings",
        ),
    ]
)

_HEADING = re.compile(r"^#+\s+")


def normal(line: str) -> str:
    """A line as compared: no surrounding blanks, no heading marker, and links into docs/
    written as the pages write them."""
    line = _HEADING.sub("", line.strip())
    return line.replace("](docs/", "](")


def lines_now() -> set[str]:
    """Every normalised line of the pages under docs/ and of today's README."""
    files = [ROOT / "README.md"]
    files += [p for p in (ROOT / "docs").rglob("*.md") if "_build" not in p.parts]
    found: set[str] = set()
    for path in files:
        found.update(normal(line) for line in path.read_text(encoding="utf-8").split("\n"))
    return found


def main(rev: str = DEFAULT_REV) -> int:
    old = subprocess.run(
        ["git", "show", f"{rev}:README.md"], cwd=ROOT, check=True, capture_output=True, text=True
    ).stdout.split("\n")
    now = lines_now()
    checked = missing = reworded = 0
    for number, line in enumerate(old, 1):
        if not line.strip():
            continue
        checked += 1
        wanted = REWORDED.get(line, line)
        reworded += wanted != line
        if normal(wanted) not in now:
            missing += 1
            print(f"README.md@{rev}:{number}: not found: {line}")
    print(
        f"{checked} non-blank lines of README.md@{rev}: {checked - missing} found "
        f"({reworded} of them reworded on purpose, see REWORDED), {missing} missing"
    )
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
