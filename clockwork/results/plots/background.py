"""A scene's plots drawn by a second process that starts before the points run.

Importing matplotlib takes about a third of a second, longer than all 24
operating points of Ziemkiewicz Fig. 4(a), and each PNG takes about a
tenth more. ``Plotter.start(scene)`` forks a child that imports matplotlib
while this process loads the FMUs and runs the points. ``submit(results,
out)`` hands it the results; it draws every plot into `out` (each file
written atomically; several plots in parallel, one process per core, all
sharing the imported matplotlib) while this process writes the CSV files,
and ``collect()`` gives what ``make_plots`` would have returned here:
(files written, plots that failed, plots with nothing to draw, notes). The
results and the summary do not depend on where the plots were drawn.

`clockwork run` forks its plot process earlier still, at the command's
start, before numpy and clockwork's modules are imported (clockwork.cli):
the child imports them and matplotlib on the other core while this
process imports them too, and ``Plotter.start(scene, early)`` adopts it;
the scene then travels with the results. A scene without plots ends it
there.

The plots are drawn in this process instead when forking is not safe or
gains nothing: outside Linux, with other threads running, with matplotlib
already imported (the gallery after its first scene, the tests), or when
the scene has no plots (or does not pickle, for an early process). A
child that dies without an answer is reported on stderr and the plots are
drawn here.

The child ignores SIGINT, SIGTERM and SIGHUP (an interrupted run is the
parent's to report), dies with its parent (Linux prctl), never runs the
parent's atexit handlers (it leaves by os._exit), and is reaped by
``close``.
"""

from __future__ import annotations

import functools
import gc
import os
import pickle
import signal
import struct
import sys
from collections.abc import Mapping
from pathlib import Path

from ...atomic import remove_stale_parts
from ...errors import say
from ...processes import Child, die_with_parent, fork_child, fork_is_safe
from .outputs import recorded_view
from .raster import prepare as prepare_raster
from .registry import draw_plot, gather, load_matplotlib, make_plots


class Plotter:
    """Draws in this process (the fallback, and the interface)."""

    def __init__(self, scene):
        self.scene = scene
        self._job: tuple | None = None

    @staticmethod
    def start(scene, early: Child | None = None) -> "Plotter":
        """A plot process for `scene`: `early` (started by ``start_early``)
        when given, else one forked now; or this process, which then draws.
        An early process the scene does not need ends here."""
        if scene.plots:
            if early is not None:
                return _PlotProcess(scene, early, early=True)
            if _fork_is_worthwhile():
                try:
                    return _PlotProcess(scene, fork_child(functools.partial(serve, scene)), early=False)
                except OSError:  # no more processes or pipes: draw here
                    pass
        if early is not None:
            early.close()
        return Plotter(scene)

    def submit(self, results: list[dict], out: Path) -> None:
        """The results to draw, into the folder `out`."""
        self._job = (results, out)

    def collect(self) -> tuple[list[str], list[dict], list[dict]]:
        """(files written, plots that failed, plots with nothing to draw, notes), as make_plots."""
        results, out = self._job
        return make_plots(self.scene, results, out)

    def close(self) -> None:
        pass

    def __enter__(self) -> "Plotter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _fork_is_worthwhile() -> bool:
    return fork_is_safe() and "matplotlib.figure" not in sys.modules


