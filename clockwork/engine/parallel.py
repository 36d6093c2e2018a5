"""Which instances may step at once (``master.threads``), with the bits of
stepping them one at a time.

A communication step (``Master.advance``) steps the feedthrough-only
instances first, all with their inputs at t: they never see each other's
step, so all of them may step at once. Then the dynamic instances: in
Jacobi order every one with inputs at t, so all at once again; in
Gauss-Seidel order each sees what those before it gave, through the
feedthrough-only instances brought up to date after each one
(``first_in_order``). A run of consecutive dynamic instances may step at
once, with its inputs set before any of them steps and one update of the
feedthrough-only instances after the last, when

- none of them takes an input that depends, directly or through
  feedthrough-only instances, on one before it in the run (then it would
  see that one's output after the step in one order and before it in the
  other);
- in the first run, none but the first reads a feedthrough-only instance
  at all (one at a time, the update after the first instance also brings
  in what the feedthrough-only ones committed in their own step);
- no algebraic loop is among the feedthrough-only instances: solving a
  loop once more from where it stopped moves it within its tolerance, so
  fewer updates would change the bits. Then each dynamic instance is a run
  of its own (the feedthrough-only instances still step at once).

Updating a feedthrough-only instance again from the inputs it already has
gives the outputs it already gave (an FMU's outputs are functions of its
state and inputs), so the fewer updates change no bit.
"""

from __future__ import annotations

from .loops import Loop


def _reach(ports) -> tuple[dict[int, int], dict[int, int]]:
    """(position of each dynamic port, and per feedthrough-only port the
    dynamic ones its outputs depend on as a bit set over positions), by id."""
    position = {id(p): a for a, p in enumerate(ports.dynamic)}
    reach: dict[int, int] = {}
    for f in ports.first_in_order:  # dependency order: a source's set is known first
        bits = 0
        for _, src, _ in [*getattr(f, "sources", ()), *getattr(f, "adds", ())]:  # adds: a sum's further terms
            a = position.get(id(src))
            bits |= (1 << a) if a is not None else reach.get(id(src), 0)
        reach[id(f)] = bits
    return position, reach


def updates_after(ports) -> list[list]:
    """Per position a of ``ports.dynamic`` (Gauss-Seidel): the part of
    ``first_in_order`` brought up to date after that instance steps. After
    the first, all of it (it also brings in what the feedthrough-only
    instances committed in their own step); after a later one, those whose
    inputs depend on it: the others would be given the inputs they have.
    With an algebraic loop among them, all of it after each (see above).
    Linear in the system where each instance feeds a few others, instead of
    (dynamic instances) x (feedthrough-only instances) updates per step."""
    order = ports.first_in_order
    n = len(ports.dynamic)
    if any(isinstance(x, Loop) for x in order):
        return [order] * n
    _, reach = _reach(ports)
    after: list[list] = [[] for _ in range(n)]
    for f in order:
        bits = reach[id(f)] & ~1  # position 0 updates them all
        while bits:
            low = bits & -bits
            after[low.bit_length() - 1].append(f)
            bits ^= low
    if n:
        after[0] = order
    return after


def group_ends(ports, jacobi: bool) -> list[int]:
    """Per position a of ``ports.dynamic``: where the run of instances that
    may step at once starting at a ends (exclusive; a + 1: alone)."""
    dynamic = ports.dynamic
    n = len(dynamic)
    if jacobi:
        return [n] * n
    if any(isinstance(x, Loop) for x in ports.first_in_order):
        return [a + 1 for a in range(n)]
    position, reach = _reach(ports)
    starts = [0] * n
    start = 0
    for b, p in enumerate(dynamic):
        needs = 0
        reads_first = False
        for _, src, _ in p.sources + p.adds:  # adds: a sum's further terms
            a = position.get(id(src))
            if a is None:
                needs |= reach.get(id(src), 0)
                reads_first = True
            else:
                needs |= 1 << a
        before = needs & ((1 << b) - 1)  # inputs from instances stepped before this one
        if b > start and ((before >> start) or (start == 0 and reads_first)):
            start = b
        starts[b] = start
    ends = [0] * n
    for b in range(n - 1, -1, -1):
        ends[b] = b + 1 if b == n - 1 or starts[b + 1] != starts[b] else ends[b + 1]
    return ends
