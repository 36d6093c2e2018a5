"""The default plot's pages drawn with Pillow instead of matplotlib.

A run's default plot (kind ``outputs``, plots/outputs.py) is the first
thing a user of their own FMU waits for. matplotlib takes about a third of
a second to import and a quarter more to lay out and draw a page, more
than fmpy's whole run of the same FMU (docs/benchmarks.md, "The first run
of an FMU"); Pillow, which matplotlib itself depends on, imports in a
few hundredths and draws a page in a few more. The page is the same plot:
stacked axes sharing the time axis, ticks and grid, each axes' unit as its
y label, a legend beside it, the title above, "time (s)" below, discrete
signals as steps, Booleans on false/true, gaps where a value is not
finite. Text is drawn with matplotlib's own DejaVu Sans (its mpl-data
folder, found without importing matplotlib); without Pillow or that font
the pages are drawn by matplotlib as before (``available``).

Everything is drawn at twice the size and halved (smooth lines and text
without an antialiasing pass of its own); a series longer than the axes
are wide is drawn as each pixel column's least and greatest value, which
looks the same and costs the same for a million rows as for a thousand.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np

from ...atomic import write_bytes_atomic
from .registry import MAX_LABEL, MAX_TITLE, shown

DPI = 110  # as registry.PNG_DPI: the pages are the size matplotlib's were
_S = 2  # drawn at this multiple, then reduced
# matplotlib's default colour cycle ("tab10"), restarted on each axes as there
_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf")
_GRID = (217, 217, 217)
_NOTE_GREY = (89, 89, 89)


@functools.lru_cache(maxsize=1)
def _font_file() -> str | None:
    """matplotlib's DejaVu Sans, found without importing matplotlib."""
    import importlib.util

    try:
        spec = importlib.util.find_spec("matplotlib")
    except (ImportError, ValueError):
        return None
    for folder in (spec.submodule_search_locations or []) if spec else []:
        font = Path(folder) / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf"
        if font.is_file():
            return str(font)
    return None


@functools.lru_cache(maxsize=1)
def available() -> bool:
    """Whether pages can be drawn here: Pillow with FreeType, and the font."""
    if _font_file() is None:
        return False
    try:
        from PIL import Image, ImageDraw, ImageFont  # noqa: F401

        ImageFont.truetype(_font_file(), 10)
    except Exception:  # noqa: BLE001 (no Pillow, no FreeType, an unreadable font: matplotlib draws)
        return False
    return True


def prepare() -> None:
    """Import Pillow and load the fonts ahead of time (the plot process, while it waits)."""
    if available():
        for points in (7, 8, 9, 10):
            _font(points)


@functools.lru_cache(maxsize=None)
def _font(points: float):
    from PIL import ImageFont

    return ImageFont.truetype(_font_file(), round(points * DPI / 72 * _S))


def _px(inches: float) -> int:
    return round(inches * DPI * _S)


def _fit(text: str, font, width: float) -> str:
    """`text`, cut with an ellipsis to at most `width` drawn pixels."""
    if font.getlength(text) <= width:
        return text
    lo, hi = 0, len(text)
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if font.getlength(text[:mid] + "\u2026") <= width:
            lo = mid
        else:
            hi = mid - 1
    return text[:lo] + "\u2026"


def nice_ticks(lo: float, hi: float, most: int) -> list[float]:
    """As many round values (1, 2, 2.5, 5 times a power of ten apart) within
    [lo, hi] as there can be without passing `most`."""
    span = hi * 0.5 - lo * 0.5  # halved: no overflow between -1e308 and 1e308
    if not (math.isfinite(span) and span > 0):
        return [lo] if math.isfinite(lo) else []
    power = 2.0 * 10.0 ** math.floor(math.log10(span / max(1, most)))
    for step in (m * power * d for d in (0.05, 0.5, 5.0) for m in (1.0, 2.0, 2.5, 5.0)):
        if step == 0.0 or not math.isfinite(step):
            continue
        first, last = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
        if last - first + 1 <= most:
            ticks = [0.0 if k == 0 else k * step for k in range(first, last + 1)]
            return [t for t in ticks if math.isfinite(t)]
    return [lo, hi]


