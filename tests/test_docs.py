"""The documentation: the site builds without a warning, and every relative
link of README.md and docs/*.md resolves as GitHub resolves it.

`mkdocs build --strict` (mkdocs.yml) fails on a broken link or anchor
between pages, a page left out of the navigation and a docstring the API
reference cannot read. The README is no page of the site, and GitHub shows
the pages as plain Markdown, so the links of both are also checked here
against the files and GitHub's heading anchors.
"""

from __future__ import annotations

import dataclasses
import inspect
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cwtest import FMU_DIR, ROOT

PAGES = sorted((ROOT / "docs").glob("*.md"))


def _require_mkdocs() -> None:
    """Skip without the docs extra, except in CI, where everything is installed."""
    try:
        import mkdocs  # noqa: F401
        import mkdocstrings  # noqa: F401
    except ImportError as e:
        reason = f"the docs extra is not installed ({e}): pip install -e .[docs]"
        if os.environ.get("CI"):
            pytest.fail(reason)
        pytest.skip(reason)


def test_site_builds_without_warnings(tmp_path):
    _require_mkdocs()
    site = tmp_path / "site"
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    # The notebook's kernel (mkdocs-jupyter executes docs/notebooks/) logs that its
    # zmq sockets on localhost are not encrypted: a line of ipykernel's, not of the docs.
    lines = [ln for ln in r.stderr.splitlines() if not ln.startswith("[IPKernelApp] WARNING | Kernel is running over TCP")]
    problems = "\n".join(line for line in lines if not line.startswith("INFO"))
    assert r.returncode == 0 and "WARNING" not in "\n".join(lines), problems[-4000:]
    for page in PAGES:
        built = site / ("index.html" if page.stem == "index" else f"{page.stem}/index.html")
        assert built.is_file(), f"{page.name} was not built"
    # The reference is generated, not just the page's own text.
    api = (site / "api" / "index.html").read_text()
    for name in ("clockwork.engine.System", "clockwork.engine.System.output", "clockwork.engine.MasterSettings",
                 "clockwork.engine.Master.run_until", "clockwork.errors.SceneError",
                 "clockwork.errors.SimulationError"):
        assert f'id="{name}"' in api, f"the API reference has no entry {name}"


# -- links, as GitHub resolves them -------------------------------------

