"""SSP files under hostile edits, by class (issue 28's SSP classes, issue 26's
SSP items): numbers in spellings XML has not, unit factors of 0,
transformations clockwork would drop, the same thing said twice, element
names that are no instance names, URI schemes, archive entries zipfile
cannot read, the Open Simulation Platform's annotations, values echoed in
error lines and repeated warnings. Each refusal is one stderr line naming
the file and the element or attribute, exit code 2, for `validate` and
`run`, as an .ssd and zipped as an .ssp, with nothing written.
"""

import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest

from cwtest import assert_one_line_error, fmu_file, run_cli
from test_ssp import _edit, fixture_dir, series, zip_dir

from clockwork.run.catalog import load_scene

SSD = "SystemStructure.ssd"
SSV = "resources/escapement.ssv"
SHORT = ["--set", "experiment.stop=0.5", "--set", "record.interval=0.01"]


def _warnings_and_notes(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith(("clockwork: warning:", "clockwork: note:"))]


def _refused(tmp_path, capsys, src: Path, needles, out=None):
    out = out or tmp_path / "out"
    for cmd in (["validate", src], ["run", src, "--out", out, "--no-progress"]):
        rc, _, err = run_cli(capsys, cmd)
        rest = "\n".join(line for line in err.splitlines() if line not in _warnings_and_notes(err))
        assert_one_line_error(rc, rest, *needles)
    assert not out.exists()


def _both(tmp_path, d: Path, as_archive: bool) -> Path:
    if as_archive:
        return zip_dir(d, tmp_path / "bad.ssp")
    return d / SSD


def _refused_edited(tmp_path, capsys, needles, as_archive: bool, *edits, fixture: str = "flat10"):
    """The fixture with `edits` applied, as an .ssd or an .ssp, refused in one line."""
    d = fixture_dir(tmp_path, fixture)
    for edit in edits:
        edit(d)
    _refused(tmp_path, capsys, _both(tmp_path, d, as_archive), needles)


# ------------------------------------------------------------- numbers


# Spellings Python's float() takes and xs:double has not.
SPELLINGS = ["1_0", " 2", "2 ", "\u0662", "\uff12", "infinity", "nan", "+nan", "Infinity"]
# (file, the attribute as written in the fixture, its name)
NUMBER_ATTRIBUTES = [
    (SSD, 'factor="2"', "factor"),  # ssc:LinearTransformation on a connection
    (SSD, 'name="Q"><ssv:Real value="1000"', "value"),  # an inline parameter value
    (SSD, 'stopTime="20"', "stopTime"),
    (SSD, 'kg="1" m="2" s="-2" factor="0.01"', "factor"),  # an ssd:Units unit
    (SSV, 'kg="1" m="2" s="-2" factor="0.01"', "factor"),  # an .ssv's unit
    (SSV, 'name="torque"><ssv:Real value="0.4"', "value"),
]
INTEGER_SPELLINGS = ["1_0", " 1", "1 ", "\u0661"]


def _set_attr(file: str, written: str, attr: str, value: str):
    new = written.rsplit(f'{attr}="', 1)[0] + f'{attr}="{value}"' + written.rsplit('"', 1)[1]
    return _edit(written, new, file)


@pytest.mark.parametrize("as_archive", [False, True], ids=["ssd", "ssp"])
@pytest.mark.parametrize("file, written, attr", NUMBER_ATTRIBUTES, ids=[f"{f}:{a}" for f, w, a in NUMBER_ATTRIBUTES])
@pytest.mark.parametrize("spelling", SPELLINGS, ids=repr)
def test_a_number_xml_does_not_spell_is_refused(tmp_path, capsys, spelling, file, written, attr, as_archive):
    _refused_edited(tmp_path, capsys, [Path(file).name, f"{attr}={spelling!r}", "expected a number"], as_archive,
                    _set_attr(file, written, attr, spelling))


@pytest.mark.parametrize("spelling", INTEGER_SPELLINGS, ids=repr)
def test_an_integer_xml_does_not_spell_is_refused(tmp_path, capsys, spelling):
    """A unit's exponent (xs:int)."""
    d = fixture_dir(tmp_path, "flat10")
    _edit('<ssc:BaseUnit kg="1" m="2" s="-2"/>', f'<ssc:BaseUnit kg="{spelling}" m="2" s="-2"/>')(d)
    _refused(tmp_path, capsys, d / SSD, [SSD, f"kg={spelling!r}", "expected an integer"])


