"""Algebraic loops broken by a one-step delay give libcosim's and ecos' numbers.

master.algebraic_loops = "delay" with master.order = "jacobi" steps a loop's
members with the inputs of the step's start and reads them once after the
step, and starts them as libcosim does (engine/loops.py). Each scene, written
as an SSP by `clockwork export-ssp`, runs in libcosim and ecos (in a
subprocess, clockwork/bench/peer_tool.py); h = 0.125 s, whose multiples all
three clocks (grid, integer nanoseconds, sums) hold exactly, so that the
outputs must agree bit for bit. The test FMUs: TestSum (y = k1 u1 + k2 u2 +
c) and TestIntegrator (y = x, dx/dt = k u, dependencies undeclared).

Where the peers disagree with each other (docs/interop.md): ecos starts the
first step one Jacobi sweep earlier and records its outputs after setting the
new inputs again, so on a loop through a state (the third scene) it differs
from libcosim, which clockwork follows.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from clockwork.engine import MasterSettings, System
from cwtest import test_fmu
from interop_common import PEER_TOOL, require

H, STEPS = 0.125, 24

SCENE = """
connections = [{links}]
[scene]
title = "a loop"
{components}
[experiment]
stop = {stop}
[master]
step = {h}
order = "jacobi"
algebraic_loops = "delay"
"""

CASES = {
    # name: ({instance: (test FMU, parameters)}, links, recorded, peers that must agree)
    "gain and adder": ({"add": ("TestSum", {"c": 1.0}), "gain": ("TestSum", {"k1": 0.5, "k2": 0.0})},
                       ["add.y -> gain.u1", "gain.y -> add.u2"], ["add.y", "gain.y"], ("libcosim", "ecos")),
    "two integrators": ({"x1": ("TestIntegrator", {"k": 1.0, "x0": 1.0}),
                         "x2": ("TestIntegrator", {"k": -1.0, "x0": 0.0})},
                        ["x1.y -> x2.u", "x2.y -> x1.u"], ["x1.y", "x2.y"], ("libcosim", "ecos")),
    "through a state": ({"integ": ("TestIntegrator", {"k": -1.0, "x0": 1.0}), "add": ("TestSum", {"c": 0.25}),
                         "gain": ("TestSum", {"k1": 0.5, "k2": 0.0})},
                        ["integ.y -> add.u1", "add.y -> integ.u", "add.y -> gain.u1", "gain.y -> add.u2"],
                        ["integ.y", "add.y", "gain.y"], ("libcosim",)),
}


def _toml(value) -> str:
    return "{ " + ", ".join(f"{k} = {v!r}" for k, v in value.items()) + " }"


def _clockwork(comps, links, record, engine):
    components = {n: (str(test_fmu(m)), p) for n, (m, p) in comps.items()}
    rec = {}
    for r in record:
        i, v = r.split(".")
        rec.setdefault(i, []).append(v)
    settings = MasterSettings(step=H, order="jacobi", algebraic_loops="delay", engine=engine)
    with System(components, links, settings, record=rec) as s:
        rows = []
        for _ in range(STEPS):
            s.master.step(H)
            rows.append([s.output(*r.split(".")) for r in record])
        return np.array(rows).T


@pytest.mark.parametrize("case", list(CASES))
def test_delay_gives_the_peers_numbers(case, tmp_path):
    from clockwork.run import load_scene
    from clockwork.scene.ssp import export_ssp

    comps, links, record, peers = CASES[case]
    f = tmp_path / "loop.toml"
    f.write_text(SCENE.format(
        links=", ".join(f'"{k}"' for k in links), stop=STEPS * H, h=H,
        components="\n".join(f'[components.{n}]\nfmu = "{test_fmu(m)}"\nparameters = {_toml(p)}'
                             for n, (m, p) in comps.items())))
    ssp = tmp_path / "loop.ssp"
    export_ssp(load_scene(f), ssp)
    ours = _clockwork(comps, links, record, "python")
    assert np.array_equal(ours, _clockwork(comps, links, record, "compiled"))
    for tool in ("libcosim", "ecos"):
        require({"libcosim": "libcosimpy", "ecos": "ecospy"}[tool])
        out = tmp_path / f"{tool}.npz"
        p = subprocess.run([sys.executable, str(PEER_TOOL), tool, str(ssp), "--steps", str(STEPS), "--step", repr(H),
                            "--out", str(out), *record], capture_output=True, text=True, timeout=600)
        assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
        got = np.load(out)
        assert np.allclose(got["time"], H * np.arange(1, STEPS + 1), rtol=0, atol=1e-12), tool
        theirs = np.array([got[r] for r in record])
        same = np.array_equal(ours, theirs)
        if tool in peers:
            assert same, (tool, np.max(np.abs(ours - theirs)))
        else:  # ecos' start and recording differ on a loop through a state (module docstring)
            assert not same, tool
