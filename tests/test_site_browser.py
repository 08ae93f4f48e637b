"""The built site looked at in a browser (issue 45 item 4): every HTML page of
``docs/_build/html`` (``make docs`` builds it; ``make test`` builds it before pytest) opened in
headless Debian Chromium (``/usr/bin/chromium``; ``scripts/system-deps`` installs it), driven
over the DevTools protocol on a pipe (``tests/chromium.py``, the standard library alone).

Each page must render with furo's navigation (the sidebar, visible, with a link to every page of
the home page's toctrees), a heading, every ``<img>`` loaded (``naturalWidth > 0``), every link
into the site pointing at a page and anchor that exist, and no console errors, uncaught
exceptions or failed loads; the search page finds pages. The site is served by Python's HTTP
server on 127.0.0.1, as a host serves it. Screenshots of the home page (its first screen) and
one guide page (whole, its figures too) are saved to ``docs/_build/screenshots/`` (git-ignored)
to be looked at.
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Iterator
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

from tests.chromium import CHROMIUM, Chromium
from tests.test_docs_build import toctree_entries

ROOT = Path(__file__).resolve().parents[1]
HTML = ROOT / "docs" / "_build" / "html"
SCREENSHOTS = ROOT / "docs" / "_build" / "screenshots"
GUIDE = "getting-started"
"""The guide page whose screenshot is saved (else the home page's first toctree entry)."""

pytestmark = [
    pytest.mark.skipif(
        not (HTML / "index.html").is_file(),
        reason="no built site at docs/_build/html (make docs builds it; make test does first)",
    ),
    pytest.mark.skipif(
        not CHROMIUM.is_file(),
        reason=f"no {CHROMIUM} (Debian's chromium package; scripts/system-deps installs it)",
    ),
]

PAGE_STATE = """
(async () => {
  // images that are not loaded yet (lazy ones too) get a second to load
  const images = [...document.images];
  for (const image of images) image.loading = "eager";
  await Promise.all(images.filter((i) => !i.complete).map((i) => new Promise((done) => {
    i.addEventListener("load", done); i.addEventListener("error", done);
    setTimeout(done, 1000);
  })));
  const tree = document.querySelector(".sidebar-drawer .sidebar-tree");
  const box = (e) => { const r = e ? e.getBoundingClientRect() : null;
                       return r ? [r.width, r.height] : [0, 0]; };
  return {
    title: document.title,
    sidebar: box(tree),
    navigation: tree ? [...tree.querySelectorAll("a.reference")].map((a) => a.href) : [],
    main: box(document.querySelector("article[role=main]")),
    heading: (document.querySelector("article h1") || {}).textContent || "",
    images: images.map((i) => [i.getAttribute("src"), i.complete, i.naturalWidth]),
    links: [...document.querySelectorAll("a[href]")].map((a) => a.href)
             .filter((h) => h.startsWith(location.origin + "/")),
    ids: [...document.querySelectorAll("[id]")].map((e) => e.id),
  };
})()
"""


def _pages() -> list[Path]:
    """Every HTML page of the built site (not the sources' copies or the theme's files)."""
    return sorted(
        path
        for path in HTML.rglob("*.html")
        if path.relative_to(HTML).parts[0] not in ("_sources", "_static", "_images")
    )


def _navigation() -> set[str]:
    """The pages that every page's sidebar must link to: the home page's toctree entries."""
    return {f"{entry}.html" for entry in toctree_entries("index")}


def _guide() -> str:
    entries = toctree_entries("index")
    return GUIDE if GUIDE in entries else entries[0]


class _Quiet(SimpleHTTPRequestHandler):
    """Python's file server, silent; ``/favicon.ico``, which the browser asks every host for
    (the site declares no icon), is answered with no content rather than a 404."""

    def log_message(self, format: str, *args: object) -> None:
        pass

    def do_GET(self) -> None:
        if self.path == "/favicon.ico" and not (HTML / "favicon.ico").exists():
            self.send_response(204)
            self.end_headers()
            return
        super().do_GET()


@pytest.fixture(scope="module")
def site() -> Iterator[str]:
    """The built site served on 127.0.0.1 (a free port) by Python's HTTP server, as a host
    serves it (the search page fetches pages, which ``file:`` URLs forbid); its base URL."""
    handler = functools.partial(_Quiet, directory=str(HTML))
    server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join()


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Chromium]:
    with Chromium(tmp_path_factory.mktemp("chromium-profile"), timeout=30.0) as chromium:
        yield chromium


