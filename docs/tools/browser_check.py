"""Open the built manual in headless Chromium and check what a reader sees (``make docs-browser``).

Usage: ``python docs/tools/browser_check.py [BUILD_DIR] [--out DIR] [--search TERM]``
(defaults: ``docs/_build/html``, ``docs/_build/browser``, ``omega-K``).

Serves BUILD_DIR on a local port and drives Debian's Chromium through ChromeDriver (Selenium):

- every page loads without a console error (severity SEVERE in Chromium's log);
- every image on every page is displayed (``complete`` with a non-zero natural width, after it is
  scrolled into view, so lazy images load);
- the physics page's equations are typeset (MathJax's ``mjx-container`` elements, no error nodes);
- the search page finds TERM;
- screenshots of the front page, the physics page at (M5) and one gallery example go to ``--out``.

Needs ``/usr/bin/chromium`` and ``/usr/bin/chromedriver`` (``apt-get install chromium
chromium-driver``) and the ``selenium`` package (the ``docs`` extra). Prints one line per problem
and a summary; exits 1 on a problem, 2 when the manual or the browser is missing.
"""
from __future__ import annotations

import argparse
import functools
import http.server
import shutil
import sys
import threading
import time
from pathlib import Path

#: JavaScript: the images of the page that are not displayed, after scrolling each into view
_UNDISPLAYED_IMAGES = """
const done = arguments[arguments.length - 1];
const images = Array.from(document.images);
images.forEach(img => { img.loading = 'eager'; img.scrollIntoView(); });
const deadline = Date.now() + 8000;
(function wait() {
  const bad = images.filter(img => !(img.complete && img.naturalWidth > 0));
  if (bad.length === 0 || Date.now() > deadline) { done(bad.map(img => img.getAttribute('src'))); }
  else { setTimeout(wait, 100); }
})();
"""


def _serve(build: Path) -> tuple[http.server.ThreadingHTTPServer, str]:
    handler = functools.partial(_QuietHandler, directory=str(build))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}/"


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:       # noqa: D102  (no line per request)
        pass


def _driver(width: int = 1400, height: int = 1000):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                     f"--window-size={width},{height}"):
        options.add_argument(argument)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    service = Service(shutil.which("chromedriver") or "/usr/bin/chromedriver")
    driver = webdriver.Chrome(service=service, options=options)
    driver.set_script_timeout(20)
    return driver


def _pages(build: Path) -> list[str]:
    """The manual's pages (docs/tools/check_links.py's list), as paths relative to ``build``."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from check_links import pages
    return [p.relative_to(build).as_posix() for p in pages(build)]


def _wait_for(driver, script: str, seconds: float = 20.0):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.2)
    return driver.execute_script(script)


def check_pages(driver, base: str, pages: list[str]) -> list[str]:
    """Console errors and undisplayed images of each page: one ``"page: message"`` per problem."""
    problems = []
    for page in pages:
        driver.get(base + page)
        _wait_for(driver, "return document.readyState === 'complete'")
        for entry in driver.get_log("browser"):
            if entry.get("level") == "SEVERE":
                problems.append(f"{page}: console error: {entry.get('message', '')[:300]}")
        for src in driver.execute_async_script(_UNDISPLAYED_IMAGES):
            problems.append(f"{page}: image not displayed: {src}")
    return problems


def check_math(driver, base: str, page: str = "physics.html") -> tuple[list[str], int]:
    """Whether the page's equations are typeset: problems and the number of typeset equations."""
    driver.get(base + page)
    count = _wait_for(driver, "return document.querySelectorAll('mjx-container').length")
    errors = driver.execute_script("return document.querySelectorAll('mjx-merror, .MathJax_Error').length")
    problems = [] if count else [f"{page}: no equation typeset (no mjx-container)"]
    if errors:
        problems.append(f"{page}: {errors} equations failed to typeset")
    return problems, int(count or 0)


def check_search(driver, base: str, term: str) -> tuple[list[str], int]:
    """Whether the search page finds ``term``: problems and the number of results."""
    from urllib.parse import quote
    driver.get(base + "search.html?q=" + quote(term))
    count = _wait_for(driver, "return document.querySelectorAll('#search-results ul.search li, ul.search li').length", 30)
    return ([] if count else [f"search.html: no result for {term!r}"]), int(count or 0)


def screenshots(driver, base: str, build: Path, out: Path) -> list[Path]:
    """Screenshots of the front page, the physics page at (M5) and the first gallery example."""
    out.mkdir(parents=True, exist_ok=True)
    gallery = sorted(p.relative_to(build).as_posix() for p in (build / "gallery").glob("plot_*.html"))
    shots = [("front_page.png", "index.html"), ("physics.png", "physics.html#eq-m5")]
    if gallery:
        shots.append(("gallery_example.png", gallery[0]))
    written = []
    for name, page in shots:
        driver.get(base + page)
        _wait_for(driver, "return document.readyState === 'complete'")
        time.sleep(1.0)                 # MathJax typesets after the load event
        driver.save_screenshot(str(out / name))
        written.append(out / name)
    return written


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("build", nargs="?", default="docs/_build/html")
    parser.add_argument("--out", default="docs/_build/browser", help="folder of the screenshots")
    parser.add_argument("--search", default="omega-K", help="a term the search must find")
    args = parser.parse_args(argv)
    build = Path(args.build)
    if not (build / "index.html").is_file():
        print(f"browser_check: {build} holds no built manual (index.html); run `make docs` first", file=sys.stderr)
        return 2
    if not (shutil.which("chromium") and shutil.which("chromedriver")):
        print("browser_check: needs chromium and chromedriver on PATH "
              "(`apt-get install chromium chromium-driver`)", file=sys.stderr)
        return 2
    started = time.monotonic()
    server, base = _serve(build)
    driver = _driver()
    try:
        pages = _pages(build)
        problems = check_pages(driver, base, pages)
        math_problems, equations = check_math(driver, base)
        search_problems, results = check_search(driver, base, args.search)
        shots = screenshots(driver, base, build, Path(args.out))
    finally:
        driver.quit()
        server.shutdown()
    problems += math_problems + search_problems
    for problem in problems:
        print(problem)
    print(f"browser_check: {len(pages)} pages, {equations} equations typeset on physics.html, "
          f"{results} results for {args.search!r}, {len(problems)} problems, "
          f"{time.monotonic() - started:.0f} s; screenshots: {', '.join(str(s) for s in shots)}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