@pytest.mark.parametrize("file", [SSD, SSV])
def test_a_unit_factor_of_zero_is_refused(tmp_path, capsys, file):
    d = fixture_dir(tmp_path, "flat10")
    _edit('kg="1" m="2" s="-2" factor="0.01"', 'kg="1" m="2" s="-2" factor="0"', file)(d)
    _refused(tmp_path, capsys, d / SSD, [Path(file).name, "factor='0'", "other than 0"])


# ------------------------------------------------------------- transformations


_LINEAR = '<ssc:LinearTransformation factor="2"/>'
TRANSFORMATIONS = {
    "unknown ssc element": ("<ssc:MapTransformation/>", ["ssc:MapTransformation", "not supported"]),
    "a foreign namespace": ('<x:LinearTransformation xmlns:x="urn:other" factor="2"/>',
                            ["{urn:other}LinearTransformation", "not supported"]),
    "no namespace": ('<LinearTransformation factor="2"/>', ["LinearTransformation", "not supported"]),
    "two linear": (_LINEAR + '<ssc:LinearTransformation factor="3"/>', ["ssc:LinearTransformation",
                                                                       "one transformation"]),
    "an unknown ssd element": ("<ssd:Transformation/>", ["ssd:Transformation", "not supported"]),
}


@pytest.mark.parametrize("as_archive", [False, True], ids=["ssd", "ssp"])
@pytest.mark.parametrize("case", list(TRANSFORMATIONS))
def test_a_connection_transformation_is_applied_or_refused_never_dropped(tmp_path, capsys, case, as_archive):
    written, needles = TRANSFORMATIONS[case]
    _refused_edited(tmp_path, capsys, [SSD, *needles], as_archive, _edit(_LINEAR, written))


@pytest.mark.parametrize("case", ["a foreign namespace", "no namespace", "two linear"])
def test_a_mapping_entry_transformation_is_applied_or_refused(tmp_path, capsys, case):
    written, needles = TRANSFORMATIONS[case]
    _refused_edited(tmp_path, capsys, ["drive.ssm", *needles], False,
                    _edit('<ssc:LinearTransformation factor="2" offset="0"/>', written, "resources/drive.ssm"),
                    fixture="nested")


def test_inert_children_of_a_connection_change_nothing(tmp_path):
    """The drawing (ssd:ConnectionGeometry) and tools' annotations are no transformation."""
    d = fixture_dir(tmp_path, "flat10")
    before = load_scene(d / SSD).connections
    _edit(_LINEAR, _LINEAR + '<ssd:ConnectionGeometry pointsX="1" pointsY="2"/><ssd:Annotations>'
          '<ssc:Annotation type="x"><y/></ssc:Annotation></ssd:Annotations>')(d)
    assert load_scene(d / SSD).connections == before


# ------------------------------------------------------------- one thing said twice


TWICE = {
    "a parameter twice in an .ssv, two values": (
        _edit('<ssv:Parameter name="torque">', '<ssv:Parameter name="torque"><ssv:Real value="1"/></ssv:Parameter>'
              '<ssv:Parameter name="torque">', SSV), ["escapement.ssv", "ssv:Parameter name='torque'", "once"]),
    "a parameter twice inline": (
        _edit('<ssv:Parameter name="L">', '<ssv:Parameter name="L"><ssv:Real value="2"/></ssv:Parameter>'
              '<ssv:Parameter name="L">'), [SSD, "name='L'", "once"]),
    "a unit twice": (
        _edit('<ssc:Unit name="N.m">', '<ssc:Unit name="N.m"><ssc:BaseUnit kg="1" m="2" s="-2" factor="2"/>'
              '</ssc:Unit><ssc:Unit name="N.m">'), [SSD, "name='N.m'", "defined twice"]),
}


@pytest.mark.parametrize("as_archive", [False, True], ids=["ssd", "ssp"])
@pytest.mark.parametrize("case", list(TWICE))
def test_one_thing_said_twice_is_refused(tmp_path, capsys, case, as_archive):
    edit, needles = TWICE[case]
    _refused_edited(tmp_path, capsys, needles, as_archive, edit)


def test_a_parameter_said_twice_alike_is_one_value(tmp_path):
    """OMSimulator's testsuite has such .ssv files: nothing to choose between."""
    d = fixture_dir(tmp_path, "flat10")
    before = load_scene(d / SSD).components["escapement"].parameters
    _edit('<ssv:Parameter name="torque">', '<ssv:Parameter name="torque"><ssv:Real value="0.4" unit="N.cm"/>'
          '</ssv:Parameter><ssv:Parameter name="torque">', SSV)(d)
    assert load_scene(d / SSD).components["escapement"].parameters == before


