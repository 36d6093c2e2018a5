"""Coupling: what a dynamic instance is given as its inputs over a step.

Zero-order hold gives the sources' values at the step's start. With
extrapolation of order 1 or 2, each input is a polynomial in time handed
to the FMU through fmi2SetRealInputDerivatives: its derivatives come from
the source's output derivatives where the source offers them, else from
divided differences through the last few communication points. History is
forgotten across a discontinuity (an event, a changed parameter): values
from before it say nothing about the signal after it.

Strong coupling (``iterate_step``) repeats a step with the inputs
interpolated linearly between the step's start and the last iterate's
end, to a fixed point.
"""

from __future__ import annotations

from ctypes import c_double, c_int, c_uint
from dataclasses import dataclass, field

from ..errors import say
from .events import input_polynomial
from ..fmi.calls import WARNING
from .ports import Port


@dataclass
class _History:
    """Recent values of one instance's inputs, for finite differences."""

    times: list[float] = field(default_factory=list)
    values: list[list[float]] = field(default_factory=list)


class InputCoupling:
    def __init__(self, dynamic: list[Port], extrapolation: int):
        self.order = extrapolation
        self.dynamic = dynamic
        self.history = {p.inst.name: _History() for p in dynamic}
        # Filled by find_derivative_sources once the FMUs are initialized:
        # fmi2GetRealOutputDerivatives is not allowed before that.
        self.derivative_sources: dict = {}
        self.notes: list[str] = []  # orders lowered, said once each
        for p in dynamic:
            # fmi2SetRealInputDerivatives "has an effect" only where canInterpolateInputs.
            p.ext_order = extrapolation if p.inst.can_interpolate_inputs else 0
            if extrapolation and p.n_in and not p.inst.can_interpolate_inputs:
                self.note(f"{p.inst.name} cannot interpolate its inputs (canInterpolateInputs is false): "
                          f"zero-order hold for it instead of master.extrapolation = {extrapolation}")

    def note(self, text: str, kind: str = "warning") -> None:
        if text not in self.notes:
            self.notes.append(text)
            say(kind, text)

    def find_derivative_sources(self) -> None:
        """For each dynamic input: a source offering output derivatives, if any
        (asked of the FMU itself, after initialization)."""
        if not self.order:
            return
        found = {}
        for p in self.dynamic:
            for k, src, j in p.sources:
                got = derivative_source(src, j)
                if got is not None:
                    found[(p.inst.name, k)] = got
        self.derivative_sources = found

    def set_inputs(self, p: Port, t: float, h: float, smooth: bool,
                   coupling_end: tuple[list[float], list[float]] | None = None) -> None:
        """Inputs of a dynamic instance for the step from t.

        Sources that already stepped (Gauss-Seidel) hold values at t + h;
        with extrapolation the polynomial through them is re-anchored at t,
        which makes it an interpolation over the step. `smooth` is False
        right after a discontinuity: then zero-order hold.
        """
        if p.din_names:
            p.set_discrete()
        if not p.n_in:
            return
        inp = p.inp
        if coupling_end is not None:
            starts, coupling_end = coupling_end
            for k in range(p.n_in):
                inp[k] = starts[k]
            if p.scale:
                coupling_end = list(coupling_end)
                for k, f, o in p.scale:
                    inp[k] = f * inp[k] + o
                    coupling_end[k] = f * coupling_end[k] + o
        else:
            for k, src, j in p.sources:
                inp[k] = src.out[j]
            for k, src, j in p.adds:
                inp[k] += src.out[j]
            for k, f, o in p.scale:
                inp[k] = f * inp[k] + o
        polynomial = bool(p.ext_order) and smooth and coupling_end is None
        if polynomial:
            self._extrapolate(p, t)
        elif coupling_end is None and p.sent_valid and p.sent == inp[:p.n_in]:
            return  # held value unchanged: the FMU already has it
        st = p.setReal(p.comp, p.in_vr, p.n_in, inp)
        if st > WARNING:
            raise p.inst.fail(p.inst.named("setReal") + " of inputs", st, t)
        p.sent = inp[:p.n_in]
        p.sent_valid = not polynomial and coupling_end is None
        if coupling_end is not None:
            # Strong coupling: interpolate linearly towards the last iterate.
            if p.inst.can_interpolate_inputs:
                for k in range(p.n_in):
                    p.der[k] = (coupling_end[k] - inp[k]) / h
                    p.der[p.n_in + k] = 0.0
                self._set_derivatives(p, t, 1)
        elif polynomial and not self._set_derivatives(p, t, p.ext_order, refusable=True):
            # FMI 2.0 has no attribute for the highest input derivative an FMU takes:
            # refused, it gets one order lower, from the same sources, and never this order again.
            p.ext_order -= 1
            self.note(f"{p.inst.name} refused input derivatives of order {p.ext_order + 1} "
                      f"({p.inst.named('setInputDerivatives')}): order {p.ext_order} from t = {t!r} s on")
            self.set_inputs(p, t, h, smooth)

    @staticmethod
    def _set_derivatives(p: Port, t: float, order: int, refusable: bool = False) -> bool:
        """False when the FMU refused them and `refusable` (its messages are dropped)."""
        n = p.n_in * (2 if order >= 2 else 1)
        keep = len(p.inst.messages)
        st = p.inst.c_setInputDerivatives(p.comp, p.der_vr, n, p.der_order, p.der)
        if st > WARNING:
            if refusable and st < 4:  # not after fmi2Fatal
                del p.inst.messages[keep:]
                return False
            raise p.inst.fail(p.inst.named("setInputDerivatives"), st, t)
        return True

    def _extrapolate(self, p: Port, t: float) -> None:
        """Fill p.inp (values at t) and p.der (derivatives at t) from the sources."""
        order = p.ext_order
        hist = self.history[p.inst.name]
        n = p.n_in
        for k, (_, src, j) in enumerate(p.sources):
            ta, ua = src.out_time, src.out[j]
            d1 = d2 = 0.0
            dsrc = self.derivative_sources.get((p.inst.name, k))
            if not isinstance(src, Port):
                # A source of another rate, as passed at the last point both
                # share, with its polynomial there (engine/multirate.py).
                d1 = src.d1[j]
                d2 = src.d2[j] if order >= 2 else 0.0
            elif dsrc is not None:
                inst, vrs, orders, out, m = dsrc
                m = min(m, order)
                if inst.c_getOutputDerivatives(inst.component, vrs, m, orders, out) <= WARNING:
                    d1 = out[0]
                    d2 = out[1] if m == 2 else 0.0
            else:
                # Divided differences through the history and the current value.
                pts = [(tt, vv[k]) for tt, vv in zip(hist.times, hist.values) if tt < ta - 1e-15]
                d1, d2 = divided_differences(pts[-order:] + [(ta, ua)], order)
            dt = t - ta
            p.inp[k] = input_polynomial(ua, d1, d2, dt)
            p.der[k] = d1 + d2 * dt
            p.der[n + k] = d2
        for k, f, o in p.scale:
            p.inp[k] = f * p.inp[k] + o
            p.der[k] = f * p.der[k]
            p.der[n + k] = f * p.der[n + k]

    def forget(self) -> None:
        for hist in self.history.values():
            hist.times.clear()
            hist.values.clear()

    def record(self, t: float, after_discontinuity: bool, ports: list[Port] | None = None) -> None:
        """Remember the inputs' source values at the communication point t
        (of `ports`, where only some are at a point of their own: multi-rate)."""
        if not self.order:
            return
        if after_discontinuity:
            self.forget()
        for p in self.dynamic if ports is None else ports:
            if not p.n_in:
                continue
            hist = self.history[p.inst.name]
            hist.times.append(t)
            hist.values.append([src.out[j] for _, src, j in p.sources])
            if len(hist.times) > 3:
                del hist.times[0], hist.values[0]

    def snapshot(self) -> dict:
        return {n: (list(h.times), [list(v) for v in h.values]) for n, h in self.history.items()}

    def restore(self, snap: dict) -> None:
        for n, (times, values) in snap.items():
            self.history[n].times[:] = times
            self.history[n].values[:] = [list(v) for v in values]


