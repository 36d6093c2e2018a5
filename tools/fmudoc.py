"""The FMU's own documentation, generated from model.toml by fmugen.py:
documentation/index.html (equations, variables, event indicators,
references, usage) and the model.png icon of the archive's root.

Both are self-contained: the page has no external style sheet, script or
image, and the icon is drawn here with zlib and struct only, so that the
build needs nothing beyond the Python standard library.
"""

from __future__ import annotations

import html
import math
import struct
import zlib

CAUSALITY_ORDER = {"parameter": 0, "input": 1, "output": 2, "local": 3}

STYLE = """
body { font-family: sans-serif; max-width: 60em; margin: 2em auto; padding: 0 1em;
       color: #222; line-height: 1.45; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; width: 100%; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.5em; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
td.num { text-align: right; white-space: nowrap; font-family: monospace; }
code, pre { font-family: monospace; background: #f6f6f6; }
pre { padding: 0.6em; overflow-x: auto; }
p.meta { color: #555; margin-top: 0; }
"""


# The FMI 2.0 functions a model's own prose names, and their FMI 3.0 names.
FMI3_NAMES = {"fmi2DoStep": "fmi3DoStep", "fmi2ExitInitializationMode": "fmi3ExitInitializationMode",
              "fmi2GetFMUstate": "fmi3GetFMUState", "fmi2SetFMUstate": "fmi3SetFMUState"}


def fmi3_prose(t: dict) -> dict:
    """The table with the FMI 2.0 function names in its descriptions and
    equations replaced by FMI 3.0's, for the FMI 3.0 build's texts."""
    def convert(x):
        if isinstance(x, str):
            for a, b in FMI3_NAMES.items():
                x = x.replace(a, b)
            return x
        if isinstance(x, dict):
            return {k: v if k.startswith("_") else convert(v) for k, v in x.items()}
        if isinstance(x, list):
            return [convert(v) for v in x]
        return x
    return convert(t)


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def number_text(x) -> str:
    """Shortest text that reads back as the same number (a double round-trips)."""
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, int):
        return str(x)
    r = repr(float(x))
    return r[:-2] if r.endswith(".0") else r


def _deps(v: dict) -> list[str]:
    d = v.get("depends_on", [])
    return list(d) if isinstance(d, (list, dict)) else []


def variable_table(variables: list[dict]) -> list[str]:
    rows = sorted(variables, key=lambda v: (CAUSALITY_ORDER[v["causality"]], v["vr"]))
    out = [
        "<table>",
        "<tr><th>name</th><th>causality</th><th>variability</th><th>type</th>"
        "<th>unit</th><th>start</th><th>min</th><th>max</th>"
        "<th>direct feedthrough from</th><th>description</th></tr>",
    ]
    for v in rows:
        unit = v.get("unit", "")
        if "display_unit" in v:
            unit += f" (shown in {v['display_unit']})"
        start = "calculated"
        if v["causality"] in ("parameter", "input"):
            start = v["start"] if v["type"] == "String" else number_text(v["start"])
        feed = ", ".join(_deps(v)) if v["causality"] == "output" else ""
        if v["causality"] == "output" and not feed:
            feed = "none"
        out.append(
            f"<tr><td><code>{_e(v['name'])}</code></td><td>{_e(v['causality'])}</td>"
            f"<td>{_e(v['variability'])}</td><td>{_e(v['type'])}</td><td>{_e(unit)}</td>"
            f'<td class="num">{_e(start)}</td>'
            f'<td class="num">{_e(number_text(v["min"])) if "min" in v else ""}</td>'
            f'<td class="num">{_e(number_text(v["max"])) if "max" in v else ""}</td>'
            f"<td>{_e(feed)}</td><td>{_e(v['description'])}</td></tr>"
        )
    out.append("</table>")
    return out