def test_a_mapping_target_twice_is_refused(tmp_path, capsys):
    d = fixture_dir(tmp_path, "nested")
    _edit('<ssm:MappingEntry source="relay_angle" target="phi_r"/>',
          '<ssm:MappingEntry source="relay_angle" target="phi_r"/><ssm:MappingEntry source="half_torque" '
          'target="phi_r"/>', "resources/drive.ssm")(d)
    _refused(tmp_path, capsys, d / SSD, ["drive.ssm", "target='phi_r'", "once"])


@pytest.mark.parametrize("entry", [SSD, "resources/Pendulum.fmu", "resources/escapement.ssv"])
def test_an_archive_entry_twice_is_refused(tmp_path, capsys, entry):
    d = fixture_dir(tmp_path, "flat10")
    with pytest.warns(UserWarning, match="Duplicate name"):
        src = zip_dir(d, tmp_path / "bad.ssp", extra={entry: (d / entry).read_bytes()})
    _refused(tmp_path, capsys, src, ["bad.ssp", f"archive entry {entry!r}", "two entries"])


# ------------------------------------------------------------- names


BAD_NAMES = ["a/b", "..", "p-&gt;q", "esc&#10;apement", " escapement", "escapement.", "tab&#9;x", "a\\b",
             "master", "record"]


@pytest.mark.parametrize("as_archive", [False, True], ids=["ssd", "ssp"])
@pytest.mark.parametrize("name", BAD_NAMES)
def test_an_element_name_follows_the_instance_name_rule(tmp_path, capsys, name, as_archive):
    """The rule of docs/scenes.md: the scene layer's own check (scene.checks.instance_problem)."""
    d = fixture_dir(tmp_path, "flat10")
    p = d / SSD
    p.write_text(p.read_text().replace('"escapement"', f'"{name}"'))
    _refused(tmp_path, capsys, _both(tmp_path, d, as_archive), [SSD, "ssd:Component", "element name"])


def test_a_nested_system_name_follows_the_rule_too(tmp_path, capsys):
    d = fixture_dir(tmp_path, "nested")
    p = d / SSD
    text = p.read_text().replace('"movement"', '"move/ment"')
    p.write_text(text.replace("movement.pendulum.", "move/ment.pendulum."))
    _refused(tmp_path, capsys, p, [SSD, "ssd:System", "element name", "'/'"])


# ------------------------------------------------------------- URI schemes


SCHEMES = {
    "proxyfmu://localhost?file=resources/Pendulum.fmu": "proxyfmu:",
    "http://example.com/Pendulum.fmu": "http:",
    "fmu://resources/Pendulum.fmu": "fmu:",
    "urn:x:Pendulum.fmu": "urn:",
}


@pytest.mark.parametrize("as_archive", [False, True], ids=["ssd", "ssp"])
@pytest.mark.parametrize("uri", list(SCHEMES))
def test_an_unsupported_uri_scheme_is_named(tmp_path, capsys, uri, as_archive):
    _refused_edited(tmp_path, capsys, [SSD, "source=", f"the URI scheme {SCHEMES[uri]} is not supported"], as_archive,
                    _edit('source="resources/Pendulum.fmu"', f'source="{uri.replace("&", "&amp;")}"'))


# file: URIs (docs/scenes.md: a source is a relative path or file:): RFC 8089's
# absolute forms, and the relative form tools write (file:resources/x.fmu).
RELATIVE_FILE_URIS = ["file:resources/Pendulum.fmu", "file:./resources/Pendulum.fmu", "file:resources/Pendul%75m.fmu",
                      "file:resources/../resources/Pendulum.fmu"]


def _sources(uri: str, ssv_uri: str | None = None):
    def apply(d: Path) -> Path:
        p = d / SSD
        text = p.read_text().replace('source="resources/Pendulum.fmu"', f'source="{uri}"')
        if ssv_uri is not None:
            text = text.replace('source="resources/escapement.ssv"', f'source="{ssv_uri}"')
        p.write_text(text)
        return p
    return apply


def _run_series(tmp_path, capsys, src: Path, name: str):
    out = tmp_path / name
    rc, _, err = run_cli(capsys, ["validate", src])
    assert rc == 0, err
    rc, _, err = run_cli(capsys, ["run", src, "--out", out, "--no-progress", *SHORT])
    assert rc == 0, err
    return (out / "timeseries.csv").read_bytes()


