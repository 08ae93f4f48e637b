"""The README is a front door (issue 45): short, and every relative link in it leads somewhere.

A few milliseconds: it reads README.md and looks at the files it names.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAX_LINES = 300

# [text](target) and ![alt](target), with an optional "title"; and reference definitions
# [label]: target. Code spans and fenced blocks are left out first.
_INLINE = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_DEFINITION = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$", re.M)
_FENCE = re.compile(r"^(`{3,}|~{3,}).*?^\1\s*$", re.S | re.M)
_CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1", re.S)
_EXTERNAL = re.compile(r"^(?:[a-z][a-z0-9+.-]*:|//|#)", re.I)


def relative_links(text: str) -> list[str]:
    """The targets of the relative links of a Markdown text (no URLs, no in-page anchors)."""
    text = _CODE_SPAN.sub("", _FENCE.sub("", text))
    targets = _INLINE.findall(text) + _DEFINITION.findall(text)
    return [target for target in targets if not _EXTERNAL.match(target)]


def test_readme_is_at_most_300_lines() -> None:
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= MAX_LINES, f"README.md has {len(lines)} lines, at most {MAX_LINES}"


def test_every_relative_link_of_the_readme_exists() -> None:
    links = relative_links(README.read_text(encoding="utf-8"))
    assert links, "README.md links to no page"
    missing = []
    for link in links:
        path = link.split("#", 1)[0].split("?", 1)[0]
        if path and not (ROOT / path).exists():
            missing.append(link)
    assert not missing, f"README.md links to files that do not exist: {missing}"


def test_links_are_found() -> None:
    """The link finder itself: inline links, images, definitions; not URLs, anchors or code."""
    text = (
        'See [a](docs/a.md), ![b](docs/figures/b.png "title") and [c](docs/c.md#part).\n'
        "[d]: docs/d.md\n"
        "Not [e](https://example.org), [f](#here), `[g](docs/g.md)`.\n"
        "```md\n[h](docs/h.md)\n```\n"
    )
    assert relative_links(text) == [
        "docs/a.md",
        "docs/figures/b.png",
        "docs/c.md#part",
        "docs/d.md",
    ]
