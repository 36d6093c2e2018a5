"""An FMU with many outputs, made from the test FMU TestSink: its model
description gains `n` Real outputs w[1] .. w[n], each an alias (the same
valueReference) of its output y, which FMI 2.0 allows. The binary is
TestSink's own, so the FMU runs; the outputs are as many as asked.

    python tests/wide_fmu.py 100000 /tmp/wide.fmu
"""

from __future__ import annotations

import re
import sys
import zipfile
from pathlib import Path


def wide_fmu(sink: Path, n: int, out: Path) -> Path:
    with zipfile.ZipFile(sink) as z:
        files = {i.filename: z.read(i) for i in z.infolist() if not i.is_dir()}
    xml = files["modelDescription.xml"].decode()
    count = len(re.findall(r"<ScalarVariable\b", xml))
    variables = "".join(
        f'    <ScalarVariable name="w[{k}]" valueReference="1" causality="output" variability="continuous" '
        f'initial="calculated"><Real/></ScalarVariable>\n' for k in range(1, n + 1))
    xml = xml.replace("  </ModelVariables>", variables + "  </ModelVariables>")
    unknowns = "".join(f'      <Unknown index="{count + k}" dependencies=""/>\n' for k in range(1, n + 1))
    xml = xml.replace("    </Outputs>", unknowns + "    </Outputs>")
    files["modelDescription.xml"] = xml.encode()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in files.items():
            z.writestr(name, data)
    return out


if __name__ == "__main__":
    root = Path(__file__).resolve().parents[1]
    wide_fmu(root / "build" / "test-fmus" / "TestSink.fmu", int(sys.argv[1]), Path(sys.argv[2]))
