"""Rollback-heavy runs keep their memory flat.

A pendulum of L = 1 cm (T0 = 0.2 s) driven at 5 deg by the grasshopper
escapement: two torque switches per period, each located by rolling every
FMU back (fmi2SetFMUstate) and stepping again. Resident memory (VmRSS from
/proc/self/status) is read after a warm-up and after the run. CI: 2e4
events; CLOCKWORK_STRESS=full: 1e6 events (about 11 min).
"""


from stress_support import fmus, size  # noqa: F401 (first: puts benchmarks/ on sys.path)
import stability as st  # noqa: E402

EVENTS = size(20_000, 1_000_000)
BOUND_KIB = 1024  # a leak of 52 bytes per event (CI), 1 byte per event (full) would exceed it


def test_rss_does_not_grow_with_located_events():
    r = st.rollback_run(EVENTS)
    assert r["events"] >= EVENTS
    assert r["rollbacks"] >= r["events"]  # every located event rolls back at least once
    assert r["rss_growth_kib"] < BOUND_KIB, r
    # Not just the end points: no intermediate sample above the start either.
    assert r["rss_max_kib"] - r["rss_before_kib"] < BOUND_KIB, r["trace"]


def test_rss_reader():
    """The measurement can see growth: 64 MiB of touched memory shows up.

    64 MiB is above glibc's largest dynamic mmap threshold (32 MiB), so the
    block gets fresh pages rather than reusing resident freed heap."""
    before = st.rss_kib()
    block = bytearray(64 * 1024 * 1024)
    for i in range(0, len(block), 4096):
        block[i] = 1
    assert st.rss_kib() - before > 48 * 1024
    del block