class _PlotProcess(Plotter):
    def __init__(self, scene, child: Child, early: bool):
        super().__init__(scene)
        self._child = child
        self._early = early  # forked before the scene was loaded: the scene travels with the job
        self._drawn_here = False

    def submit(self, results, out):
        super().submit(results, out)
        fd = self._child.take_job_fd()
        try:
            data = pickle.dumps((_SceneOnDemand(self.scene, results) if self._early else None, results, str(out)),
                                protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # noqa: BLE001 (a scene that does not pickle: drawn here)
            os.close(fd)
            self._child.close()
            self._drawn_here = True
            return
        try:
            _write_all(fd, data)
        except OSError:
            pass  # the child is gone: collect says so and draws here

    def collect(self):
        if self._drawn_here:
            return super().collect()
        answer = None
        try:
            data = _read_all(self._child.take_answer_fd())
            answer = pickle.loads(data) if data else None
        except (OSError, pickle.UnpicklingError, EOFError):
            answer = None
        status = self._child.reap()
        if isinstance(answer, tuple) and len(answer) == 4:
            return answer
        why = (answer[1] if isinstance(answer, list) and len(answer) == 2 and answer[0] == "crashed"
               else _exit_reason(status))
        say("warning", f"the plot process ended without drawing ({why}); drawing here")
        remove_stale_parts(Path(self._job[1]))  # a file it was writing when it died
        return super().collect()

    def close(self) -> None:
        self._child.close()


def _exit_reason(status: int | None) -> str:
    if status is None:
        return "no exit status"
    if os.WIFSIGNALED(status):
        return f"killed by {signal.Signals(os.WTERMSIG(status)).name}"
    return f"exit status {os.WEXITSTATUS(status)}"


def serve(scene, parent: int, job_fd: int, answer_fd: int, default_plot_only: bool = False) -> None:
    """The plot process (processes.fork_child's body): import matplotlib,
    wait for the results, draw, answer. `scene` None: a process forked
    before the scene was loaded (clockwork.cli), which gets it with the
    results. `default_plot_only`: the run's one plot is its default plot
    (an FMU's run), drawn by Pillow (raster.py): Pillow is imported instead
    of matplotlib, and nothing else while it waits (matplotlib still comes
    on first use if Pillow cannot draw)."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)  # the run's to report; this process dies with it
    die_with_parent(parent)
    try:
        # The slow part, done while the parent computes. The collector would
        # walk the growing heap again and again during the import (a tenth of
        # its time); frozen afterwards, those objects stay out of later walks.
        gc.disable()
        if default_plot_only:
            prepare_raster()
        else:
            try:
                load_matplotlib(lean=True)
            except Exception:
                pass  # draw_plot reports it for each plot, as in the parent
            if scene is None:
                _import_while_waiting(job_fd)
        gc.freeze()
        gc.enable()
        job = _read_all(job_fd)
        if job:  # else the parent gave up
            sent, results, out = pickle.loads(job)
            scene = scene if sent is None else sent
            answer = gather(_draw_in_parallel(scene, results, Path(out), answer_fd))
            _write_all(answer_fd, pickle.dumps(answer, protocol=pickle.HIGHEST_PROTOCOL))
    except BaseException as e:  # noqa: BLE001 (the parent gets it; nothing may escape a forked child)
        try:
            _write_all(answer_fd, pickle.dumps(["crashed", f"{type(e).__name__}: {e}"]))
        except BaseException:  # noqa: BLE001
            pass
        raise


class _SceneOnDemand:
    """The scene as an early plot process gets it: what every plot reads
    (its plots, title and --set overrides) at once, the rest unpickled on
    first use. The whole scene holds fmpy's model descriptions and
    clockwork's scene classes: unpickling it imports fmpy and the engine,
    which a sweep's plots of result columns do without."""

    def __init__(self, scene, results: list[dict] | None = None):
        self.plots, self.title, self.overrides = scene.plots, scene.title, scene.overrides
        # A run's recorded columns as the outputs plot reads them (outputs.recorded_view),
        # computed here, where the engine is loaded: the plot process then draws
        # a run's default plot without fmpy, the engine and the whole scene.
        r = results[0] if results and len(results) == 1 and isinstance(results[0], dict) else None
        # the series in memory (a dict) or on disk (series.StreamedSeries): only its names are read
        names = [n for n in r["series"] if n != "time"] if r and isinstance(r.get("series"), Mapping) else None
        self.recorded_view = None
        if names is not None and any(p.get("kind") == "outputs" for p in scene.plots):
            info, strip = recorded_view(scene, names)
            self.recorded_view = (info, strip, frozenset(names))
        self._pickled: bytes | None = pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL)
        self._scene = None

    def __getattr__(self, name: str):  # only for the attributes not set above
        if name.startswith("_"):  # pickle's probes (__setstate__...), and ours before they are set
            raise AttributeError(name)
        if self._scene is None:
            self._scene, self._pickled = pickle.loads(self._pickled), None
        return getattr(self._scene, name)