@pytest.mark.parametrize("as_archive", [False, True], ids=["ssd", "ssp"])
@pytest.mark.parametrize("uri", RELATIVE_FILE_URIS)
def test_a_relative_file_uri_names_the_file_a_relative_path_names(tmp_path, capsys, uri, as_archive):
    ref = _run_series(tmp_path, capsys, _both(tmp_path, fixture_dir(tmp_path, "flat10"), as_archive), "ref")
    d = fixture_dir(tmp_path / "b", "flat10")
    _sources(uri, "file:resources/escapement.ssv")(d)
    assert _run_series(tmp_path, capsys, _both(tmp_path / "b", d, as_archive), "out") == ref


@pytest.mark.parametrize("form", ["file:{p}", "file://{p}", "file://localhost{p}", "file://LOCALHOST{p}"])
def test_an_absolute_file_uri_beside_an_ssd_names_that_file(tmp_path, capsys, form):
    ref = _run_series(tmp_path, capsys, fixture_dir(tmp_path, "flat10") / SSD, "ref")
    d = fixture_dir(tmp_path / "b", "flat10")
    fmu = (d / "resources" / "Pendulum.fmu").resolve()
    _sources(form.format(p=fmu.as_posix()))(d)
    assert _run_series(tmp_path, capsys, d / SSD, "out") == ref


FILE_URIS_REFUSED = {
    "file:///tmp/Pendulum.fmu": ["expected a path inside the archive", "absolute path"],
    "file:/tmp/Pendulum.fmu": ["expected a path inside the archive", "absolute path"],
    "file://example.com/resources/Pendulum.fmu": ["expected a file on this machine", "example.com",
                                                  "another host's file"],
    "file:../Pendulum.fmu": ["expected a path inside the archive: this one leaves it"],
    "file:///C:/fmus/Pendulum.fmu": ["Windows drive path"],
    "file:resources/Missing.fmu": ["no such file in the archive", "resources/Missing.fmu"],
    "file:resources/Pendulum.fmu?x=1": ["without scheme, host, query or fragment"],
}


@pytest.mark.parametrize("uri", list(FILE_URIS_REFUSED))
def test_a_file_uri_that_leaves_the_archive_is_refused(tmp_path, capsys, uri):
    d = fixture_dir(tmp_path, "flat10")
    _sources(uri)(d)
    _refused(tmp_path, capsys, zip_dir(d, tmp_path / "bad.ssp"), [SSD, "source=", *FILE_URIS_REFUSED[uri]])


def test_a_windows_drive_path_is_named(tmp_path, capsys):
    d = fixture_dir(tmp_path, "flat10")
    _edit('source="resources/Pendulum.fmu"', 'source="C:/fmus/Pendulum.fmu"')(d)
    _refused(tmp_path, capsys, d / SSD, [SSD, "source='C:/fmus/Pendulum.fmu'", "Windows drive path"])


# ------------------------------------------------------------- entries zipfile cannot read


def _patch_entry(archive: Path, name: str, flag_bits: int | None = None, method: int | None = None) -> None:
    """Mark one entry encrypted or compressed with another method, in its
    local header and in the central directory, as another zip tool would."""
    data = bytearray(archive.read_bytes())
    with zipfile.ZipFile(archive) as z:
        info = z.getinfo(name)
    local, central = info.header_offset, None
    pos = data.index(b"PK\x01\x02")  # the central directory's records
    while pos != -1:
        n = struct.unpack_from("<H", data, pos + 28)[0]
        if data[pos + 46:pos + 46 + n].decode() == name:
            central = pos
            break
        pos = data.find(b"PK\x01\x02", pos + 4)
    for head, flag_at, method_at in ((local, 6, 8), (central, 8, 10)):
        if flag_bits is not None:
            struct.pack_into("<H", data, head + flag_at, struct.unpack_from("<H", data, head + flag_at)[0] | flag_bits)
        if method is not None:
            struct.pack_into("<H", data, head + method_at, method)
    archive.write_bytes(bytes(data))


@pytest.mark.parametrize("entry", [SSD, "resources/escapement.ssv", "resources/Pendulum.fmu"])
@pytest.mark.parametrize("how, needle", [({"flag_bits": 1}, "encrypted"), ({"method": 99}, "method 99"),
                                         ({"method": 93}, "method 93")], ids=["encrypted", "AES", "zstd"])
