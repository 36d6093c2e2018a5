"""Every FMU documents itself: documentation/index.html (equations, every
variable, references, a usage example that runs), a model.png icon at the
archive's root, and its copyright and license."""

from __future__ import annotations

import html
import os
import re
import struct
import zlib
import zipfile
from html.parser import HTMLParser

import pytest

from cwtest import fmu_file
from fmu_driver import unpack

MODELS = ["Air", "AveragedPendulum", "ChronometerEscapement", "Drag", "GrasshopperEscapement",
          "MechanismVibration", "Pendulum"]
VOID = {"meta", "br", "hr", "img", "link", "input", "wbr", "col", "area", "base", "source"}


class _Tags(HTMLParser):
    """Checks that elements nest and close, and collects what would load
    something from outside the page."""

    def __init__(self):
        super().__init__()
        self.stack: list[str] = []
        self.problems: list[str] = []

    def handle_starttag(self, tag, attrs):
        for key, value in attrs:
            if key in ("src", "srcset") or (tag == "link" and key == "href"):
                self.problems.append(f"<{tag} {key}={value!r}> loads an external resource")
        if tag in ("script", "iframe", "object", "embed"):
            self.problems.append(f"<{tag}>")
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.problems.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
        else:
            self.stack.pop()


def _png_size(data: bytes) -> tuple[int, int]:
    """Walk the PNG's chunks, checking every CRC, and decode the image data
    far enough to know it has the declared size."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks, idat = 8, [], b""
    while pos < len(data):
        (n,) = struct.unpack_from(">I", data, pos)
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        (crc,) = struct.unpack_from(">I", data, pos + 8 + n)
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF, kind
        chunks.append(kind)
        if kind == b"IDAT":
            idat += body
        pos += 12 + n
    assert chunks[0] == b"IHDR" and chunks[-1] == b"IEND" and b"IDAT" in chunks
    ihdr = data[16:16 + 13]
    width, height, depth, color = struct.unpack(">IIBB", ihdr[:10])
    channels = {0: 1, 2: 3, 4: 2, 6: 4}[color]
    assert depth == 8
    assert len(zlib.decompress(idat)) == height * (1 + width * channels)
    return width, height


@pytest.fixture(params=MODELS)
def model(request):
    return request.param


def test_fmu_has_documentation_and_icon(model):
    path = fmu_file(model)
    md, _ = unpack(path)
    with zipfile.ZipFile(path) as z:
        names = set(z.namelist())
        assert {"documentation/index.html", "model.png",
                "documentation/licenses/LICENSE.txt"} <= names, sorted(names)
        page = z.read("documentation/index.html").decode("utf-8")
        icon = z.read("model.png")
        license_text = z.read("documentation/licenses/LICENSE.txt").decode()
    width, height = _png_size(icon)
    assert width == height and width >= 32

    for v in md.modelVariables:
        assert f"<code>{html.escape(v.name)}</code>" in page, v.name
    assert "Equations" in page and "<pre>" in page
    assert "Ziemkiewicz" in page or "Hoyng" in page
    indicators = [v.name for v in md.modelVariables
                  if v.name.startswith("event_indicator")]
    for name in indicators:
        assert f"<li><code>{name}</code>" in page, name

    tags = _Tags()
    tags.feed(page)
    tags.close()
    assert not tags.problems and tags.stack == [], (tags.problems, tags.stack)
    assert not re.search(r"url\(|@import", page)

    assert md.copyright == "Copyright (c) 2026 The clockwork authors"
    assert md.license == "MIT"
    assert "MIT License" in license_text and md.copyright in license_text


def test_usage_example_runs(model, tmp_path, monkeypatch):
    """The page's example, run as written next to a copy of the FMU."""
    path = fmu_file(model)
    with zipfile.ZipFile(path) as z:
        page = z.read("documentation/index.html").decode("utf-8")
    found = re.search(r'<pre class="example">(.*?)</pre>', page, re.S)
    assert found, "no usage example"
    code = html.unescape(found.group(1))
    (tmp_path / path.name).write_bytes(path.read_bytes())
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(compile(code, f"{model} documentation example", "exec"), scope)
    result = scope["result"]
    assert len(result) > 10
    for name in result.dtype.names[1:]:
        assert all(map(lambda x: x == x, result[name])), name  # no NaN
    # Something happens in every example.
    moving = [n for n in result.dtype.names[1:] if len(set(result[n].tolist())) > 1]
    assert moving, result.dtype.names
    assert os.path.exists(path.name)