def _frac(v, lo: float, hi: float):
    """Where `v` is between `lo` (0) and `hi` (1); halved: no overflow."""
    return (v * 0.5 - lo * 0.5) / (hi * 0.5 - lo * 0.5)


def tick_labels(ticks: list[float]) -> tuple[list[str], str]:
    """The ticks' labels and an offset text ("1e-05": the labels are in those
    units) as matplotlib's scalar formatter shows them, roughly: plain
    decimals, a common power of ten for very large or small values."""
    if len(ticks) < 2:
        return [f"{t:g}".replace("-", "\u2212") for t in ticks], ""
    step = abs(ticks[1] * 0.5 - ticks[0] * 0.5) * 2.0
    biggest = max(abs(t) for t in ticks)
    exponent = 0
    if biggest >= 1e5 or biggest < 1e-3:
        exponent = max(-300, math.floor(math.log10(biggest)))
    scale = 10.0 ** -exponent
    decimals = max(0, -math.floor(math.log10(step * scale) + 1e-9))
    if round(step * scale * 10 ** decimals, 6) % 1:  # 2.5 times a power of ten
        decimals += 1
    labels = [f"{t * scale:.{decimals}f}".replace("-", "\u2212") for t in ticks]
    return [lb if lb.strip("\u22120.") else "0" + ("." + "0" * decimals if decimals else "") for lb in labels], \
        (f"1e{exponent}" if exponent else "")


def _limits(values: list[np.ndarray], boolean: bool = False) -> tuple[float, float]:
    """The axis' range: the finite values' with a margin of 5% each side
    (as matplotlib's), around a flat line 5% of its value (0.05 at 0)."""
    if boolean:
        return -0.15, 1.15
    finite = [v[np.isfinite(v)] for v in values]
    finite = [v for v in finite if v.size]
    if not finite:
        return -0.055, 0.055
    lo, hi = min(float(v.min()) for v in finite), max(float(v.max()) for v in finite)
    biggest = max(abs(lo), abs(hi))
    if hi * 0.5 - lo * 0.5 <= biggest * 1e-13 or hi - lo < 1e-300:  # flat, to the doubles' precision
        pad = biggest * 0.05 if biggest >= 1e-300 else 0.05  # subnormal: as zero
        return max(lo - pad, -_BIG), min(hi + pad, _BIG)
    pad = (hi * 0.5 - lo * 0.5) * 0.1
    return max(lo - pad, -_BIG), min(hi + pad, _BIG)


_BIG = float(np.finfo(float).max)


def _runs(t: np.ndarray, y: np.ndarray):
    """The stretches of (t, y) with finite values: lines break at gaps."""
    ok = np.isfinite(y) & np.isfinite(t)
    if ok.all():
        yield t, y
        return
    edges = np.flatnonzero(np.diff(ok.astype(np.int8)))
    starts = [0, *(edges + 1)]
    ends = [*(edges + 1), len(y)]
    for a, b in zip(starts, ends):
        if ok[a]:
            yield t[a:b], y[a:b]


def _path(x: np.ndarray, y: np.ndarray, steps: bool, width: int) -> np.ndarray:
    """Pixel vertices of a line: (x, y) as given, as steps (each value held
    until the next time), or, when there are more points than pixels,
    each pixel column's first, least, greatest and last value."""
    if len(x) > 2 * width:
        col = np.clip(x.astype(np.int64) - int(x[0]), 0, None)
        starts = np.flatnonzero(np.r_[True, np.diff(col) != 0])
        lo = np.minimum.reduceat(y, starts)
        hi = np.maximum.reduceat(y, starts)
        ends = np.r_[starts[1:], len(y)] - 1
        xs = np.repeat(x[starts], 4)
        xs[3::4] = x[ends]
        ys = np.empty(4 * len(starts))
        ys[0::4], ys[1::4], ys[2::4], ys[3::4] = y[starts], lo, hi, y[ends]
        return np.column_stack([xs, ys])
    if steps and len(x) > 1:
        xs = np.repeat(x, 2)[1:]
        ys = np.repeat(y, 2)[:-1]
        return np.column_stack([xs, ys])
    return np.column_stack([x, y])