def test_an_entry_zipfile_cannot_read_is_one_line(tmp_path, capsys, entry, how, needle):
    d = fixture_dir(tmp_path, "flat10")
    src = zip_dir(d, tmp_path / "bad.ssp")
    _patch_entry(src, entry, **how)
    _refused(tmp_path, capsys, src, [f"bad.ssp/{entry}", needle])


@pytest.mark.parametrize("how, needle", [({"flag_bits": 1}, "encrypted"), ({"method": 99}, "method 99")],
                         ids=["encrypted", "AES"])
def test_an_fmu_entry_zipfile_cannot_read_is_one_line(tmp_path, capsys, how, needle):
    """Inside an FMU (a scene's or an archive's): modelDescription.xml or a binary."""
    fmu = tmp_path / "Pendulum.fmu"
    fmu.write_bytes(fmu_file("Pendulum").read_bytes())
    _patch_entry(fmu, "modelDescription.xml", **how)
    scene = tmp_path / "s.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.p]\nfmu = "{fmu}"\n[experiment]\nstop = 0.1\n')
    _refused(tmp_path, capsys, scene, ["Pendulum.fmu", "modelDescription.xml", needle])


# ------------------------------------------------------------- the OSP annotations


def _osp(algorithm: str, start_stop: str = 'startTime="0" stopTime="20"'):
    return _edit('<ssd:DefaultExperiment startTime="0" stopTime="20"/>',
                 f'<ssd:DefaultExperiment {start_stop}><ssd:Annotations><ssc:Annotation '
                 f'type="com.opensimulationplatform"><osp:Algorithm>{algorithm}</osp:Algorithm></ssc:Annotation>'
                 '</ssd:Annotations></ssd:DefaultExperiment>')


def _with_osp_ns(d: Path) -> None:
    p = d / SSD
    p.write_text(p.read_text().replace('version="1.0" name="flat10"', 'version="1.0" name="flat10" '
                                       'xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations"', 1))


def _hint(component: str, value: str):
    def edit(d: Path) -> None:
        p = d / SSD
        text = p.read_text()
        tag = f'<ssd:Component name="{component}"'
        i = text.index(tag)
        j = text.index("</ssd:Component>", i)
        p.write_text(text[:j] + '<ssd:Annotations><ssc:Annotation type="com.opensimulationplatform">'
                     f'<osp:StepSizeHint value="{value}"/></ssc:Annotation></ssd:Annotations>' + text[j:])
    return edit


def test_the_osp_base_step_is_the_master_step(tmp_path):
    d = fixture_dir(tmp_path, "flat10")
    _with_osp_ns(d)
    _osp('<osp:FixedStepAlgorithm baseStepSize="0.005" numWorkerThreads="4"/>')(d)
    assert load_scene(d / SSD).master.step == 0.005
    assert load_scene(zip_dir(d, tmp_path / "x.ssp")).master.step == 0.005


def test_the_same_step_hint_on_every_component_is_the_master_step(tmp_path, capsys):
    d = fixture_dir(tmp_path, "flat10")
    _with_osp_ns(d)
    _osp('<osp:FixedStepAlgorithm baseStepSize="0.001"/>')(d)
    for c in ("pendulum", "escapement"):
        _hint(c, "0.004")(d)
    assert load_scene(d / SSD).master.step == 0.004
    # --set master.step steps every component alike, with a note naming the hints
    scene = load_scene(d / SSD, ["master.step=0.002"])
    _, err = capsys.readouterr()
    assert scene.master.step == 0.002
    assert "clockwork: note:" in err and "osp:StepSizeHint" in err


