"""Event location: find where an event indicator crosses zero inside a step.

Each escapement declares event indicators: outputs that cross zero exactly
where its torque switches (modelDescription vendor annotation). After each
step the master compares their signs at the step's two ends (``scan``).
When one changed, every FMU is rolled back and the step is shortened to
land just past the earliest crossing (``locate``):

1. the first trial comes from a Hermite interpolant of the lead indicator,
   its derivatives taken from the output derivatives of the single
   connected output it depends on (the pendulum's dphi/dt = w): quintic
   when the source also gives second derivatives, else cubic;
2. after each trial, a Newton step from the indicator there (second order
   when the source gives second derivatives), aimed a hair past the root
   in time, gives the next trial;
3. the crossing stays bracketed; Illinois iteration takes over when Newton
   has nothing to offer, until the bracket is within the time tolerance or
   the indicator within its own tolerance.

Two crossings inside one step cancel at its ends; ``hidden_crossing``
finds them from the same interpolant. The interpolation is reliable up to
about a quarter of the source's oscillation period, which therefore caps
the step (``remember_sources``).
"""

from __future__ import annotations

import math
from ctypes import c_double, c_int, c_uint

from ..errors import SimulationError
from .events import (PREDICTION_HORIZON, Illinois, crossed, earliest, extrapolants, first_root, hermite_extremum,
                     hermite_root, slope_at)
from ..fmi.calls import WARNING
from ..fmi.contract import Instance
from .ports import Port, feeds

_ORDER_ONE = (c_int * 1)(1)
_ORDER_TWO = (c_int * 1)(2)
_ORDERS_ONE_TWO = (c_int * 2)(1, 2)


# What a predicted step is (EventLocator.plan): free of crossings, short of
# the predicted crossing, or just past it.
CLEAR, APPROACH, LAND = 1, 2, 3


def scan(z0: list[float], z1: list[float], h: float) -> float:
    """-1 when an indicator changed sign over the step of h s; else the
    time, s, until the nearest one would reach zero at its rate over the
    step, in either direction (a turn-around is also a risk)."""
    steps = math.inf
    for a, b in zip(z0, z1):
        if (a > 0.0 and b <= 0.0) or (a < 0.0 and b >= 0.0):
            return -1.0
        dist = abs(b)
        if dist <= 1e-15:
            return 0.0
        change = abs(b - a)
        if dist < steps * change:
            steps = dist / change
    return steps * h