# What each binaries/ folder name of the standards holds, for the
# Platforms section (FMI 2.0 Sec. 2.3 and FMI 3.0 Sec. 2.5.1 name them).
PLATFORMS = {
    "linux64": "Linux on x86-64 (glibc), built with GCC",
    "x86_64-linux": "Linux on x86-64 (glibc), built with GCC",
    "win64": "Windows on x86-64, cross-compiled with mingw-w64; it needs only "
             "Windows' own KERNEL32.dll and msvcrt.dll",
    "x86_64-windows": "Windows on x86-64, cross-compiled with mingw-w64; it needs "
                      "only Windows' own KERNEL32.dll and msvcrt.dll",
    "aarch64-linux": "Linux on 64-bit Arm (glibc), cross-compiled with GCC",
}


def platforms_section(name: str, platforms: list[str], fmi_version: int) -> list[str]:
    """Which binaries the archive carries, and what to do elsewhere."""
    ext = {"win64": "dll", "x86_64-windows": "dll"}
    b = ["<h2>Platforms</h2>", "<p>Binaries in this archive:</p>", "<ul>"]
    b += [f"<li><code>binaries/{_e(p)}/{_e(name)}.{ext.get(p, 'so')}</code>: "
          f"{_e(PLATFORMS.get(p, p))}.</li>" for p in platforms]
    b.append("</ul>")
    if any(p in ext for p in platforms):
        b.append("<p>Every binary is built from the C sources in <code>sources/</code> by GCC at the "
                 "same optimisation level. The Windows binary carries mingw-w64's sin, cos, exp, log and pow "
                 "(it takes any other, such as j1, from Windows' msvcrt.dll), the Linux binary "
                 "calls glibc's; the two round differently in the last bit for "
                 "about one argument in a thousand, so where a model calls them the binaries can "
                 "differ by rounding, far below the integrator's tolerance. Otherwise they give the "
                 "same bits: clockwork's tests compare them at every communication point of the "
                 "default experiment.</p>")
    if "aarch64-linux" in platforms:
        b.append("<p>The aarch64-linux binary is compiled without fused multiply-add (x86-64's "
                 "baseline has none), so that it rounds as the x86-64 binary does; both call "
                 "glibc.</p>")
    build = ("sources/buildDescription.xml lists them" if fmi_version == 3
             else "the modelDescription.xml lists them under SourceFiles")
    b.append(f"<p>Elsewhere, compile the C99 sources in <code>sources/</code> ({build}) into a "
             f"shared library named <code>{_e(name)}</code> with the FMI headers on the include path.</p>")
    return b


