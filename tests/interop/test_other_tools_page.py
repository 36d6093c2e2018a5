"""The commands of docs/other-tools.md ("Using the FMUs in other tools",
once a section of the README) work as written.

Every fenced bash and python block of the page runs, in order, in a
scratch directory laid out like a fresh clone after setup (scenarios/, fmus/,
the sources the cross build reads, no out/).
"""

import os
import re
import shutil
import subprocess
import sys

import pytest

from interop_common import FMU_DIR, ROOT, relative_difference, require

PAGE = ROOT / "docs" / "other-tools.md"


def blocks() -> list[tuple[str, str]]:
    return re.findall(r"```(bash|python)\n(.*?)```", PAGE.read_text(), flags=re.S)


def test_page_has_commands():
    kinds = [k for k, _ in blocks()]
    assert kinds.count("bash") >= 1 and kinds.count("python") >= 3


def test_page_commands_run(tmp_path):
    for module in ("libcosimpy", "ecospy", "fmu_manipulation_toolbox"):
        require(module)
    if not shutil.which("x86_64-w64-mingw32-gcc"):  # the page's cross build; tools/setup.sh installs it
        reason = "mingw-w64 is missing (apt-get install mingw-w64)"
        pytest.fail(reason) if os.environ.get("CI") else pytest.skip(reason)
    (tmp_path / "scenarios").symlink_to(ROOT / "scenarios")
    (tmp_path / "fmus").symlink_to(FMU_DIR)
    for source in ("CMakeLists.txt", "cmake", "src_c", "tools", "tests"):  # the cross build by hand
        (tmp_path / source).symlink_to(ROOT / source)
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR),
               PATH=os.pathsep.join([os.path.dirname(sys.executable), os.environ.get("PATH", "")]))
    printed = []
    for k, (kind, code) in enumerate(blocks()):
        cmd = ["bash", "-euo", "pipefail", "-c", code] if kind == "bash" else [sys.executable, "-c", code]
        p = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, f"{PAGE.name} block {k} ({kind}) failed:\n{code}\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}"
        printed += p.stdout.splitlines()
    assert (tmp_path / "out" / "core_grasshopper.ssp").exists()
    assert (tmp_path / "out" / "container.csv").exists()
    values = {}
    for line in printed:
        m = re.match(r"(\w+): phi(?:\(10 s\))? = ([-+0-9.e]+)", line)
        if m:
            values[m.group(1)] = float(m.group(2))
    assert set(values) == {"fmpy", "libcosim", "ecos"}, printed
    for tool, phi in values.items():
        assert abs(phi) < 0.2, (tool, phi)
    # Same conventions but the clock's rounding: the same numbers.
    assert relative_difference([values["ecos"]], [values["libcosim"]]) < 1e-9
