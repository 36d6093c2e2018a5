"""Run an exported kit case in another FMI tool; each writes its own CSV layout.

    python -m clockwork.kit.tools TOOL CASE_DIR --step H --out RESULT

TOOL is fmpy (``fmpy.simulate_fmu`` for a single FMU, ``fmpy.ssp.simulation.simulate_ssp``
for an SSP; written with ``fmpy.util.write_csv``), libcosim (libcosimpy)
or ecos (ecospy). libcosim's and ecos's values are read after each step
through their Python APIs and written at full precision in their naming
(``Time``/``<slave>.<var>``; ``time``/``<inst>::<var>``); with --native
their own writers make the file (libcosim: one CSV per slave in the
directory RESULT; ecos: its CSV writer), which round to 6 significant
digits, more than the kit's tubes allow. A case's input (``_in.csv``, the torque
jump) is applied as each tool allows: fmpy through a system input
connector of a copy of the SSP (its ``input=``), libcosim through an
override manipulator, ecos with ``set_real``; all three at the first
communication point at or after the input's step. Run in a subprocess:
a crash in native code must not take the caller down.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from ..engine.names import split_ref
from ..files import read_regular
from ..numbers import parse_json


def _meta(case_dir: Path) -> dict:
    return parse_json(read_regular(next(case_dir.glob("*_case.json")), "a JSON case file"))


def _steps(meta: dict, h: float) -> int:
    n = round(meta["stop"] / h)
    if abs(n * h - meta["stop"]) > 1e-9 * meta["stop"]:
        raise SystemExit(f"step {h} does not divide the horizon {meta['stop']}")
    return n


def _record(meta: dict) -> list[str]:
    names = list(meta["signals"]["tube"])
    if meta["signals"].get("switch"):
        names.append(meta["signals"]["switch"])
    return names


# --- fmpy ------------------------------------------------------------------------


def _split(signal: str, instances) -> tuple[str, str]:
    """(instance, variable) of "instance.variable", the instances known."""
    split = split_ref(signal, list(instances))
    if split is None:
        raise SystemExit(f"{signal}: no instance of {', '.join(instances)} is followed by a variable name")
    return split


def _ssp_with_input(ssp: Path, signal: str, work: Path) -> tuple[Path, str]:
    """A copy of the archive with a system input connector feeding `signal`."""
    import zipfile

    from lxml import etree

    from ..scene.ssp import NS

    with zipfile.ZipFile(ssp) as z:
        files = {n: z.read(n) for n in z.namelist()}
    root = etree.fromstring(files["SystemStructure.ssd"])
    ssd, ssc = "{%s}" % NS["ssd"], "{%s}" % NS["ssc"]
    # Instance and variable names may hold dots: the longest component name that fits.
    inst, var = _split(signal, [c.get("name") for c in root.iter(f"{ssd}Component")])
    name = f"{inst}_{var}"
    system = root.find(f"{ssd}System")
    conns = etree.Element(f"{ssd}Connectors")
    c = etree.SubElement(conns, f"{ssd}Connector", name=name, kind="input")
    etree.SubElement(c, f"{ssc}Real")
    system.insert(0, conns)
    comp = next(e for e in system.find(f"{ssd}Elements") if e.get("name") == inst)
    cc = comp.find(f"{ssd}Connectors")
    k = etree.SubElement(cc, f"{ssd}Connector", name=var, kind="input")
    etree.SubElement(k, f"{ssc}Real")
    connections = system.find(f"{ssd}Connections")
    etree.SubElement(connections, f"{ssd}Connection", startConnector=name, endElement=inst, endConnector=var)
    files["SystemStructure.ssd"] = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    out = work / ssp.name
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for n, data in files.items():
            z.writestr(n, data)
    return out, name


def run_fmpy(case_dir: Path, h: float, out: Path, native: bool = False) -> None:
    from fmpy.util import write_csv

    meta = _meta(case_dir)
    n = _steps(meta, h)
    if meta["kind"] == "fmu":
        from fmpy import simulate_fmu

        res = simulate_fmu(str(case_dir / f"{meta['name']}.fmu"), stop_time=meta["stop"], step_size=h,
                           output_interval=h, output=_record(meta))
        write_csv(str(out), res)
        return
    from fmpy.ssp.simulation import simulate_ssp

    from ..scene.ssp import fmpy_parameter_set

    ssp = case_dir / f"{meta['name']}.ssp"
    inp = meta.get("input")
    work = Path(tempfile.mkdtemp(prefix="clockwork-kit-fmpy-"))
    try:
        inputs = {}
        if inp:
            ssp_run, cname = _ssp_with_input(ssp, inp["signal"], work)
            t_in, before, after = inp["time"], inp["before"], inp["after"]
            inputs[cname] = lambda t: after if t >= t_in - 1e-9 * h else before
        else:
            ssp_run = ssp
        # simulate_ssp steps while time < stop, adding h: a stop half a step
        # before N h gives exactly N steps; its rows hold the time at the start
        # of a step and the values after it.
        res = simulate_ssp(str(ssp_run), start_time=0.0, stop_time=(n - 0.5) * h, step_size=h,
                           parameter_set=fmpy_parameter_set(ssp), input=inputs)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    names = [x for x in _record(meta) if x in res.dtype.names]
    table = np.zeros(len(res), dtype=[("time", float)] + [(x, float) for x in names])
    table["time"] = res["time"] + h
    for x in names:
        table[x] = res[x]
    write_csv(str(out), table)


# --- libcosim --------------------------------------------------------------------


def run_libcosim(case_dir: Path, h: float, out: Path, native: bool = False) -> None:
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    meta = _meta(case_dir)
    n = _steps(meta, h)
    if meta["kind"] == "fmu":
        ex = CosimExecution.from_step_size(step_size=int(round(h * 1e9)))
        ex.add_local_slave(CosimLocalSlave(fmu_path=str(case_dir / f"{meta['name']}.fmu"), instance_name="pendulum"))
    else:
        ex = CosimExecution.from_ssp_file(str(case_dir / f"{meta['name']}.ssp"), step_size=int(round(h * 1e9)))
    slaves = [info.name.decode() for info in ex.slave_infos()]

    def ref(signal):
        inst, var = _split(signal, slaves)
        idx = ex.slave_index_from_instance_name(inst)
        return idx, next(v.reference for v in ex.slave_variables(idx)
                         if (v.name.decode() if isinstance(v.name, bytes) else v.name) == var)

    if native:
        # libcosim's file observer: one CSV per slave (6 significant digits)
        out.mkdir(parents=True, exist_ok=True)
        ex.add_observer(CosimObserver.create_to_dir(str(out)))
        names, refs, obs = [], [], None
    else:
        names = [s if "." in s else f"pendulum.{s}" for s in _record(meta)]
        refs = [ref(s) for s in names]
        obs = CosimObserver.create_last_value()
        ex.add_observer(obs)
        # The initialized values (t = 0): a time-series observer keeps step 0,
        # which the last-value observer has overwritten by the time step() returns.
        first = CosimObserver.create_time_series()
        ex.add_observer(first)
        for i, r in refs:
            first.start_time_series(i, r, CosimVariableType.REAL)
    inp = meta.get("input")
    k_in = int(np.ceil(inp["time"] / h - 1e-9)) if inp else -1
    if inp:
        man = CosimManipulator.create_override()
        ex.add_manipulator(man)
        in_ref = ref(inp["signal"])
    rows, initial = [], None
    for k in range(n + 1):
        if k == k_in:
            man.slave_real_values(in_ref[0], [in_ref[1]], [float(inp["after"])])
        if k == n:
            break
        if not ex.step():
            raise SystemExit(f"libcosim: step {k + 1} failed")
        if obs is not None:
            if k == 1:  # the time series hands out step 0's sample after a later step
                got = [first.time_series_real_samples(i, r, 0, 2) for i, r in refs]
                if all(len(x[1]) and x[1][0] == 0 for x in got):
                    initial = [x[2][0] for x in got]
            t = ex.status().current_time * 1e-9
            rows.append([t] + [obs.last_real_values(i, [r])[0] for i, r in refs])
    if obs is not None:
        from .csvio import write_csv

        if initial:
            rows.insert(0, [0.0] + initial)

        write_csv(out, ["Time"] + names, np.array(rows))


# --- ecos ------------------------------------------------------------------------


def run_ecos(case_dir: Path, h: float, out: Path, native: bool = False) -> None:
    from ecospy import EcosLib, EcosSimulation
    from ecospy.EcosSimulationStructure import EcosSimulationStructure

    from ..scene.ssp import PARAMETER_SET

    EcosLib.set_log_level("warn")
    meta = _meta(case_dir)
    n = _steps(meta, h)
    if meta["kind"] == "fmu":
        st = EcosSimulationStructure()
        st.add_model("pendulum", str(case_dir / f"{meta['name']}.fmu"))
        sim = EcosSimulation(step_size=h, structure=st)
        ids = [f"pendulum::{s}" for s in _record(meta)]
        pset = None
    else:
        sim = EcosSimulation(step_size=h, ssp_path=str(case_dir / f"{meta['name']}.ssp"))
        ids = [s.replace(".", "::", 1) for s in _record(meta)]
        pset = PARAMETER_SET
    if native:  # ecos's CSV writer (6 significant digits)
        sim.add_csv_writer(str(out), identifiers=ids)
    sim.init(parameter_set=pset)
    inp = meta.get("input")
    k_in = int(np.ceil(inp["time"] / h - 1e-9)) if inp else -1
    rows = []
    for k in range(n + 1):
        if k == k_in:
            sim.set_real(inp["signal"].replace(".", "::", 1), float(inp["after"]))
        if k == 0 or k == n:
            if not native:
                rows.append([sim.get_time()] + [sim.get_real(i) for i in ids])
        if k == n:
            break
        t = sim.step()
        if not native and k + 1 < n:
            rows.append([t] + [sim.get_real(i) for i in ids])
    sim.terminate()
    if not native:
        from .csvio import write_csv

        write_csv(out, ["time"] + ids, np.array(rows))


RUNNERS = {"fmpy": run_fmpy, "libcosim": run_libcosim, "ecos": run_ecos}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("tool", choices=sorted(RUNNERS))
    p.add_argument("case_dir")
    p.add_argument("--step", type=float, required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--native", action="store_true",
                   help="libcosim/ecos: the tool's own CSV writer (6 significant digits) instead of full precision")
    a = p.parse_args(argv)
    RUNNERS[a.tool](Path(a.case_dir), a.step, Path(a.out), a.native)
    return 0


if __name__ == "__main__":
    sys.exit(main())