BAD_OSP = {
    "another algorithm": (_osp('<osp:EccoAlgorithm/>'), ["osp:Algorithm", "osp:EccoAlgorithm", "not supported"]),
    "two algorithms": (_osp('<osp:FixedStepAlgorithm baseStepSize="0.01"/><osp:FixedStepAlgorithm '
                            'baseStepSize="0.02"/>'), ["osp:Algorithm", "not supported"]),
    "no base step": (_osp("<osp:FixedStepAlgorithm/>"), ["baseStepSize", "missing required attribute"]),
    "a base step of 0": (_osp('<osp:FixedStepAlgorithm baseStepSize="0"/>'), ["baseStepSize='0'", "> 0"]),
    "a negative base step": (_osp('<osp:FixedStepAlgorithm baseStepSize="-1e-3"/>'), ["baseStepSize='-1e-3'"]),
    "worker threads no number": (_osp('<osp:FixedStepAlgorithm baseStepSize="0.01" numWorkerThreads="many"/>'),
                                 ["numWorkerThreads='many'", "whole number"]),
    "a step hint of 0": (_hint("pendulum", "0"), ["osp:StepSizeHint", "value='0'", "> 0"]),
    # steps that differ are the components' own (multi-rate), each a whole multiple of the base step
    "steps that differ": (lambda d: (_hint("pendulum", "0.001")(d), _hint("escapement", "0.01")(d)),
                          ["osp:StepSizeHint", "whole multiple of master.step (0.01 s)", "0.001 s"]),
    "a hint beside the base step": (lambda d: (_osp('<osp:FixedStepAlgorithm baseStepSize="0.001"/>')(d),
                                               _hint("escapement", "0.01")(d)),
                                    ["osp:StepSizeHint", "master.event_location",
                                     "escapement every 10 base steps"]),
    "OMSimulator's step differs": (
        lambda d: (_osp('<osp:FixedStepAlgorithm baseStepSize="0.001"/>')(d),
                   _edit('<ssd:System name="root">', '<ssd:System name="root"><ssd:Annotations><ssc:Annotation '
                         'type="org.openmodelica"><oms:Annotations xmlns:oms="https://raw.githubusercontent.com/'
                         'OpenModelica/OMSimulator/master/schema/oms.xsd"><oms:SimulationInformation>'
                         '<oms:FixedStepMaster stepSize="0.01"/></oms:SimulationInformation></oms:Annotations>'
                         '</ssc:Annotation></ssd:Annotations>')(d)),
        ["baseStepSize='0.001'", "two steps for the master"]),
}


@pytest.mark.parametrize("as_archive", [False, True], ids=["ssd", "ssp"])
@pytest.mark.parametrize("case", list(BAD_OSP))
def test_an_osp_annotation_the_master_cannot_honour_is_one_line(tmp_path, capsys, case, as_archive):
    edit, needles = BAD_OSP[case]
    _refused_edited(tmp_path, capsys, [SSD, *needles], as_archive, _with_osp_ns, edit)


# Values an SSD gives the sections, refused after it is read (by the checks a
# scene file's values go through): each named by its own element and attribute,
# not by the master key it became (before: a base step of 1e-300 was reported
# as master.min_step, a stopTime before the startTime as experiment.stop).
_OMS = ('<ssd:System name="root"><ssd:Annotations><ssc:Annotation type="org.openmodelica"><oms:Annotations '
        'xmlns:oms="https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd">'
        '<oms:SimulationInformation><oms:FixedStepMaster {attrs}/></oms:SimulationInformation></oms:Annotations>'
        '</ssc:Annotation></ssd:Annotations>')
ORIGINS = {
    "a base step of 1e-300": (_osp('<osp:FixedStepAlgorithm baseStepSize="1e-300"/>'),
                              ["osp:FixedStepAlgorithm baseStepSize='1e-300'", "expected a step >= master.min_step"]),
    "a base step below the time resolution": (
        _osp('<osp:FixedStepAlgorithm baseStepSize="1e-6"/>', 'startTime="1e9" stopTime="1.0000001e9"'),
        ["osp:FixedStepAlgorithm baseStepSize='1e-6'", "expected a step of at least"]),
    "a stop before the start": (_edit('startTime="0" stopTime="20"', 'startTime="30" stopTime="20"'),
                                ["ssd:DefaultExperiment stopTime='20'", "a time > experiment.start (30 s)"]),
    "a step hint of 1e-300": (lambda d: [_hint(c, "1e-300")(d) for c in ("pendulum", "escapement")],
                              ["osp:StepSizeHint value='1e-300'", "expected a step >= master.min_step"]),
    "OMSimulator's step of 1e-300": (_edit('<ssd:System name="root">', _OMS.format(attrs='stepSize="1e-300"')),
                                     ["oms:FixedStepMaster stepSize='1e-300'", "master.min_step"]),
    "OMSimulator's tolerance of 0": (_edit('<ssd:System name="root">', _OMS.format(attrs='relativeTolerance="0"')),
                                     ["oms:FixedStepMaster relativeTolerance='0'", "a relative tolerance > 0"]),
}