def generate_html(t: dict, references: dict, fmi_version: int = 2, platforms: list[str] | None = None) -> str:
    """The page of the FMI 2.0 build, or of the FMI 3.0 build (its API names,
    Event Mode and the events fmi3DoStep returns early at), with the
    platforms whose binaries the archive carries (default: Linux x86-64)."""
    v3 = fmi_version == 3
    api = "fmi3" if v3 else "fmi2"
    m = t["model"]
    doc = t.get("documentation", {})
    variables = t["variable"]
    exp = t.get("experiment", {})
    name = m["name"]
    b = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        f"<title>{_e(name)}</title>",
        f"<style>{STYLE}</style>",
        "</head>",
        "<body>",
        f"<h1>{_e(name)}</h1>",
        f'<p class="meta">FMI {"3.0" if v3 else "2.0"} Co-Simulation FMU, version {_e(m.get("version", "0.1.0"))}. '
        f"{_e(t['_copyright'])}; license {_e(t['_license'])}. "
        "Generated by clockwork tools/fmugen.py from model.toml.</p>",
        f"<p>{_e(m['description'])}</p>",
        "<h2>Equations</h2>",
        doc.get("equations", "<p>See the description above.</p>"),
        "<h2>Variables</h2>",
        f"<p>Parameters and inputs are refused ({api}Error, with a logged reason) "
        "outside [min, max] or when not finite. &ldquo;Direct feedthrough from&rdquo; "
        "lists the inputs an output depends on at the same communication point "
        "(ModelStructure/Outputs); other outputs follow the inputs only through "
        "the FMU's state, so they close no algebraic loop.</p>",
    ]
    b += variable_table(variables)

    indicators = [v for v in sorted(variables, key=lambda v: v["vr"]) if v.get("event_indicator")]
    b.append("<h2>Event indicators</h2>")
    if indicators:
        b += [
            "<p>These outputs change sign exactly where the model's outputs jump. "
            "A master that locates their zero crossings (for example by bisection "
            f"with {api}GetFMU{'S' if v3 else 's'}tate/{api}SetFMU{'S' if v3 else 's'}tate) puts a communication point on "
            f"each switch. They are listed in the {'annotation' if v3 else 'vendor annotation'} "
            f"<code>clockwork</code> of modelDescription.xml. An indicator is "
            f"computed with the discrete mode committed at the last {api}DoStep (left "
            "limit); the outputs already reflect a switch seen in the current "
            "inputs (right limit), and the mode is committed at the start of the "
            f"next {api}DoStep{' or by fmi3UpdateDiscreteStates in Event Mode' if v3 else ''}.</p>",
            "<ul>",
        ]
        b += [f"<li><code>{_e(v['name'])}</code>: {_e(v['description'])}</li>" for v in indicators]
        b.append("</ul>")
    else:
        b.append("<p>None: the outputs of this model are continuous in time.</p>")

    derivs = [v for v in sorted(variables, key=lambda v: v["vr"]) if v.get("derivatives")]
    if derivs:
        b += ["<h2>Output derivatives</h2>",
              f"<p>{'fmi3GetOutputDerivatives' if v3 else 'fmi2GetRealOutputDerivatives'} provides, after each step:</p>", "<ul>"]
        b += [f"<li><code>{_e(v['name'])}</code>: orders 1 to {int(v['derivatives'])}</li>" for v in derivs]
        b.append("</ul>")

    b += [
        "<h2>Capabilities</h2>",
        "<ul>",
        "<li>Co-Simulation only; variable communication step sizes.</li>",
        f"<li>{api}GetFMU{'S' if v3 else 's'}tate, {api}SetFMU{'S' if v3 else 's'}tate and state serialization: a state "
        "restores the instance bit for bit; a corrupt or inconsistent state is "
        "refused.</li>",
        ("<li>Inputs hold their values over a step (FMI 3.0 has no input "
         "derivatives; no intermediate update).</li>" if v3 else
         "<li>Inputs are followed between communication points when their "
         "derivatives are set with fmi2SetRealInputDerivatives (orders 1 and 2).</li>")
        if any(v["causality"] == "input" for v in variables) else "",
        _early_return_item(m) if v3 else "",
        f"<li>Default experiment: {number_text(exp.get('start', 0.0))} s to "
        f"{number_text(exp.get('stop', 10.0))} s, step {number_text(exp.get('step', 0.01))} s.</li>",
        "</ul>",
    ]

    if platforms is None:
        platforms = ["x86_64-linux" if v3 else "linux64"]
    b += platforms_section(name, platforms, fmi_version)

    refs = doc.get("references", [])
    if refs:
        b += ["<h2>References</h2>", "<ol>"]
        for key in refs:
            r = references[key]
            doi = f" doi:{_e(r['doi'])}" if "doi" in r else ""
            b.append(f"<li>{_e(r['text'])}{doi}</li>")
        b.append("</ol>")

    if "example" in doc:
        b += [
            "<h2>Usage</h2>",
            "<p>With FMPy (<code>pip install fmpy</code>), from the folder that "
            f"holds <code>{_e(name)}.fmu</code>:</p>",
            f'<pre class="example">{_e(doc["example"].strip())}</pre>',
        ]
    b += ["</body>", "</html>", ""]
    return "\n".join(x for x in b if x)


def _early_return_item(m: dict) -> str:
    events = m.get("early_return", [])
    if not events:
        return ("<li>Event Mode (fmi3UpdateDiscreteStates commits the modes "
                "decided from the current inputs); fmi3DoStep never returns early: "
                "the events of this model depend on its inputs and are located by "
                "the importer.</li>")
    return ("<li>Event Mode; with <code>earlyReturnAllowed</code>, fmi3DoStep "
            "returns early, with <code>lastSuccessfulTime</code> at the event and "
            "<code>eventHandlingNeeded</code> in Event Mode, at each "
            + ", ".join(_e(e) for e in events) + ".</li>")


# ---------------------------------------------------------------- icon


