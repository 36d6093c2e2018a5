"""`clockwork export-ssp`: the archive's structure, as each tool reads it.

- fmpy.ssp.ssd.read_ssd with schema validation accepts the SystemStructure.ssd
  and every bound .ssv (read_ssd validates those too);
- the parameter values read back are the scene's doubles, bit for bit;
- the names libcosim, ecos and OMSimulator look up literally are there:
  prefixes ssd/ssc/ssv, ssv:ParameterSet as an .ssv's root, component-level
  ssd:ParameterBinding, OMSimulator's org.openmodelica annotation with
  oms:Annotations/oms:SimulationInformation/oms:FixedStepMaster (stepSize =
  the scene's step) as the system's first ssc:Annotation, libcosim's
  osp:FixedStepAlgorithm;
- the CLI's errors.
"""

import subprocess
import sys
import zipfile

import pytest
from lxml import etree

from clockwork.scene.ssp import NS, OMS_NS, OSP_NS, PARAMETER_SET, build_ssp, export_ssp, fmpy_parameter_set
from interop_common import ROOT, SCENES, exported, scene


@pytest.mark.parametrize("name", SCENES)
def test_archive_is_valid_ssp_for_fmpy(name, ssp_dir):
    from fmpy.ssp.ssd import find_components, read_ssd

    sc = scene(name)
    ssp = exported(name, ssp_dir)
    ssd = read_ssd(str(ssp), validate=True)
    comps = {c.name: c for c in find_components(ssd.system)}
    assert list(comps) == list(sc.components)
    with zipfile.ZipFile(ssp) as z:
        names = set(z.namelist())
        for inst, comp in sc.components.items():
            c = comps[inst]
            assert c.type == "application/x-fmu-sharedlibrary"
            assert z.read(c.source) == comp.fmu_path.read_bytes()
            [binding] = c.parameterBindings
            assert binding.source == f"resources/{inst}.ssv" and binding.source in names
            [pset] = binding.parameterValues
            assert pset.name == PARAMETER_SET
            got = {p.name: p.value for p in pset.parameters}
            assert set(got) == set(comp.parameters)
            for var, value in comp.parameters.items():
                assert type(value)(got[var]) == value, (inst, var, got[var], value)
            kinds = {k.name: k.kind for k in c.connectors}
            for conn in sc.connections:
                if conn.dst_instance == inst:
                    assert kinds[conn.dst_var] == "input"
                if conn.src_instance == inst:
                    assert kinds[conn.src_var] == "output"
            # Only connected inputs: fmpy's runner would set any other to 0.
            assert sum(k == "input" for k in kinds.values()) == sum(x.dst_instance == inst for x in sc.connections)
    assert [(c.startElement, c.startConnector, c.endElement, c.endConnector) for c in ssd.system.connections] \
        == [tuple(c[:4]) for c in sc.connections]
    pset = fmpy_parameter_set(ssp)
    assert {p.name: p.value for p in pset.parameters} == {
        f"{i}.{k}": v for i, c in sc.components.items() for k, v in c.parameters.items()}


@pytest.mark.parametrize("name", SCENES)
def test_vendor_annotations_and_literal_prefixes(name):
    sc = scene(name)
    files = build_ssp(sc)
    root = etree.fromstring(files["SystemStructure.ssd"])
    assert root.prefix == "ssd" and root.get("version") == "1.0"
    assert {root.nsmap[k] for k in ("ssd", "ssc", "ssv")} == {NS[k] for k in ("ssd", "ssc", "ssv")}
    system = root.find("ssd:System", NS)
    first = system.find("ssd:Annotations", NS)[0]
    assert first.tag == f"{{{NS['ssc']}}}Annotation" and first.get("type") == "org.openmodelica"
    fsm = first.find(f"{{{OMS_NS}}}Annotations/{{{OMS_NS}}}SimulationInformation/{{{OMS_NS}}}FixedStepMaster")
    assert fsm is not None and fsm.prefix == "oms"
    assert fsm.get("description") == "oms-ma" and float(fsm.get("stepSize")) == sc.master.step
    # The tightest tolerance any component runs with (the core scene sets the pendulum's).
    rtols = [c.parameters["rtol"] for c in sc.components.values() if "rtol" in c.parameters]
    assert rtols and float(fsm.get("relativeTolerance")) == min(rtols)
    assert float(fsm.get("absoluteTolerance")) > 0.0
    osp = root.find(f"ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation/{{{OSP_NS}}}Algorithm/"
                    f"{{{OSP_NS}}}FixedStepAlgorithm", NS)
    assert osp is not None and osp.prefix == "osp" and float(osp.get("baseStepSize")) == sc.master.step
    exp = root.find("ssd:DefaultExperiment", NS)
    assert float(exp.get("startTime")) == sc.experiment.start and float(exp.get("stopTime")) == sc.experiment.stop
    for inst in sc.components:
        ssv = etree.fromstring(files[f"resources/{inst}.ssv"])
        assert ssv.tag == f"{{{NS['ssv']}}}ParameterSet" and ssv.prefix == "ssv"
    raw = files["SystemStructure.ssd"].decode()
    assert "<ssd:Component " in raw and "<ssd:ParameterBinding " in raw and "<ssc:Real" in raw


def run_cli(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "clockwork", *args], capture_output=True, text=True,
                          timeout=120, cwd=cwd)


def test_cli_writes_archive(tmp_path):
    out = tmp_path / "new" / "clock.ssp"  # one missing folder level is created
    p = run_cli("export-ssp", "scenarios/core_grasshopper.toml", "--out", str(out), "--set", "pendulum.Q=500")
    assert p.returncode == 0, p.stderr
    assert "parameter set 'clockwork'" in p.stdout
    pset = fmpy_parameter_set(out)
    assert {x.name: x.value for x in pset.parameters}["pendulum.Q"] == 500.0


def test_cli_errors(tmp_path):
    p = run_cli("export-ssp", "scenarios/core_grasshopper.toml", "--out", str(tmp_path / "x.zip"))
    assert p.returncode == 2 and "expected a file name ending .ssp" in p.stderr
    p = run_cli("export-ssp", "scenarios/core_grasshopper.toml", "--out", str(tmp_path / "no" / "no" / "x.ssp"))
    assert p.returncode == 2 and "no such directory" in p.stderr
    p = run_cli("export-ssp", "scenarios/ziemkiewicz_fig4a.toml", "--out", str(tmp_path / "x.ssp"))
    assert p.returncode == 2 and "--point" in p.stderr and not (tmp_path / "x.ssp").exists()
    p = run_cli("export-ssp", "scenarios/ziemkiewicz_fig4a.toml", "--out", str(tmp_path / "x.ssp"), "--point", "99")
    assert p.returncode == 2 and "--point 99" in p.stderr


def test_sweep_point_is_exported(tmp_path):
    sc = scene("core_grasshopper")
    out = export_ssp(sc, tmp_path / "x.ssp", {("escapement", "torque"): 0.003})
    values = {x.name: x.value for x in fmpy_parameter_set(out).parameters}
    assert values["escapement.torque"] == 0.003