def test_every_page_renders_with_navigation_images_and_no_errors(
    browser: Chromium, site: str
) -> None:
    pages = _pages()
    assert len(pages) > 10, pages
    navigation = _navigation()
    problems: list[str] = []
    ids: dict[str, set[str]] = {}
    links: dict[str, set[str]] = {}
    started = time.monotonic()
    for page in pages:
        name = page.relative_to(HTML).as_posix()
        browser.open(f"{site}/{name}")
        state = browser.evaluate(PAGE_STATE)
        ids[name] = set(state["ids"])
        links[name] = {url.removeprefix(site + "/") for url in state["links"]}
        width, height = state["sidebar"]
        if width <= 0 or height <= 0:
            problems.append(f"{name}: the sidebar's navigation is not shown")
        shown = {_page_of(url.removeprefix(site + "/"), name) for url in state["navigation"]}
        if navigation - shown:
            problems.append(f"{name}: the sidebar lacks {sorted(navigation - shown)}")
        if name != "search.html":  # furo's shows a form, its results below (tested apart)
            if min(state["main"]) <= 0:
                problems.append(f"{name}: no main content")
            if not state["heading"].strip():
                problems.append(f"{name}: no heading")
        for src, complete, natural_width in state["images"]:
            if not complete or natural_width <= 0:
                problems.append(f"{name}: image {src} not loaded")
        problems += [f"{name}: {error}" for error in browser.errors()]
    for name, targets in sorted(links.items()):
        for target in sorted(targets):
            parts = urlsplit(target)
            path = unquote(parts.path) or name
            if path.endswith("/"):
                path += "index.html"
            if not (HTML / path).is_file():
                problems.append(f"{name}: a link to a missing file {target}")
            elif parts.fragment and path in ids and unquote(parts.fragment) not in ids[path]:
                problems.append(f"{name}: a link to a missing anchor {target}")
    seconds = time.monotonic() - started
    assert not problems, "\n".join(problems)
    assert seconds < 60, f"{len(pages)} pages in {seconds:.0f} s"


def _page_of(link: str, page: str) -> str:
    """The page a link of ``page`` leads to (its anchor off; ``#x`` alone: ``page``)."""
    path = unquote(urlsplit(link).path)
    return path or page


def test_screenshots_of_the_home_page_and_a_guide(browser: Chromium, site: str) -> None:
    for page, shot, full_page in (("index", "home.png", False), (_guide(), "guide.png", True)):
        browser.open(f"{site}/{page}.html")
        browser.evaluate(PAGE_STATE)
        path = SCREENSHOTS / shot
        browser.screenshot(path, full_page=full_page)
        data = path.read_bytes()
        assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 10_000, path
        assert browser.errors() == []


SEARCH_RESULTS = """
new Promise((done) => {
  const started = Date.now();
  const poll = () => {
    const found = document.querySelectorAll("#search-results ul.search li").length;
    if (found > 0 || Date.now() - started > 10000) done(found); else setTimeout(poll, 100);
  };
  poll();
})
"""


def test_search_finds_pages(browser: Chromium, site: str) -> None:
    browser.open(f"{site}/search.html?q=automaton")
    assert browser.evaluate(SEARCH_RESULTS) > 0, "no results for 'automaton'"
    assert browser.errors() == []