@pytest.mark.parametrize("as_archive", [False, True], ids=["ssd", "ssp"])
@pytest.mark.parametrize("case", list(ORIGINS))
def test_a_value_the_ssd_gives_is_refused_under_its_own_origin(tmp_path, capsys, case, as_archive):
    edit, needles = ORIGINS[case]
    _refused_edited(tmp_path, capsys, [SSD, *needles], as_archive, _with_osp_ns, edit)


# ------------------------------------------------------------- no stopTime


@pytest.mark.parametrize("experiment, stop", [("", 1.0), ('startTime="0"', 1.0), ('startTime="0.25"', 1.25)])
def test_an_ssd_without_a_stop_time_runs_one_second_with_a_note(tmp_path, capsys, experiment, stop):
    d = fixture_dir(tmp_path, "flat10")
    tag = f"<ssd:DefaultExperiment {experiment}/>" if experiment else ""
    _edit('<ssd:DefaultExperiment startTime="0" stopTime="20"/>', tag)(d)
    rc, out, err = run_cli(capsys, ["run", d / SSD, "--out", tmp_path / "out", "--no-progress",
                                    "--set", "record.interval=0.05"])
    assert rc == 0, err
    notes = [line for line in err.splitlines() if line.startswith("clockwork: note:")]
    assert len(notes) == 1 and "no ssd:DefaultExperiment stopTime" in notes[0] and SSD in notes[0], err
    assert "1 s after the start" in notes[0], err
    assert series(tmp_path / "out")["time"][-1] == pytest.approx(stop)
    # --set experiment.stop says another, without a note
    rc, _, err = run_cli(capsys, ["validate", d / SSD, "--set", "experiment.stop=2"])
    assert rc == 0 and "note:" not in err, err


# ------------------------------------------------------------- bounds of the walks


def _chain(n: int):
    """flat10 with the escapement's torque passed through n system connectors in a row."""
    def edit(d: Path) -> None:
        p = d / SSD
        text = p.read_text()
        conns = "".join(f'<ssd:Connector name="c{i}" kind="output"><ssc:Real unit="N.m"/></ssd:Connector>'
                        for i in range(n))
        text = text.replace("</ssd:Connectors>\n    <ssd:Elements>", conns + "</ssd:Connectors>\n    <ssd:Elements>", 1)
        links = '<ssd:Connection startElement="escapement" startConnector="tau" endConnector="c0"/>'
        links += "".join(f'<ssd:Connection startConnector="c{i}" endConnector="c{i + 1}"/>' for i in range(n - 1))
        links += f'<ssd:Connection startConnector="c{n - 1}" endConnector="drive"/>'
        old = '<ssd:Connection startElement="escapement" startConnector="tau" endConnector="drive"/>'
        assert old in text
        p.write_text(text.replace(old, links))
    return edit


def test_a_chain_of_2000_system_connectors_gives_the_bits_of_one_link(tmp_path, capsys):
    """No recursion as deep as the chain (a RecursionError before), and the
    same link: factor, offset and bits."""
    ref = fixture_dir(tmp_path, "flat10")
    long = tmp_path / "long"
    long.mkdir()
    d = fixture_dir(long, "flat10")
    _chain(2000)(d)
    assert load_scene(d / SSD).connections == load_scene(ref / SSD).connections
    for src, out in ((ref, "a"), (d, "b")):
        rc, _, err = run_cli(capsys, ["run", src / SSD, "--out", tmp_path / out, "--no-progress", *SHORT])
        assert rc == 0, err
    a, b = series(tmp_path / "a"), series(tmp_path / "b")
    assert all(np.array_equal(a[k], b[k]) for k in a)
    # the last connector records the escapement's torque, by its name
    scene = load_scene(d / SSD, ["record.outputs=['c1999']"])
    assert list(scene.record.outputs) == [("escapement", "tau")]


def test_systems_nested_as_deep_as_xml_allows_are_read(tmp_path):
    """lxml refuses documents deeper than 256 elements; every level below is
    read without recursion (a System is two levels: ssd:System, ssd:Elements)."""
    d = fixture_dir(tmp_path, "flat10")
    depth = 120
    p = d / SSD
    text = p.read_text()
    inner = '<ssd:System name="n"><ssd:Elements>' * depth + "</ssd:Elements></ssd:System>" * depth
    p.write_text(text.replace("<ssd:Elements>", f"<ssd:Elements>{inner}", 1))
    assert set(load_scene(p).components) == {"pendulum", "escapement"}


# ------------------------------------------------------------- what is echoed


