"""Check a built HTML manual's internal links and images (``make docs`` runs it after Sphinx).

Usage: ``python docs/tools/check_links.py [BUILD_DIR] [--gallery-figures]`` (default
``docs/_build/html``).

Every ``<a href>``, ``<img src>``, ``<link href>``, ``<script src>`` and ``<source srcset>`` of
every page is resolved against the page:

- a local target must exist as a file; a link with a fragment (``page.html#eq-m5``) must name an
  ``id`` (or ``name``) on the target page;
- an image must be a non-empty file that Pillow can open (SVG: non-empty XML);
- no page may load a script, style sheet, font or image from the network (the manual is read
  offline); plain ``<a>`` links to other sites are allowed and not fetched;
- with ``--gallery-figures`` (a build that ran the gallery, ``make docs``): every example page
  ``gallery/plot_*.html`` shows at least one figure its script drew (``sphx_glr_plot_*``).

Prints one line per problem and a summary; exits 1 if there is any problem, 2 if BUILD_DIR
holds no manual.
"""
from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

#: attributes that name a resource, by tag; ``True``: the resource is loaded with the page
RESOURCE_ATTRIBUTES = {("a", "href"): False, ("img", "src"): True, ("link", "href"): True,
                       ("script", "src"): True, ("source", "srcset"): True, ("iframe", "src"): True}
#: folders of the build that are not pages of the manual (Sphinx's copies of sources, assets)
SKIPPED_FOLDERS = {"_sources", "_static", "_images", "_downloads", "_modules"}


class _Page(HTMLParser):
    """The ids and the resource references of one HTML page."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.references: list[tuple[str, str, bool]] = []     # (tag, url, loaded with the page)

    def handle_starttag(self, tag, attrs):
        values = dict(attrs)
        for key in ("id", "name"):
            if values.get(key):
                self.ids.add(values[key])
        for (ref_tag, attribute), loaded in RESOURCE_ATTRIBUTES.items():
            if tag == ref_tag and values.get(attribute):
                url = values[attribute].split()[0] if attribute == "srcset" else values[attribute]
                rel = values.get("rel", "") or ""
                # <link rel="canonical"/"alternate"> names a page, it does not load one
                self.references.append((tag, url, loaded and "canonical" not in rel and "alternate" not in rel))


def pages(build: Path) -> list[Path]:
    """The manual's pages in ``build``: every HTML file outside :data:`SKIPPED_FOLDERS`, sorted."""
    return [p for p in sorted(build.rglob("*.html")) if not SKIPPED_FOLDERS.intersection(p.relative_to(build).parts[:-1])]


def _parse(path: Path, cache: dict[Path, _Page]) -> _Page:
    if path not in cache:
        page = _Page()
        page.feed(path.read_text(encoding="utf-8", errors="replace"))
        cache[path] = page
    return cache[path]


def _image_problem(path: Path) -> str | None:
    if path.stat().st_size == 0:
        return "empty image"
    if path.suffix.lower() == ".svg":
        return None if b"<svg" in path.read_bytes()[:4096] else "SVG without <svg>"
    try:
        from PIL import Image
        with Image.open(path) as image:
            image.verify()
    except Exception as error:      # any decoder failure means the browser shows nothing
        return f"unreadable image ({error})"
    return None


def check(build: Path) -> list[str]:
    """Problems of the manual built in ``build``: one ``"page: message"`` string each."""
    cache: dict[Path, _Page] = {}
    problems: list[str] = []
    for page_path in pages(build):
        page = _parse(page_path, cache)
        where = page_path.relative_to(build)
        for tag, url, loaded in page.references:
            parts = urlsplit(url)
            if parts.scheme in ("mailto", "javascript", "data") or url.startswith("#") and not parts.fragment:
                continue
            if parts.scheme or parts.netloc:
                if loaded:
                    problems.append(f"{where}: <{tag}> loads {url} from the network")
                continue
            target = (page_path.parent / unquote(parts.path)).resolve() if parts.path else page_path
            if target.is_dir():
                target = target / "index.html"
            if not target.is_file():
                problems.append(f"{where}: <{tag}> {url}: no such file")
                continue
            if tag == "img" or (tag == "source" and target.suffix.lower() in (".png", ".jpg", ".svg")):
                message = _image_problem(target)
                if message:
                    problems.append(f"{where}: <{tag}> {url}: {message}")
            fragment = unquote(parts.fragment)
            if fragment and target.suffix == ".html" and fragment not in _parse(target, cache).ids:
                problems.append(f"{where}: <{tag}> {url}: no id {fragment!r} on {target.name}")
    return problems


def gallery_problems(build: Path) -> list[str]:
    """Example pages of the gallery that show no figure of their own script."""
    problems = []
    for page_path in sorted((build / "gallery").glob("plot_*.html")):
        figures = [url for tag, url, _ in _parse(page_path, {}).references
                   if tag == "img" and f"sphx_glr_{page_path.stem}_" in url]
        if not figures:
            problems.append(f"{page_path.relative_to(build)}: the example left no figure")
    if not problems and not list((build / "gallery").glob("plot_*.html")):
        problems.append("gallery: no example pages")
    return problems


def main(argv: list[str]) -> int:
    figures = "--gallery-figures" in argv
    argv = [a for a in argv if a != "--gallery-figures"]
    build = Path(argv[0] if argv else "docs/_build/html")
    if not (build / "index.html").is_file():
        print(f"check_links: {build} holds no built manual (index.html); run `make docs` first", file=sys.stderr)
        return 2
    problems = check(build) + (gallery_problems(build) if figures else [])
    for problem in problems:
        print(problem)
    print(f"check_links: {len(pages(build))} pages, {len(problems)} problems ({build})")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