def _seg_dist(px, py, x0, y0, x1, y1):
    dx, dy = x1 - x0, y1 - y0
    L2 = dx * dx + dy * dy
    s = 0.0 if L2 == 0 else max(0.0, min(1.0, ((px - x0) * dx + (py - y0) * dy) / L2))
    return math.hypot(px - x0 - s * dx, py - y0 - s * dy)


class _Canvas:
    """RGBA canvas with anti-aliased strokes and disks (coverage from the
    distance to the shape's edge), drawn in order over a background."""

    def __init__(self, size: int, background):
        self.size = size
        self.px = [[list(background) for _ in range(size)] for _ in range(size)]

    def _paint(self, box, dist, color):
        x0, y0, x1, y1 = (int(math.floor(box[0])), int(math.floor(box[1])),
                          int(math.ceil(box[2])), int(math.ceil(box[3])))
        r, g, b_, a = color
        for y in range(max(0, y0), min(self.size, y1 + 1)):
            row = self.px[y]
            for x in range(max(0, x0), min(self.size, x1 + 1)):
                cover = min(1.0, max(0.0, 0.5 - dist(x + 0.5, y + 0.5))) * a / 255
                if cover > 0:
                    p = row[x]
                    p[0] += (r - p[0]) * cover
                    p[1] += (g - p[1]) * cover
                    p[2] += (b_ - p[2]) * cover
                    p[3] += (255 - p[3]) * cover

    def line(self, x0, y0, x1, y1, width, color):
        h = width / 2
        box = (min(x0, x1) - h - 1, min(y0, y1) - h - 1, max(x0, x1) + h + 1, max(y0, y1) + h + 1)
        self._paint(box, lambda x, y: _seg_dist(x, y, x0, y0, x1, y1) - h, color)

    def polyline(self, points, width, color):
        for (x0, y0), (x1, y1) in zip(points, points[1:]):
            self.line(x0, y0, x1, y1, width, color)

    def disk(self, cx, cy, r, color):
        box = (cx - r - 1, cy - r - 1, cx + r + 1, cy + r + 1)
        self._paint(box, lambda x, y: math.hypot(x - cx, y - cy) - r, color)

    def ring(self, cx, cy, r, width, color):
        h, R = width / 2, r + width / 2
        box = (cx - R - 1, cy - R - 1, cx + R + 1, cy + R + 1)
        self._paint(box, lambda x, y: abs(math.hypot(x - cx, y - cy) - r) - h, color)

    def rounded_rect(self, x0, y0, x1, y1, radius, color):
        def dist(x, y):
            qx = max(x0 + radius - x, 0.0, x - (x1 - radius))
            qy = max(y0 + radius - y, 0.0, y - (y1 - radius))
            return math.hypot(qx, qy) - radius
        self._paint((x0 - 1, y0 - 1, x1 + 1, y1 + 1), dist, color)

    def png(self) -> bytes:
        raw = bytearray()
        for row in self.px:
            raw.append(0)  # filter type None
            for p in row:
                raw += bytes(max(0, min(255, int(round(c)))) for c in p)

        def chunk(kind: bytes, data: bytes) -> bytes:
            return (struct.pack(">I", len(data)) + kind + data
                    + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

        header = struct.pack(">IIBBBBB", self.size, self.size, 8, 6, 0, 0, 0)  # 8-bit RGBA
        return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                + chunk(b"IDAT", zlib.compress(bytes(raw), 9)) + chunk(b"IEND", b""))


INK = (40, 52, 70, 255)
BRASS = (196, 150, 52, 255)
AIR = (90, 150, 200, 255)
FAINT = (40, 52, 70, 90)


def _pendulum(c: _Canvas, angle=0.35, bob=BRASS, arc=True):
    px, py, length = 64.0, 20.0, 76.0
    bx, by = px + length * math.sin(angle), py + length * math.cos(angle)
    if arc:  # the swing
        pts = [(px + length * math.sin(a), py + length * math.cos(a))
               for a in [-0.5 + k * 0.05 for k in range(21)]]
        c.polyline(pts, 2.0, FAINT)
    c.line(44, 20, 84, 20, 4.0, INK)
    c.line(px, py, bx, by, 3.0, INK)
    c.disk(bx, by, 12.0, bob)
    c.ring(bx, by, 12.0, 2.0, INK)
    c.disk(px, py, 3.5, INK)


