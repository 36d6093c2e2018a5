"""Algebraic loops: instances whose direct-feedthrough outputs feed each other.

The wiring finds each loop (a strongly connected component of the
feedthrough graph); a ``Loop`` stands in the ports' update orders where its
members would, and ``pull`` brings them up to date at a communication point.

``master.algebraic_loops = "solve"``: the loop's inputs are iterated to a
fixed point, by setting inputs and getting outputs with no step. FMI 2.0
and 3.0 allow that in Initialization Mode; between steps only where the
FMU declares it (``Instance.outputs_after_inputs``, docs/master.md "The
call sequence"): a loop with a member that does not is solved in
Initialization Mode only and delayed in the steps (``solve_in_init``).
FMI 1.0 Co-Simulation has no Initialization Mode: what stands for it is
the FMI 1.0 instance's own face (a step of size 0 before a get after a
set); the loop only calls the port's set and get. First plain fixed-point iteration: Gauss-Seidel sweeps over
the members (each takes its inputs from the newest outputs), until every
loop input differs from what its source now gives by at most
``iteration_tolerance * max(1, |input|)``; a loop whose residual stops
shrinking (a loop gain above one) or that has not converged after
``PLAIN_SWEEPS`` sweeps goes to Newton's method on the same residual,
r(x) = g(x) - x over the loop's Real inputs x (g: what their sources give
when x is set), with a forward-difference Jacobian and step halving. A loop
that does not converge fails the run (``SimulationError``, one line naming
the loop and the time). Integer and Boolean links in a loop take part in
the plain iteration (converged when equal); Newton's method cannot iterate
them, so such a loop has no fallback.

``"delay"``: the members are stepped as dynamic instances and read once,
after their step, so that what a member gives reaches the others one step
late, as libcosim and ecos do with every link. They start as libcosim
does: in Initialization Mode the members' outputs are read with the inputs
they start with, then ``len(instances)`` Jacobi sweeps (each computes every
member's inputs from the outputs of the sweep before, then sets them and
reads the outputs) of which the last sets the inputs without reading; the
outputs are read again after Initialization Mode. (The master starts them
in its second sweep over the system, once every output feeding the loop
has been read.)

``src_c/master/cw_loops.c`` solves loops in its steps the same way
(``loop_solve``), operation for operation; initialization is Python's in
both engines.
"""

from __future__ import annotations

from ..errors import SimulationError
from ..fmi.calls import WARNING

PLAIN_SWEEPS = 50  # fixed-point sweeps before the Newton fallback
NEWTON_ITERATIONS = 20
HALVINGS = 10  # step halvings along one Newton direction
FD_STEP = 2.0 ** -26  # forward-difference step, relative to max(1, |x|) (about sqrt of the machine epsilon)

# Why a loop failed (the compiled core returns the same codes).
NOT_CONVERGED, SINGULAR, NO_DECREASE, DISCRETE, NO_MEMORY = 0, 1, 2, 3, 4