# What an early plot process imports while it waits for the results, in
# this order, each checked for first: the whole scene's classes and the
# analyses' helpers that some plot kinds call (a long single run leaves
# time for all of them; Fig. 4(a)'s results come first). Small steps: one
# under way when the results come delays the drawing.
_IMPORTS_WHILE_WAITING = ("attr", "lxml.etree", "fmpy.model_description", "clockwork.fmi.description",
                          "clockwork.fmi.cs2", "clockwork.engine.master", "clockwork.engine.compiled",
                          "clockwork.scene.model", "clockwork.analyses")


def _import_while_waiting(job_fd: int) -> None:
    import importlib
    import select

    for name in _IMPORTS_WHILE_WAITING:
        if select.select([job_fd], [], [], 0)[0]:  # the results are there
            return
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001 (imported again where needed, and reported there)
            return


def _draw_in_parallel(scene, results: list[dict], out: Path, answer_fd: int) -> list[tuple[str, object]]:
    """Every plot's outcome (registry.draw_plot), in order: the plots dealt
    round-robin to this process and to forked helpers, one per core. The
    helpers share the imported matplotlib; a helper that fails has its
    plots drawn here."""
    n = len(scene.plots)
    ways = max(1, min(n, os.cpu_count() or 1))
    helpers = []
    for i in range(1, ways):
        plots = list(range(i, n, ways))
        try:
            helpers.append((plots, _start_helper(scene, results, out, plots, answer_fd)))
        except OSError:
            helpers.append((plots, None))
    outcomes = {k: draw_plot(scene, results, out, k) for k in range(0, n, ways)}
    for plots, helper in helpers:
        got = _helper_outcomes(helper) if helper else None
        if got is None or sorted(got) != plots:
            remove_stale_parts(out)  # what it was writing when it died
            got = {k: draw_plot(scene, results, out, k) for k in plots}
        outcomes.update(got)
    return [outcomes[k] for k in range(n)]


def _start_helper(scene, results, out: Path, plots: list[int], answer_fd: int) -> Child:
    """Fork a process that draws `plots` and answers with their outcomes."""
    def body(parent: int, job_fd: int, helper_answer_fd: int) -> None:
        os.close(job_fd)  # nothing is sent to it: it has what it draws
        os.close(answer_fd)  # the main process reads to its end: only the plot process holds it
        die_with_parent(parent)
        got = {k: draw_plot(scene, results, out, k) for k in plots}
        _write_all(helper_answer_fd, pickle.dumps(got, protocol=pickle.HIGHEST_PROTOCOL))

    helper = fork_child(body)  # a helper that fails exits 1: the plot process draws its plots instead
    os.close(helper.take_job_fd())
    return helper


def _helper_outcomes(helper: Child) -> dict | None:
    try:
        data = _read_all(helper.take_answer_fd())
        got = pickle.loads(data) if data else None
    except (OSError, pickle.UnpicklingError, EOFError):
        got = None
    helper.reap()
    return got if isinstance(got, dict) else None


# Messages carry their length: a pipe's end of file would also wait for
# every copy of its writing end, and a process forked later (a pool worker)
# holds copies until it exits.
_LENGTH = struct.Struct("<Q")


def _read_all(fd: int) -> bytes:
    """One message from `fd` (empty when the writer closed it without one); closes fd."""
    with os.fdopen(fd, "rb") as f:
        head = f.read(_LENGTH.size)
        if len(head) < _LENGTH.size:
            return b""
        (n,) = _LENGTH.unpack(head)
        data = f.read(n)
        if len(data) < n:
            raise EOFError(f"a message of {n} bytes ended after {len(data)}")
        return data


def _write_all(fd: int, data: bytes) -> None:
    """One message to `fd`; closes fd."""
    with os.fdopen(fd, "wb") as f:
        f.write(_LENGTH.pack(len(data)))
        f.write(data)