class EventLocator:
    def __init__(self, master, ports: list[Port]):
        self.master = master
        self.ports = [p for p in ports if p.z_pos]
        self.spans = [(p.z_pos[0], p.z_pos[-1] + 1, p.out) for p in self.ports]
        self.active = bool(self.ports)
        self.z_start: list[float] = []  # indicators at t+ of the step (after a mode commit)
        self.z_end: list[float] = []  # indicators at the step's end
        # Time until the nearest indicator reaches zero at its last rate of
        # change, s; 0 = unknown (after an event), so the next step checks.
        self.time_to_zero = 0.0
        self.sources = self._indicator_sources()
        self.has_sources = any(x is not None for x in self.sources)
        # Per indicator: an earlier indicator with the same source output, or None.
        self._same_source = [next((j for j in range(k) if self.sources[j] is not None and info is not None
                                   and self.sources[j][0] is info[0] and self.sources[j][3][0] == info[3][0]),
                                  None) for k, info in enumerate(self.sources)]
        self._two = ((c_uint * 2)(), (c_double * 2)())  # one call for d/dt and d2/dt2
        self.sample_countdown = 0
        self.located_from = 0.0  # where the last located step started, s
        self._rate = (c_double * 1)()  # per locator: masters may run in threads
        self.reset()

    def reset(self) -> None:
        """Forget the sources' past (a new start, a reset)."""
        self.sources_prev = None  # [(u, du/dt) or None] per indicator at the last sample
        self.amplitudes = [(0.0, 0.0)] * len(self.sources)  # slowly forgotten max |u|, max |du/dt|
        self.z_seen = [None] * len(self.sources)
        self.step_cap = math.inf  # s
        self.end_rates = {}  # indicator -> d(source)/dt at the step's end
        self.stale_sources = False
        # Prediction: the sources (u, du/dt, d2u/dt2 or None) per indicator
        # at the last two step starts that were sampled, and the last step
        # (its start, s, and the indicators at its start) when no event ended it.
        self.sampled = self.sampled_before = None
        self.sampled_t = self.sampled_before_t = math.nan
        self.last_step = None

    def forget_end_rates(self) -> None:
        if self.end_rates:
            self.end_rates = {}

    def indicators(self) -> list[float]:
        if len(self.spans) == 1:
            a, b, out = self.spans[0]
            return out[a:b]
        z = []
        for a, b, out in self.spans:
            z += out[a:b]
        return z

    # -- the sources the indicators follow ---------------------------------

    def _indicator_sources(self) -> list:
        """Per indicator: (source port, position, instance, vr) of the single
        connected output it depends on, when that output offers a time
        derivative and does not itself depend on inputs; else None."""
        found = []
        for p in self.ports:
            summed = {k for k, _, _ in p.adds}
            for k in p.z_pos:
                name = p.out_names[k]
                deps = p.inst.variables[name].dependencies or []
                info = None
                # a summed input (Link.adds) has no one source to predict from
                if len(deps) == 1 and deps[0] in p.in_names and p.in_names.index(deps[0]) not in summed:
                    k_in = p.in_names.index(deps[0])
                    for kk, src, j in p.sources:
                        if kk == k_in:
                            var = src.inst.variables[src.out_names[j]]
                            if src.inst.max_output_derivative_order >= 1 and not feeds(src.inst, var.name):
                                info = (src, j, src.inst, (c_uint * 1)(var.vr))
                found.append(info)
        return found

    def output_rate(self, inst: Instance, vr, order: int = 1) -> float | None:
        out = self._rate
        orders = _ORDER_ONE if order == 1 else _ORDER_TWO
        if inst.c_getOutputDerivatives(inst.component, vr, 1, orders, out) > WARNING:
            return None
        return out[0]

    def slope_source(self, k: int):
        """For indicator k: ((u, du/dt, d2u/dt2 or None) now, source port,
        position, instance, vr) of its source, when that offers a time
        derivative; else None."""
        info = self.sources[k]
        if info is None:
            return None
        src, pos, inst, vr = info
        rate = self.output_rate(inst, vr)
        if rate is None:
            return None
        acc = self.output_rate(inst, vr, order=2) if inst.max_output_derivative_order >= 2 else None
        return (src.out[pos], rate, acc), src, pos, inst, vr

    def remember_sources(self) -> None:
        """Values and rates of the indicators' source outputs at this point.

        They also bound the step: the hidden-crossing check interpolates over
        a step, which is reliable up to about a quarter of the source's
        oscillation period, estimated as 2 pi max|u| / max|du/dt| over the
        recent past (slowly forgotten).
        """
        mem = []
        cap = math.inf
        for k, info in enumerate(self.sources):
            if info is None:
                mem.append(None)
                continue
            src, pos, inst, vr = info
            u = src.out[pos]
            z_now = self.z_end[k] if k < len(self.z_end) else None
            constant = z_now is not None and z_now == self.z_seen[k]
            self.z_seen[k] = z_now
            if constant:
                # An indicator that did not move says nothing about its
                # source's time scale, and has no hidden crossing to look for.
                mem.append((u, None))
                continue
            du = self.end_rates.get(k)
            second = inst.max_output_derivative_order >= 2 and u != 0.0
            acc = None
            if du is None:
                # Both derivatives in one call where both are wanted.
                du, acc = self.output_rates(inst, vr) if second else (self.output_rate(inst, vr), None)
            mem.append((u, du))
            if du is not None:
                amp_u, amp_du = self.amplitudes[k]
                amp_u = max(abs(u), 0.999 * amp_u)
                amp_du = max(abs(du), 0.999 * amp_du)
                self.amplitudes[k] = (amp_u, amp_du)
                omega = amp_du / amp_u if amp_u > 0.0 else 0.0
                # At a turning point |du| says nothing yet; |d2u/dt2| / |u| does.
                if second:
                    if acc is None:
                        acc = self.output_rate(inst, vr, order=2)
                    if acc is not None:
                        omega = max(omega, math.sqrt(abs(acc / u)))
                if omega > 0.0:
                    cap = min(cap, 0.2 * 2 * math.pi / omega)
        self.sources_prev = mem
        self.step_cap = cap
        self.end_rates = {}

    def hidden_crossing(self, h: float, z0: list[float], z1: list[float]) -> float | None:
        """Offset of an indicator's extremum inside the step, when its Hermite
        interpolant (slopes from the source outputs' derivatives) changes
        sign there although z has the same sign at both ends; else None."""
        prev = self.sources_prev
        if prev is None:
            return None
        best = None
        for k, info in enumerate(self.sources):
            if info is None or prev[k] is None or prev[k][1] is None:
                continue
            src, pos, inst, vr = info
            u0, du0 = prev[k]
            u1 = src.out[pos]
            if u1 == u0 or z0[k] == 0.0:
                continue
            ratio = (z1[k] - z0[k]) / (u1 - u0)
            dz0 = ratio * du0
            if z0[k] * dz0 >= 0.0:
                continue  # moving away from zero at the start: no early crossing
            du1 = self.output_rate(inst, vr)
            if du1 is None:
                continue
            self.end_rates[k] = du1
            dz1 = ratio * du1
            if z1[k] * dz1 <= 0.0:
                continue  # still approaching at the end: no turn inside the step
            x = hermite_extremum(h, z0[k], dz0, z1[k], dz1)
            if x is not None and (best is None or x < best):
                best = x
        return best

    # -- prediction -----------------------------------------------------------

    def output_rates(self, inst: Instance, vr) -> tuple[float | None, float | None]:
        """(du/dt, d2u/dt2) of a source output, in one call where the FMU
        offers both; None for what it refuses."""
        if inst.max_output_derivative_order >= 2:
            two = self._two
            two[0][0] = two[0][1] = vr[0]
            if inst.c_getOutputDerivatives(inst.component, two[0], 2, _ORDERS_ONE_TWO, two[1]) <= WARNING:
                return two[1][0], two[1][1]
        return self.output_rate(inst, vr), None

    def sample(self, t: float) -> None:
        """The sources' values and derivatives here, at t (for plan); an
        output that is the source of several indicators is asked once."""
        self.sampled_before, self.sampled_before_t = self.sampled, self.sampled_t
        now = []
        for k, info in enumerate(self.sources):
            if info is None:
                now.append(None)
                continue
            src, pos, inst, vr = info
            same = self._same_source[k]
            if same is not None:
                now.append(now[same])
                continue
            rate, acc = self.output_rates(inst, vr)
            now.append(None if rate is None else (src.out[pos], rate, acc))
        self.sampled, self.sampled_t = now, t

    def plan(self, t: float, h: float) -> tuple[int, float] | None:
        """Before the step from t of h s: (kind, step) when every indicator's
        next crossing can be predicted from the Hermite polynomial through
        the last step (the sources' values and derivatives at its two ends,
        the indicator affine in its source), else None.

        CLEAR: no crossing in the step; APPROACH: a crossing, but predicted
        too coarsely to land on: stop short of it by twice the estimated
        error; LAND: a step just past it, as close as locate would land.
        """
        last = self.last_step
        if last is None or self.sampled_t != t or self.sampled_before_t != last[0]:
            return None
        t_a, z_a = last
        span = t - t_a
        if not span > 0.0:
            return None
        s = self.master.settings
        z_b = self.z_end
        kind, step = CLEAR, h
        for k in range(len(z_b)):
            if z_a[k] == z_b[k]:
                continue  # an indicator that did not move does not cross by moving
            now, before = self.sampled[k], self.sampled_before[k]
            if now is None or before is None or z_b[k] == 0.0:
                return None
            u1, du1, ddu1 = now
            u0, du0, ddu0 = before
            if u1 == u0:
                return None
            ratio = (z_b[k] - z_a[k]) / (u1 - u0)  # dz/du: affine near the crossing
            second = ddu0 is not None and ddu1 is not None
            high, low = extrapolants(span, z_a[k], ratio * du0, z_b[k], ratio * du1,
                                     ratio * ddu0 if second else None, ratio * ddu1 if second else None)
            y_max = min(h / span, PREDICTION_HORIZON)
            y_high, y_low = first_root(high, y_max), first_root(low, y_max)
            if y_high is None:
                if y_low is not None or h / span > PREDICTION_HORIZON:
                    return None
                continue  # clear of this indicator
            if y_low is None:
                return None
            at = y_high * span
            err = abs(at - y_low * span)
            rate = slope_at(high, y_high) / span
            past = 0.25 * s.event_time_tolerance
            if rate != 0.0:
                past = min(past, 0.25 * s.event_indicator_tolerance / abs(rate))
            if 2.0 * err <= past and at + past <= h:
                this, mine = LAND, at + past
            elif 2.0 * err < 0.95 * at:
                this, mine = APPROACH, at - 2.0 * err
            else:
                return None
            if mine < step:
                kind, step = this, mine
        # A step must move the FMUs' clock.
        if (t + step) - t < 8 * math.ulp(abs(t) + step + 1.0):
            return None
        return kind, step

    # -- locating ------------------------------------------------------------

    def time_tolerance(self, t: float, h: float) -> float:
        """How close locate brackets a crossing in the step from t of h s:
        far from t = 0 a double cannot resolve the tolerance, so a few ulps."""
        return max(self.master.settings.event_time_tolerance, 4 * math.ulp(abs(t) + h))

    def locate(self, t: float, h: float, crossings: list[bool], z0: list[float], z1: list[float]) -> float:
        """Shorten the step from t (a checkpoint) to land just past the
        earliest crossing; returns the step taken, s."""
        m = self.master
        s = m.settings
        checkpoints = m.checkpoints
        # The indicator whose linear interpolant crosses first leads.
        lead = earliest(crossings, z0, z1)
        slope_end = self.slope_source(lead)
        checkpoints.rollback()
        first = None
        newton = None  # (ratio dz/du, instance, vr, indicator) for Newton steps after each trial
        if slope_end is not None:
            (u1, du1, ddu1), src, pos, inst, vr = slope_end
            u0, du0 = src.out[pos], self.output_rate(inst, vr)
            ddu0 = self.output_rate(inst, vr, order=2) if ddu1 is not None else None
            if du0 is not None and u1 != u0:
                # The indicator is affine in its source near the crossing: z' = ratio u'.
                ratio = (z1[lead] - z0[lead]) / (u1 - u0)
                curvature = ddu0 is not None and ddu1 is not None
                first = hermite_root(h, z0[lead], ratio * du0, z1[lead], ratio * du1,
                                     ratio * ddu0 if curvature else None, ratio * ddu1 if curvature else None)
                newton = (ratio, inst, vr, lead, curvature)
        search = Illinois(0.0, z0[lead], h, z1[lead])
        hi, z_hi = h, list(z1)
        z_lo = list(z0)
        base = 0.0  # offset from t of the checkpoint the trials start from
        last = None  # the FMUs stand at the checkpoint after the rollback above
        time_tol = self.time_tolerance(t, h)
        while True:
            if hi - search.lo <= time_tol or abs(z_hi[lead]) <= s.event_indicator_tolerance:
                break
            trial, first = (first, None) if first is not None else (search.next(), None)
            if not (search.lo < trial < hi):
                trial = 0.5 * (search.lo + hi)
            # A trial must move the FMUs' clock: at least a few ulps past lo.
            min_move = 8 * math.ulp(abs(t) + abs(hi) + 1.0)
            if (t + trial) - (t + search.lo) < min_move:
                trial = search.lo + min(0.5 * (hi - search.lo), max(min_move, 0.25 * s.event_time_tolerance))
            if last is not None:
                checkpoints.rollback()
            m.advance(m.t, (t + trial) - m.t)
            m.stats.event_iterations += 1
            last = trial
            z = self.z_end
            if newton is not None and newton[3] == lead:
                # Newton from this trial (second order when the source gives
                # d2u/dt2), with dz/dt = (dz/du) du/dt, aimed a hair past the
                # root in time, whichever side of it the trial landed on.
                ratio, inst, vr, _, curvature = newton
                rate = self.output_rate(inst, vr)
                if rate:
                    slope = ratio * rate
                    delta = -z[lead] / slope
                    acc = self.output_rate(inst, vr, order=2) if curvature else None
                    if acc is not None:
                        # Root of z + z' d + z'' d^2 / 2 nearest to the trial, in a form without cancellation.
                        bend = ratio * acc
                        disc = slope * slope - 2.0 * z[lead] * bend
                        if disc >= 0.0:
                            delta = -2.0 * z[lead] / (slope + math.copysign(math.sqrt(disc), slope))
                    past = min(0.25 * s.event_time_tolerance, 0.25 * s.event_indicator_tolerance / abs(slope))
                    first = trial + delta + past
            now = [crossed(a, b) for a, b in zip(self.z_start, z)]
            if any(now):
                earlier = [k for k, c in enumerate(now) if c]
                if lead not in earlier:
                    # Another indicator crosses first: restart on it.
                    lead = min(earlier, key=lambda k: z_lo[k] / (z_lo[k] - z[k]))
                    search = Illinois(search.lo, z_lo[lead], trial, z[lead])
                    first = None
                else:
                    search.update(trial, z[lead], crossed=True)
                hi, z_hi = trial, list(z)
            else:
                search.update(trial, z[lead], crossed=False)
                # Later trials start here: no need to integrate [t, t + trial] again.
                z_lo = list(z)
                checkpoints.mark()
                base, last = trial, None
            if search.iterations > 200:
                raise SimulationError(
                    f"event location did not converge in (t, t+h) = ({t!r}, {t + h!r}) s", time=t)
        if last != hi:
            if last is not None:
                checkpoints.rollback()
            m.advance(m.t, (t + hi) - m.t)
        if base > 0.0:
            checkpoints.since = []
        self.located_from = t + base
        m.stats.events += 1
        return hi