HUGE = "x" * (4 << 20)
LONG_NAME = "x" * 40_000  # an XML name: libxml2 refuses names of more than 50,000 characters
ECHOED = {
    "a connector name": _edit('endConnector="phi"/>', f'endConnector="{HUGE}"/>'),
    "an element name": _edit('endElement="escapement" endConnector="phi"', f'endElement="{HUGE}" endConnector="phi"'),
    "a source": _edit('source="resources/Pendulum.fmu"', f'source="{HUGE}"'),
    "a unit": _edit('<ssv:Real value="0.4" unit="N.cm"/>', f'<ssv:Real value="0.4" unit="{HUGE}"/>', SSV),
    "a number": _edit('factor="2"', f'factor="{HUGE}"'),
    "a tag": _edit(_LINEAR, f"<ssc:{LONG_NAME}/>"),
    "an attribute name": _edit('<ssd:System name="root">', '<ssd:System name="root"><ssd:Annotations><ssc:Annotation '
                               'type="clockwork"><cw:Settings xmlns:cw="urn:clockwork:ssp:1"><cw:Master '
                               f'{LONG_NAME}="1"/></cw:Settings></ssc:Annotation></ssd:Annotations>'),
    "a tag in another namespace": _edit(_LINEAR, f'<x:{LONG_NAME} xmlns:x="{HUGE}"/>'),
}


@pytest.mark.parametrize("as_archive", [False, True], ids=["ssd", "ssp"])
@pytest.mark.parametrize("case", list(ECHOED))
def test_a_4_mib_value_is_echoed_shortened(tmp_path, capsys, case, as_archive):
    d = fixture_dir(tmp_path, "flat10")
    ECHOED[case](d)
    src = _both(tmp_path, d, as_archive)
    rc, _, err = run_cli(capsys, ["validate", src])
    assert rc == 2 and "Traceback" not in err, err[:2000]
    assert len(err.splitlines()) == 1 and len(err) < 2000, (len(err), err[:2000])


def test_repeated_warnings_are_summarised(tmp_path, capsys):
    """20,000 parameter values that name no variable: a few lines and a count, not 20,000."""
    d = fixture_dir(tmp_path, "flat10")
    extra = "".join(f'<ssv:Parameter name="nope{i}"><ssv:Real value="1"/></ssv:Parameter>' for i in range(20_000))
    _edit("<ssv:Parameters>", "<ssv:Parameters>" + extra, SSV)(d)
    rc, _, err = run_cli(capsys, ["validate", d / SSD])
    assert rc == 0, err[:2000]
    warnings = [line for line in err.splitlines() if line.startswith("clockwork: warning:")]
    assert len(warnings) == 4, warnings
    assert "nope0" in warnings[0] and "19,997 more" in warnings[-1] and "name no variable" in warnings[-1]


# ------------------------------------------------------------- archive members in messages


def _fmu_with(src: Path, dst: Path, change) -> None:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            zout.writestr(item, change(item.filename, zin.read(item)))


def _bad_description(name, data):
    return data.replace(b'name="Q"', b'name="L"', 1) if name == "modelDescription.xml" else data


def _other_binary(name, data):
    if not name.startswith("binaries/"):
        return data
    with zipfile.ZipFile(fmu_file("Drag")) as z:
        return z.read("binaries/linux64/Drag.so")


@pytest.mark.parametrize("change, needles", [(_bad_description, ["modelDescription.xml", "unique variable name"]),
                                             (_other_binary, ["fmi2Instantiate refused"])],
                         ids=["description (read)", "binary (instantiated)"])
def test_an_archive_member_is_named_never_its_copy(tmp_path, capsys, change, needles):
    d = fixture_dir(tmp_path, "flat10")
    pendulum = d / "resources" / "Pendulum.fmu"
    _fmu_with(fmu_file("Pendulum"), tmp_path / "P.fmu", change)
    pendulum.write_bytes((tmp_path / "P.fmu").read_bytes())
    src = zip_dir(d, tmp_path / "bad.ssp")
    commands = [["validate", src], ["run", src, "--out", tmp_path / "out", "--no-progress"]]
    if change is _bad_description:
        commands.append(["info", src])  # info reads descriptions, loads no binary
    for cmd in commands:
        rc, _, err = run_cli(capsys, cmd)
        assert_one_line_error(rc, err, "bad.ssp/resources/Pendulum.fmu", *needles)
        assert "ssp-fmus" not in err
    # nothing written (a run that fails at instantiation leaves its --out folder empty, as for a scene)
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
