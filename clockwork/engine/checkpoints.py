"""Checkpoints: where a rollback returns to, and how a replay catches up.

The master saves FMU states only when a step may need a rollback (an event
indicator is near zero, strong coupling, step doubling), into one reused
buffer per instance. Beside the FMU states, a checkpoint keeps the master's
own state at that point (the "soft state": time, the indicators at the
end of the last step, the input history, the event flags). When an event
arrives in a step that was predicted free of events, and so taken without
a checkpoint, the master returns to the last checkpoint and replays the
deterministic steps taken since then.
"""

from __future__ import annotations

from ..errors import SimulationError

class Checkpoints:
    def __init__(self, master):
        self.master = master
        self.snapshot: tuple | None = None  # the soft state at the checkpoint
        self.since: list[float] = []  # steps taken since the checkpoint, s

    @property
    def held(self) -> bool:
        """Whether a saved state is held that a rollback or a replay may
        set again. Every fmi2DoStep/fmi3DoStep says so to the FMUs: its
        noSetFMUStatePriorToCurrentPoint is true only while none is held
        (cw_step.c: !snap_valid), so that an FMU may drop its history
        wherever the master will not go back."""
        return self.snapshot is not None

    def reset(self) -> None:
        self.snapshot = None
        self.since = []

    def take(self) -> None:
        """A checkpoint here; replays start from it."""
        self.mark()
        self.since = []

    def mark(self) -> None:
        """Save the FMU states and the soft state (the replay list is left alone)."""
        m = self.master
        for p in m.ports.all:
            p.inst.save_state(m.t)
        m.stats.states_saved += 1
        loc = m.locator
        rated = m._multirate
        self.snapshot = (loc.z_end, m.t, m.coupling.snapshot(), m.after_event, loc.time_to_zero,
                         rated.snapshot() if rated is not None else None)

    def rollback(self) -> None:
        """Every FMU and the master back to the checkpoint."""
        self.restore_states()
        self.restore_soft_state()

    def restore_states(self) -> None:
        m = self.master
        for p in m.ports.all:
            p.inst.restore_state(m.t)
            p.sent_valid = False
        m.locator.forget_end_rates()
        m.stats.rollbacks += 1

    def restore_soft_state(self) -> None:
        m = self.master
        loc = m.locator
        loc.z_end, m.t, history, m.after_event, loc.time_to_zero, rated = self.snapshot
        m.coupling.restore(history)
        # The FMU states hold their inputs; only the cached outputs are stale.
        for p in m.ports.all:
            p.read(m.t)
        if rated is not None:  # where each component of another rate stands (engine/multirate.py)
            m._multirate.restore(rated)

    def replay_to(self, t: float) -> None:
        """An event in a step predicted free of events: go back, redo the
        steps since the checkpoint, and take a checkpoint at t."""
        m = self.master
        m.stats.replays += 1
        if self.snapshot is None:
            raise SimulationError(
                f"an event indicator changed sign at t = {t!r} s in a step without a checkpoint",
                time=t)
        self.restore_states()
        steps = list(self.since)
        self.restore_soft_state()
        for h in steps:
            m.advance(m.t, h)
            m.record_history()
        if abs(m.t - t) > 1e-9 * max(1.0, abs(t)):
            raise SimulationError(f"replay ended at t = {m.t!r} s instead of {t!r} s", time=t)
        m.t = t
        self.take()
