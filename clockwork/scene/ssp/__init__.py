"""SSP (System Structure and Parameterization) files: a scene written as an
SSP archive for other FMI tools (``export``), and an SSP archive or SSD file
read into the scene model (``read``, on the files ``documents`` opens, in
three jobs: ``structure``, ``flatten``, ``parameters``; ``sections`` reads
the settings); ``common`` holds what both share (the namespaces, the safe
XML parser)."""

from typing import TYPE_CHECKING

__all__ = ["CW_ANNOTATION", "CW_NS", "NS", "OMS_NS", "OSP_NS", "FMU_TYPE", "PARAMETER_SET", "build_ssp",
           "container_description", "export_ssp", "fmpy_parameter_set", "parameter_set_xml",
           "write_container_description", "SspScene", "read_ssp"]

if TYPE_CHECKING:  # what __getattr__ gives, for readers, type checkers and the API docs
    from .common import CW_ANNOTATION, CW_NS, NS, OMS_NS, OSP_NS
    from .export import (FMU_TYPE, PARAMETER_SET, build_ssp, container_description, export_ssp, fmpy_parameter_set,
                         parameter_set_xml, write_container_description)
    from .read import SspScene, read_ssp

_HOMES = {"CW_ANNOTATION": "common", "CW_NS": "common", "NS": "common", "OMS_NS": "common", "OSP_NS": "common",
          "SspScene": "read", "read_ssp": "read"}


def __getattr__(name: str):
    # Imported on first use: an FMU run alone reads no SSP and writes none
    # (the writer imports lxml's tree builder; docs/benchmarks.md, first run).
    if name not in __all__:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f".{_HOMES.get(name, 'export')}", __name__), name)