def derivative_source(src: Port, j: int) -> tuple | None:
    """How to ask output j of `src` for its time derivatives (the FMU's
    own, where it offers them and the output has no direct feedthrough):
    (instance, value references, orders, buffer, highest order), or None."""
    inst = src.inst
    name = src.out_names[j]
    var = inst.variables[name]
    has_feed = var.dependencies is None or len(var.dependencies) > 0
    if has_feed or inst.max_output_derivative_order < 1 or inst.output_derivatives([name], 1) is None:
        return None
    m = 2 if inst.max_output_derivative_order >= 2 else 1
    return inst, (c_uint * 2)(var.vr, var.vr), (c_int * 2)(1, 2), (c_double * 2)(), m


def divided_differences(pts: list[tuple[float, float]], order: int) -> tuple[float, float]:
    """(du/dt, d2u/dt2) at the last of the points (time s, value), by
    divided differences through the last order + 1 of them (0 where too few)."""
    d1 = d2 = 0.0
    if len(pts) >= 2:
        (t1, u1), (t2, u2) = pts[-2], pts[-1]
        d1 = (u2 - u1) / (t2 - t1)
        if order >= 2 and len(pts) >= 3:
            t0, u0 = pts[-3]
            d0 = (u1 - u0) / (t1 - t0)
            d2 = 2.0 * (d1 - d0) / (t2 - t0)
            d1 += 0.5 * d2 * (t2 - t1)
    return d1, d2


def iterate_step(master, t: float, h: float) -> None:
    """Strong coupling: the step repeated on the dynamic-to-dynamic inputs
    until they reach a fixed point (or the iteration budget is spent)."""
    s = master.settings
    dynamic = master.ports.dynamic
    starts = {p.inst.name: [src.out[j] for _, src, j in p.sources] for p in dynamic if p.n_in}
    master.advance(t, h)
    for _ in range(s.iterations):
        ends = {p.inst.name: (starts[p.inst.name], [src.out[j] for _, src, j in p.sources])
                for p in dynamic if p.n_in}
        master.checkpoints.rollback()
        master.advance(t, h, coupling=ends)
        master.stats.coupling_iterations += 1
        change = max(
            (abs(src.out[j] - ends[p.inst.name][1][k]) for p in dynamic if p.n_in
             for k, (_, src, j) in enumerate(p.sources)),
            default=0.0,
        )
        if change <= s.iteration_tolerance:
            break
