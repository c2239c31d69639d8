"""The documentation site as a reader gets it: built by `scripts/docs.sh` (mkdocs --strict),
served over HTTP on localhost and opened in headless Chromium.

Checked: the landing page, the gallery index, an API page and the comparison results page
render in the browser; every ``<img>`` of their rendered DOM resolves to a file of the built
site; no relative link or source in any built HTML file points to a missing file. A screenshot
of the landing page is kept in the build folder.

Without Chromium (Debian's ``chromium``) or the ``docs`` extra the browser tests skip, unless
``REQUIRE_BROWSER`` is set (CI sets it), in which case they fail.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urljoin, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")

#: Pages opened in the browser (paths in the built site): the landing page, the gallery index,
#: one API page and a page that shows a committed plot.
BROWSED = ("index.html", "gallery/index.html", "api/envs.html", "results/comparison.html")


def _chromium() -> str | None:
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def _require_or_skip(reason: str) -> None:
    """Fails when ``REQUIRE_BROWSER`` is set, skips with ``reason`` otherwise."""
    if os.environ.get("REQUIRE_BROWSER"):
        pytest.fail(f"REQUIRE_BROWSER is set but {reason}")
    pytest.skip(reason)


# -- checkers (no browser needed) ---------------------------------------------------------------


class _Refs(HTMLParser):
    """Collects (tag, attribute, value) of every href and src of a page."""

    def __init__(self):
        super().__init__()
        self.refs: list[tuple[str, str, str]] = []

    def handle_starttag(self, tag, attrs):
        for key, value in attrs:
            if key in ("href", "src") and value is not None:
                self.refs.append((tag, key, value))


def refs(html: str) -> list[tuple[str, str, str]]:
    """Every (tag, attribute, value) of the ``href`` and ``src`` attributes in ``html``."""
    parser = _Refs()
    parser.feed(html)
    return parser.refs


def _target(site: Path, page: str, value: str) -> Path | None:
    """The file of ``site`` that ``value``, found on ``page`` (a path in the site), points to;
    None when it leaves the site (another scheme or host, a data URI, a bare fragment)."""
    parts = urlsplit(value)
    if parts.scheme or parts.netloc or not parts.path:
        return None
    path = urlsplit(urljoin("http://site/" + page, parts.path)).path
    target = site / unquote(path).lstrip("/")
    return target / "index.html" if target.is_dir() else target


def broken_links(site: Path) -> list[str]:
    """``"page: tag attr=value"`` for every relative href/src of every HTML file under
    ``site`` whose target file does not exist (links to other hosts are not followed)."""
    broken = []
    for file in sorted(site.rglob("*.html")):
        page = file.relative_to(site).as_posix()
        for tag, key, value in refs(file.read_text(errors="replace")):
            target = _target(site, page, value)
            if target is not None and not target.is_file():
                broken.append(f"{page}: <{tag} {key}={value!r}>")
    return broken


def broken_images(site: Path, page: str, dom: str, base_url: str = "") -> list[str]:
    """``"page: src"`` for every ``<img>`` of a page's rendered ``dom`` whose source is not a
    file of ``site``. Sources on ``base_url`` (the server of ``site``) are mapped to the
    site; an image from any other host is broken too (the site must not need the network);
    data URIs are fine."""
    broken = []
    for tag, key, value in refs(dom):
        if tag != "img" or key != "src" or value.startswith("data:"):
            continue
        if base_url and value.startswith(base_url):
            value = "/" + value[len(base_url) :].lstrip("/")
        target = _target(site, page, value)
        if target is None or not target.is_file():
            broken.append(f"{page}: {value}")
    return broken


def images(dom: str) -> list[str]:
    """The ``src`` of every ``<img>`` in ``dom``."""
    return [value for tag, key, value in refs(dom) if tag == "img" and key == "src"]


def test_the_checkers_report_a_missing_image_and_a_broken_link(tmp_path):
    (tmp_path / "pics").mkdir()
    (tmp_path / "pics" / "ok.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    (tmp_path / "other.html").write_text("<p>other</p>")
    page = (
        '<html><body><img src="pics/ok.png"><img src="pics/missing.png">'
        '<a href="other.html#top">ok</a><a href="gone/">gone</a>'
        '<a href="https://example.org/x">outside</a><a href="#here">here</a>'
        '<img src="data:image/png;base64,AAAA"></body></html>'
    )
    (tmp_path / "page.html").write_text(page)
    assert broken_images(tmp_path, "page.html", page) == ["page.html: pics/missing.png"]
    assert broken_links(tmp_path) == [
        "page.html: <img src='pics/missing.png'>",
        "page.html: <a href='gone/'>",
    ]
    # An image from another host is not part of the site: broken.
    assert broken_images(tmp_path, "page.html", '<img src="https://example.org/a.png">') == [
        "page.html: https://example.org/a.png"
    ]
    # Absolute URLs on the site's own server map to its files.
    dom = '<img src="http://127.0.0.1:8000/pics/ok.png"><img src="http://127.0.0.1:8000/x.png">'
    assert broken_images(tmp_path, "page.html", dom, "http://127.0.0.1:8000") == [
        "page.html: /x.png"
    ]


# -- the browser ----------------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@contextlib.contextmanager
def serve(folder: Path):
    """``python -m http.server`` on a free localhost port for ``folder``; yields its base URL
    and stops the server on exit."""
    port = _free_port()
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "http.server",
            str(port),
            "--bind",
            "127.0.0.1",
            "--directory",
            str(folder),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 20
        while True:
            try:
                with urllib.request.urlopen(base + "/", timeout=2):
                    break
            except OSError:
                if server.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"http.server on port {port} did not start") from None
                time.sleep(0.1)
        yield base
    finally:
        server.terminate()
        server.wait(timeout=10)


def chromium(url: str, profile: Path, *extra: str, timeout: float = 90) -> str:
    """Runs headless Chromium on ``url`` with ``extra`` flags (e.g. ``--dump-dom``) and a new
    profile folder; returns its standard output."""
    binary = _chromium()
    assert binary is not None
    profile.mkdir(parents=True, exist_ok=True)
    command = [
        binary,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={profile}",
        *extra,
        url,
    ]
    result = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout


def dump_dom(url: str, profile: Path) -> str:
    """The DOM of ``url`` after Chromium has loaded and run it."""
    return chromium(url, profile, "--virtual-time-budget=5000", "--dump-dom")


@pytest.fixture
def browser():
    if _chromium() is None:
        _require_or_skip("Chromium is not installed (apt-get install -y chromium)")


def test_a_page_with_a_broken_image_fails_in_the_browser(tmp_path, browser):
    site = tmp_path / "site"
    site.mkdir()
    (site / "ok.png").write_bytes((ROOT / "results" / "board_looks.png").read_bytes())
    (site / "index.html").write_text(
        '<html><body><h1>t</h1><img src="ok.png"><img src="nowhere/missing.png"></body></html>'
    )
    with serve(site) as base:
        dom = dump_dom(base + "/index.html", tmp_path / "profile")
    assert "<h1>t</h1>" in dom
    assert broken_images(site, "index.html", dom, base) == ["index.html: nowhere/missing.png"]


@pytest.fixture(scope="module")
def built_site(tmp_path_factory):
    """The site built by scripts/docs.sh (mkdocs build --strict) into a temporary folder."""
    try:
        import mkdocs  # noqa: F401
    except ImportError:
        _require_or_skip("the docs extra is not installed (pip install -e '.[docs]')")
    site = tmp_path_factory.mktemp("docs") / "site"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    result = subprocess.run(
        ["bash", "scripts/docs.sh", str(site)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, (result.stdout + result.stderr)[-4000:]
    return site


@pytest.mark.slow
def test_the_site_builds_strictly_with_every_page_and_no_broken_link(built_site):
    for page in (
        "index.html",
        "getting-started.html",
        "architecture.html",
        "adding_tasks.html",
        "changelog.html",
        "gallery/index.html",
        "api/index.html",
        "api/physics_planning.cli.html",
        "api/hier_agents.agents.registry.html",
        "tutorials/swap_planners_and_skills.html",
        "tutorials/train_and_swap_a_learned_part.html",
        "results/agent.html",
        "results/comparison.html",
        "results/images/comparison.png",
    ):
        assert (built_site / page).is_file(), page
    # No private module or __main__ gets a page.
    names = [p.name for p in (built_site / "api").glob("*.html")]
    assert not [n for n in names if any(part.startswith("_") for part in n.split("."))]
    assert broken_links(built_site) == []


@pytest.mark.slow
def test_the_browser_renders_the_pages_and_every_image_loads(built_site, browser, tmp_path):
    with serve(built_site) as base:
        doms = {
            page: dump_dom(f"{base}/{page}", tmp_path / f"profile{i}")
            for i, page in enumerate(BROWSED)
        }
        shot = built_site / "screenshot-index.png"
        chromium(
            f"{base}/index.html",
            tmp_path / "profile-shot",
            f"--screenshot={shot}",
            "--window-size=1280,900",
            "--virtual-time-budget=5000",
        )
    assert "physics-planning" in doms["index.html"]
    assert "Environments" in doms["gallery/index.html"]
    assert "envs.load" in doms["api/envs.html"] or "def load" in doms["api/envs.html"]
    assert any(src.endswith("comparison.png") for src in images(doms["results/comparison.html"]))
    for page, dom in doms.items():
        assert broken_images(built_site, page, dom, base) == [], page
    assert shot.is_file() and shot.stat().st_size > 10_000