class Loop:
    """One algebraic loop: its member ports, in instance order, and its unknowns."""

    def __init__(self, owner, name: str, members: list, unknowns: list, discrete: list, mode: str,
                 start_sweeps: int):
        self.owner = owner  # the master: its settings, and count_loop for the statistics
        self.name = name
        self.members = members
        # The Real inputs fed from inside the loop: (port, input position,
        # source port, source output position (a sum's first term: Port.adds has
        # the others), factor, offset, scaled).
        self.unknowns = unknowns
        self.n = len(unknowns)
        # The discrete ones: (port, input name, source port, position in the source's dout, link text, type).
        self.discrete = discrete
        self.mode = mode
        self.start_sweeps = start_sweeps
        self.starting = False  # "delay": the next pull is the peers' start in Initialization Mode
        # "solve" asked for, with a member whose outputs may not be read after
        # its inputs are set without a step: solved in Initialization Mode,
        # delayed in the steps (Ports.initializing switches the mode).
        self.solve_in_init = False

    def pull(self, t: float) -> None:
        """Bring the members' outputs up to date at t."""
        if self.mode == "solve":
            self.solve(t)
        elif self.starting:
            self.starting = False
            self._start(t)
        else:
            for p in self.members:
                p.read(t)

    # -- "delay" ---------------------------------------------------------------

    def _start(self, t: float) -> None:
        members = self.members
        for p in members:
            p.read(t)
        for sweep in range(self.start_sweeps):
            # Jacobi: every member's inputs from the outputs before the sweep.
            for p in members:
                p.pull(t, read=False)
            if sweep < self.start_sweeps - 1:
                for p in members:
                    p.read(t)

    # -- "solve" ---------------------------------------------------------------

    def _residual(self, x: list | None, r: list) -> tuple[float, int]:
        """r = what the sources give minus the inputs (x, else those set);
        returns the largest |r| and where (-1: none larger than zero)."""
        worst, at = 0.0, -1
        for i, (p, k, src, j, f, o, scaled) in enumerate(self.unknowns):
            g = src.out[j]
            for kk, term, jj in p.adds:  # a sum's further terms, in order (Port.pull)
                if kk == k:
                    g += term.out[jj]
            if scaled:
                g = f * g + o
            r[i] = g - (p.inp[k] if x is None else x[i])
            a = abs(r[i])
            if a > worst or a != a:
                worst, at = a, i
        return worst, at

    def _small(self, r: list) -> bool:
        tol = self.owner.settings.iteration_tolerance
        for i, (p, k, _, _, _, _, _) in enumerate(self.unknowns):
            if not abs(r[i]) <= tol * max(1.0, abs(p.inp[k])):
                return False
        return all(src.dout[j] == p.din_sent.get(name) for p, name, src, j, _, _ in self.discrete)

    def solve(self, t: float) -> None:
        members = self.members
        r = [0.0] * self.n
        prev = float("inf")
        worst, at, sweeps = 0.0, -1, 0
        while sweeps < PLAIN_SWEEPS:
            for p in members:
                p.pull(t)
            sweeps += 1
            worst, at = self._residual(None, r)
            if self._small(r):
                self.owner.count_loop(sweeps, 0)
                return
            if not worst < prev and not self.discrete:
                break  # not contracting: growing, stalled or NaN (with discrete links: no fallback to go to)
            prev = worst
        self.owner.count_loop(sweeps, 0)
        if self.discrete:
            raise self.failure(t, DISCRETE, worst, at, sweeps, 0)
        self.owner.count_loop(0, 1)
        try:
            self._newton(t, sweeps)
        except MemoryError:
            raise self.failure(t, NO_MEMORY, worst, -1, sweeps, 0) from None

    def _evaluate(self, x: list, r: list, t: float) -> tuple[float, int]:
        """Set the loop's inputs to x, read the members' outputs; r = g(x) - x."""
        for i, (p, k, _, _, _, _, _) in enumerate(self.unknowns):
            p.inp[k] = x[i]
        for p in self.members:
            if p.n_in:
                st = p.setReal(p.comp, p.in_vr, p.n_in, p.inp)
                if st > WARNING:
                    raise p.inst.fail(p.inst.named("setReal") + " of inputs", st, t)
                p.sent_valid = False
            p.read(t)
        return self._residual(x, r)

    def _newton(self, t: float, sweeps: int) -> None:
        n = self.n
        x = [p.inp[k] for p, k, _, _, _, _, _ in self.unknowns]
        r = [0.0] * n
        rj = [0.0] * n
        jac = [0.0] * (n * n)
        worst, at = self._evaluate(x, r, t)
        iterations = 0
        while not self._small(r):
            if iterations == NEWTON_ITERATIONS:
                raise self.failure(t, NOT_CONVERGED, worst, at, sweeps, iterations)
            iterations += 1
            self.owner.count_loop(1, 0)
            for j in range(n):
                xj = x[j]
                x[j] = xj + FD_STEP * max(1.0, abs(xj))
                d = x[j] - xj
                self._evaluate(x, rj, t)
                x[j] = xj
                for i in range(n):
                    jac[i * n + j] = (rj[i] - r[i]) / d
            dx = [-v for v in r]
            if not solve_linear(jac, dx, n):
                raise self.failure(t, SINGULAR, worst, at, sweeps, iterations)
            lam = 1.0
            xn = [0.0] * n
            for _ in range(HALVINGS):
                for i in range(n):
                    xn[i] = x[i] + lam * dx[i]
                worst_n, at_n = self._evaluate(xn, rj, t)
                if worst_n < worst:
                    break
                lam *= 0.5
            else:
                raise self.failure(t, NO_DECREASE, worst, at, sweeps, iterations)
            x, xn = xn, x
            r, rj = rj, r
            worst, at = worst_n, at_n

    def failure(self, t: float, why: int, worst: float, at: int, sweeps: int, newton: int) -> SimulationError:
        """The one line for a loop that did not converge (both engines)."""
        tol = self.owner.settings.iteration_tolerance
        where = ""
        if 0 <= at < self.n:
            p, k = self.unknowns[at][0], self.unknowns[at][1]
            where = f" at {p.inst.name}.{p.in_names[k]}"
        done = f"{sweeps} fixed-point sweep{'s' * (sweeps != 1)}"
        if newton:
            done += f" and {newton} Newton iteration{'s' * (newton != 1)}"
        if why == DISCRETE:
            changing = [(p.din_sent.get(name), src.dout[j], text, kind)
                        for p, name, src, j, text, kind in self.discrete if src.dout[j] != p.din_sent.get(name)]
            if changing:
                sent, now, text, kind = changing[0]
                what = (f"its {kind} link {text} still changes ({sent!r} -> {now!r}) after {done}, "
                        f"and the Newton fallback cannot iterate {kind} links")
            else:
                _, _, _, _, text, kind = self.discrete[0]
                what = (f"residual {worst:.6g}{where} after {done}; its {kind} link {text} rules out "
                        f"the Newton fallback")
        elif why == SINGULAR:
            what = f"the Newton fallback met a singular Jacobian (residual {worst:.6g}{where}) after {done}"
        elif why == NO_MEMORY:
            what = (f"residual {worst:.6g} after {done}, and the Newton fallback's {self.n} x {self.n} "
                    f"Jacobian does not fit in memory")
        elif why == NO_DECREASE:
            what = f"no Newton step reduces the residual {worst:.6g}{where} after {done}"
        else:
            what = f"residual {worst:.6g}{where} after {done}"
        return SimulationError(f"algebraic loop {self.name} did not converge: {what} "
                               f"(master.iteration_tolerance = {tol:g})", time=t)


def solve_linear(a: list, b: list, n: int) -> bool:
    """Solve a x = b in place (a: n x n, row-major; x into b) by Gaussian
    elimination with partial pivoting; False where a pivot is zero or not
    finite. Written out (not numpy) so that the compiled core's twin gives
    the same bits."""
    for c in range(n):
        piv, best = c, abs(a[c * n + c])
        for row in range(c + 1, n):
            v = abs(a[row * n + c])
            if v > best:
                piv, best = row, v
        if not (best > 0.0 and best < float("inf")):
            return False
        if piv != c:
            for k in range(n):
                a[c * n + k], a[piv * n + k] = a[piv * n + k], a[c * n + k]
            b[c], b[piv] = b[piv], b[c]
        for row in range(c + 1, n):
            f = a[row * n + c] / a[c * n + c]
            for k in range(c, n):
                a[row * n + k] = a[row * n + k] - f * a[c * n + k]
            b[row] = b[row] - f * b[c]
    for row in range(n - 1, -1, -1):
        s = b[row]
        for k in range(row + 1, n):
            s = s - a[row * n + k] * b[k]
        b[row] = s / a[row * n + row]
    return True