def encode_png(img) -> bytes:
    """An RGB image as PNG bytes, its resolution DPI. Written here: Pillow's
    own ``save`` first imports its readers and writers of five formats (a
    tenth of a second on the first run's path)."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    w, h = img.size
    rows = np.frombuffer(img.tobytes(), dtype=np.uint8).reshape(h, 3 * w)
    # each row filtered "Sub" (its difference from the pixel to its left): a plot's
    # flat colours become runs of zeros
    diff = rows.copy()
    diff[:, 3:] -= rows[:, :-3]
    raw = np.empty((h, 3 * w + 1), dtype=np.uint8)
    raw[:, 0] = 1
    raw[:, 1:] = diff
    per_metre = round(DPI / 0.0254)
    return b"".join((b"\x89PNG\r\n\x1a\n", chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)),
                     chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1)),
                     chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)), chunk(b"IEND", b"")))


class RasterPage:
    """One page of the default plot: `axes`, a list of lists of
    outputs.Column (one list per axes), against `time` (s)."""

    def __init__(self, time, axes: list, title: str):
        self.time = np.asarray(time, dtype=float)
        self.axes = axes
        self.title = title
        self.footnote: str | None = None  # drawn small below the plot (a run's --set line)

    def png(self) -> bytes:
        from PIL import Image, ImageDraw

        f8, f9, f10 = _font(8), _font(9), _font(10)
        n = len(self.axes)
        width = _px(10.0)
        longest = max(f8.getlength(shown(c.name, MAX_LABEL)) for members in self.axes for c in members)
        legend_w = min(_px(2.4), round(longest) + _px(0.5))
        left, right = _px(0.95), width - legend_w - _px(0.12)
        top = _px(0.42)
        gap = _px(0.12)
        axes_h = _px(1.35) - gap
        bottom_of_axes = top + n * (axes_h + gap) - gap
        height = bottom_of_axes + _px(0.5) + (_px(0.2) if self.footnote else 0)
        img = Image.new("RGB", (width, height), "white")
        draw = ImageDraw.Draw(img)
        draw.text((width / 2, _px(0.12)), _fit(shown(self.title, MAX_TITLE), f10, width - _px(0.2)), fill="black",
                  font=f10, anchor="mt")

        t = self.time
        t0, t1 = _limits([t])
        xticks = nice_ticks(t0, t1, 9)
        x_of = lambda v: left + _frac(v, t0, t1) * (right - left)  # noqa: E731
        tick_len, line_w = _px(0.05), max(1, round(1.5 * _S))
        for i, members in enumerate(self.axes):
            y_top = top + i * (axes_h + gap)
            y_bot = y_top + axes_h
            boolean = members[0].kind == "boolean"
            lo, hi = _limits([c.values for c in members], boolean)
            y_of = lambda v, lo=lo, hi=hi, y_bot=y_bot: y_bot - _frac(v, lo, hi) * axes_h  # noqa: E731
            yticks = [0.0, 1.0] if boolean else nice_ticks(lo, hi, max(3, min(6, axes_h // _px(0.3))))
            ylabels, offset = (["false", "true"], "") if boolean else tick_labels(yticks)
            for v in xticks:
                draw.line([(x_of(v), y_top), (x_of(v), y_bot)], fill=_GRID, width=1)
            for v in yticks:
                draw.line([(left, y_of(v)), (right, y_of(v))], fill=_GRID, width=1)
            for v, label in zip(yticks, ylabels):
                y = y_of(v)
                draw.line([(left - tick_len, y), (left, y)], fill="black", width=_S)
                draw.text((left - tick_len - _S * 2, y), label, fill="black", font=f8, anchor="rm")
            for v in xticks:
                draw.line([(x_of(v), y_bot), (x_of(v), y_bot + tick_len)], fill="black", width=_S)
            if offset:
                draw.text((left, y_top - _S), offset, fill="black", font=f8, anchor="ld")
            unit = members[0].unit
            ylabel = "Boolean" if boolean else shown(unit, MAX_LABEL) if unit else "(no unit)"
            label_x = left - tick_len - _S * 4 - max(f8.getlength(lb) for lb in ylabels)
            self._vertical_text(img, ylabel, f8, label_x, (y_top + y_bot) / 2, axes_h)

            # the lines, clipped to the axes: drawn on a layer of the axes' size
            layer = Image.new("RGBA", (right - left, axes_h), (255, 255, 255, 0))
            pen = ImageDraw.Draw(layer)
            for k, c in enumerate(members):
                color = _COLORS[k % len(_COLORS)]
                for ts, ys in _runs(t, np.asarray(c.values, dtype=float)):
                    xs = _frac(ts, t0, t1) * (right - left)
                    yp = (1.0 - _frac(ys, lo, hi)) * axes_h
                    pts = _path(xs, yp, c.kind != "real", right - left)
                    if len(pts) == 1:
                        x, y = pts[0]
                        pen.ellipse([x - line_w, y - line_w, x + line_w, y + line_w], fill=color)
                    else:
                        pen.line(pts.ravel().tolist(), fill=color, width=line_w)
            img.paste(layer, (left, y_top), layer)
            draw.rectangle([left, y_top, right, y_bot], outline="black", width=_S)

            # the legend beside the axes
            # every line listed: the rows closer together where many lines share the axes
            row = min(round(f8.size * 1.45), (axes_h + gap) / len(members))
            x_leg = right + _px(0.1)
            for k, c in enumerate(members):
                y = y_top + row * k + row / 2
                draw.line([(x_leg, y), (x_leg + _px(0.25), y)], fill=_COLORS[k % len(_COLORS)], width=line_w)
                draw.text((x_leg + _px(0.32), y), _fit(shown(c.name, MAX_LABEL), f8, width - x_leg - _px(0.38)),
                          fill="black", font=f8, anchor="lm")
        xlabels, offset = tick_labels(xticks)
        for v, label in zip(xticks, xlabels):
            draw.text((x_of(v), bottom_of_axes + tick_len + _S * 2), label, fill="black", font=f8, anchor="mt")
        if offset:
            draw.text((right, bottom_of_axes + tick_len + _S * 2 + f8.size * 1.3), offset, fill="black",
                      font=f8, anchor="rt")
        draw.text(((left + right) / 2, bottom_of_axes + _px(0.24)), "time (s)", fill="black", font=f9, anchor="mt")
        if self.footnote:
            draw.text((_px(0.1), height - _px(0.18)), _fit(self.footnote, _font(7), width - _px(0.2)),
                      fill=_NOTE_GREY, font=_font(7), anchor="lt")
        return encode_png(img.reduce(_S))

    @staticmethod
    def _vertical_text(img, text: str, font, x_right: float, y_mid: float, room: int) -> None:
        from PIL import Image, ImageDraw

        text = _fit(text, font, room)
        w = max(1, math.ceil(font.getlength(text)))
        h = round(font.size * 1.3)
        mask = Image.new("L", (w, h), 0)
        ImageDraw.Draw(mask).text((0, h / 2), text, fill=255, font=font, anchor="lm")
        mask = mask.rotate(90, expand=True)
        img.paste((0, 0, 0), (round(x_right - mask.width), round(y_mid - mask.height / 2)), mask)

    def clear(self) -> None:
        """Let the columns go (as a matplotlib figure's ``clear``)."""
        self.axes = []

    def write_png(self, path: Path) -> None:
        """The page as a PNG file, written atomically."""
        write_bytes_atomic(Path(path), self.png())