def _gear(c: _Canvas, cx=64.0, cy=64.0, r=30.0, teeth=15):
    for k in range(teeth):
        a = 2 * math.pi * k / teeth
        # Ratchet teeth: radial back, slanted front (an escape wheel).
        x0, y0 = cx + r * math.cos(a), cy + r * math.sin(a)
        x1, y1 = cx + (r + 12) * math.cos(a), cy + (r + 12) * math.sin(a)
        a2 = a + 2 * math.pi / teeth
        x2, y2 = cx + r * math.cos(a2), cy + r * math.sin(a2)
        c.line(x0, y0, x1, y1, 3.0, INK)
        c.line(x1, y1, x2, y2, 3.0, INK)
    c.disk(cx, cy, r, BRASS)
    c.ring(cx, cy, r, 3.0, INK)
    for k in range(4):  # spokes
        a = math.pi / 4 + k * math.pi / 2
        c.line(cx, cy, cx + (r - 2) * math.cos(a), cy + (r - 2) * math.sin(a), 3.0, INK)
    c.disk(cx, cy, 6.0, INK)


def _drag(c: _Canvas):
    _pendulum(c, angle=0.3, arc=False)
    for k, y in enumerate((72.0, 86.0, 100.0)):
        pts = [(14 + x, y + 3.0 * math.sin(0.35 * x + k)) for x in range(0, 44, 2)]
        c.polyline(pts, 2.5, AIR)


def _spring(c: _Canvas):
    c.line(20, 18, 108, 18, 4.0, INK)
    pts = [(64.0, 18.0), (64.0, 26.0)]
    for k in range(8):
        pts.append((50.0 if k % 2 == 0 else 78.0, 30.0 + 6.5 * k))
    pts += [(64.0, 84.0), (64.0, 90.0)]
    c.polyline(pts, 3.0, INK)
    c.rounded_rect(42, 90, 86, 112, 4, BRASS)
    for x in (42.0, 86.0):
        c.line(x, 90, x, 112, 2.0, INK)
    c.line(42, 90, 86, 90, 2.0, INK)
    c.line(42, 112, 86, 112, 2.0, INK)


def _averaged(c: _Canvas):
    # A decaying oscillation under its envelope: amplitude and phase.
    pts = [(14 + x, 64 - 36 * math.exp(-x / 70) * math.cos(x / 6.0)) for x in range(0, 101)]
    env = [(14 + x, 64 - 36 * math.exp(-x / 70)) for x in range(0, 101, 2)]
    env2 = [(14 + x, 64 + 36 * math.exp(-x / 70)) for x in range(0, 101, 2)]
    c.line(14, 64, 114, 64, 1.5, FAINT)
    c.polyline(env, 3.0, BRASS)
    c.polyline(env2, 3.0, BRASS)
    c.polyline(pts, 2.5, INK)


def _air(c: _Canvas):
    # A thermometer beside three streams of air.
    c.rounded_rect(88, 18, 102, 96, 7, (255, 255, 255, 255))
    c.line(95, 30, 95, 96, 5.0, (190, 60, 50, 255))
    c.disk(95, 102, 11.0, (190, 60, 50, 255))
    c.ring(95, 102, 11.0, 2.0, INK)
    for k, y in enumerate((36.0, 62.0, 88.0)):
        pts = [(14 + x, y + 5.0 * math.sin(0.3 * x + k)) for x in range(0, 62, 2)]
        c.polyline(pts, 3.0, AIR)


ICONS = {"pendulum": _pendulum, "escapement": _gear, "drag": _drag,
         "vibration": _spring, "averaged": _averaged, "air": _air}


def generate_png(kind: str, size: int = 128) -> bytes:
    c = _Canvas(size, (0, 0, 0, 0))
    c.rounded_rect(2, 2, size - 2, size - 2, 18, (246, 241, 228, 255))
    ICONS[kind](c)
    return c.png()
