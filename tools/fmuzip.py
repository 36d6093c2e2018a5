"""Pack a staged FMU folder into a .fmu archive, the same bytes wherever built.

A zip records each entry's order, time and permissions; `cmake -E tar`
takes them from the file system (directory order, build time, umask), so
two builds of the same sources differed. Here entries are sorted by name,
dated $SOURCE_DATE_EPOCH (else 1980-01-01, the first date a zip can hold),
given mode 0755 (binaries) or 0644 (everything else), and compressed at a
fixed level. The archive is written to OUT.part and renamed.

    python tools/fmuzip.py STAGE_DIR OUT.fmu
"""

from __future__ import annotations

import os
import sys
import time
import zipfile
from pathlib import Path

ZIP_EPOCH = 315532800  # 1980-01-01T00:00:00Z


def entry_time() -> tuple[int, int, int, int, int, int]:
    epoch = int(os.environ.get("SOURCE_DATE_EPOCH", ZIP_EPOCH))
    return time.gmtime(max(epoch, ZIP_EPOCH))[:6]


def pack(stage: Path, out: Path) -> None:
    when = entry_time()
    files = sorted(p.relative_to(stage).as_posix() for p in stage.rglob("*") if p.is_file())
    part = out.with_name(out.name + ".part")
    with zipfile.ZipFile(part, "w") as z:
        for name in files:
            info = zipfile.ZipInfo(name, when)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.create_system = 3  # Unix, so that the mode below is read
            info.external_attr = (0o100755 if name.startswith("binaries/") else 0o100644) << 16
            z.writestr(info, (stage / name).read_bytes(), compresslevel=9)
    os.replace(part, out)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__.strip().splitlines()[-1].strip())
    pack(Path(sys.argv[1]), Path(sys.argv[2]))