_FENCE = re.compile(r"^(```|~~~).*?^\1\s*$", re.M | re.S)
_CODE = re.compile(r"(`+)(?:(?!\1).)+?\1", re.S)
_LINK = re.compile(r"!?\[((?:[^\[\]]|\[[^\]]*\])*)\]\(\s*<?([^\s()<>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_REFERENCE = re.compile(r"^ {0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s.*)?$", re.M)
_HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$", re.M)
_HTML_ID = re.compile(r"<a\s+(?:id|name)=\"([^\"]+)\"", re.I)


def _prose(text: str) -> str:
    """The text without fenced code blocks and code spans, where nothing is a link."""
    text = _FENCE.sub("", text)
    return _CODE.sub("", text)


def github_slug(heading: str) -> str:
    """GitHub's id of a heading: its text lowercased, punctuation removed
    (letters, digits, marks, '_', '-' and spaces stay), each space a '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link counts by its text
    text = re.sub(r"<[^>]+>", "", text).replace("`", "").replace("*", "")
    return re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every anchor a Markdown file has on GitHub: its headings' ids (the
    n-th repeat gets -n) and explicit <a id=...> tags."""
    text = _FENCE.sub("", path.read_text())
    seen: dict[str, int] = {}
    found = set(_HTML_ID.findall(text))
    for _, title in _HEADING.findall(text):
        slug = github_slug(title)
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        found.add(slug if n == 0 else f"{slug}-{n}")
    return found


def links(path: Path) -> list[str]:
    text = _prose(path.read_text())
    return [target for _, target in _LINK.findall(text)] + _REFERENCE.findall(text)


def broken_links(path: Path) -> list[str]:
    """The relative links of `path` that name no file, or an anchor its target lacks."""
    bad = []
    for target in links(path):
        if re.match(r"[a-z][a-z0-9+.-]*:", target, re.I):  # https:, mailto:: not ours to check
            continue
        file, _, anchor = target.partition("#")
        dest = (path.parent / file).resolve() if file else path
        if not dest.exists():
            bad.append(f"{target}: no file {dest.relative_to(ROOT) if dest.is_relative_to(ROOT) else dest}")
        elif anchor and (dest.suffix != ".md" or anchor not in anchors(dest)):
            bad.append(f"{target}: {dest.name} has no heading with the anchor #{anchor}")
    return bad


@pytest.mark.parametrize("path", [ROOT / "README.md"] + PAGES, ids=lambda p: p.name)
def test_links_resolve(path):
    assert links(path) or path.name != "README.md", "no links found: the link pattern is broken"
    assert broken_links(path) == []


def test_link_check_finds_what_is_broken(tmp_path):
    page = tmp_path / "page.md"
    (tmp_path / "other.md").write_text("# Other\n\n## Results (2026, `x --y`; a -> b)\n\n## Again\n\n## Again\n")
    page.write_text("[ok](other.md#results-2026-x---y-a---b) [ok](other.md#again-1) [ok](#own)\n\n# Own\n\n"
                    "[missing](nothing.md) [anchor](other.md#results) [anchor](#none) "
                    "[url](https://example.org/x.md) `[code](nowhere.md)`\n\n```\n[fenced](nowhere.md)\n```\n")
    assert broken_links(page) == ["nothing.md: no file " + str(tmp_path / "nothing.md"),
                                  "other.md#results: other.md has no heading with the anchor #results",
                                  "#none: page.md has no heading with the anchor #none"]


def test_readme_fits_two_screens():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 120, f"README.md has {len(lines)} lines: move detail into docs/"


# -- the API reference documents every argument and setting ---------------

def documented(doc: str, section: str) -> list[str]:
    """The names a Google-style docstring section lists ("Args:", "Attributes:")."""
    body = re.split(rf"^\s*{section}:\s*$", inspect.cleandoc(doc), maxsplit=1, flags=re.M)
    if len(body) < 2:
        return []
    names = []
    for line in body[1].splitlines():
        if line.strip() and not line.startswith(" "):
            break  # the next section
        m = re.match(r"^    (\w+)(?: \(.*\))?:", line)
        if m:
            names.append(m.group(1))
    return names


def test_every_argument_and_setting_is_documented():
    from clockwork.engine import Master, MasterSettings, System

    fields = {f.name for f in dataclasses.fields(MasterSettings)}
    listed = set(documented(MasterSettings.__doc__, "Attributes"))
    assert listed == fields, f"MasterSettings' Attributes: missing {fields - listed}, not fields {listed - fields}"
    for function, doc in ((System.__init__, System.__doc__), (System.restart, None), (System.value, None),
                          (System.output, None), (Master.run_until, None), (Master.step, None)):
        wanted = {p for p in inspect.signature(function).parameters if p != "self"}
        listed = set(documented(doc or function.__doc__, "Args"))
        assert listed == wanted, f"{function.__qualname__}: missing {wanted - listed}, not arguments {listed - wanted}"


def test_documented_reads_a_docstring():
    doc = """Summary.

    Args:
        a: One
            more line.
        b (int): Two.

    Raises:
        c: not an argument.
    """
    assert documented(doc, "Args") == ["a", "b"]
    assert documented(doc, "Attributes") == []


def test_api_examples_run(tmp_path):
    """The Python blocks of docs/api.md and of the documented docstrings run as written."""
    from clockwork.engine import Master, MasterSettings, System

    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "api.md").read_text(), flags=re.S)
    for doc in (System.__doc__, MasterSettings.__doc__, Master.__doc__, Master.run_until.__doc__):
        blocks += re.findall(r"```python\n(.*?)```", inspect.cleandoc(doc), flags=re.S)
    assert len(blocks) >= 3
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR))
    for code in blocks:
        code = "from clockwork.engine import MasterSettings, System\n" + textwrap.dedent(code)
        r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                           timeout=120)
        assert r.returncode == 0, (code, r.stderr[-2000:])
