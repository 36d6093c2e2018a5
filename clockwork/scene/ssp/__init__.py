"""SSP (System Structure and Parameterization) files: a scene written as an
SSP archive for other FMI tools (``export``), and an SSP archive or SSD file
read into the scene model (``read``, on the files ``documents`` opens, in
three jobs: ``structure``, ``flatten``, ``parameters``; ``sections`` reads
the settings); ``common`` holds what both share (the namespaces, the safe
XML parser)."""

from .common import CW_ANNOTATION, CW_NS, NS, OMS_NS, OSP_NS
from .export import (FMU_TYPE, PARAMETER_SET, build_ssp, container_description, export_ssp, fmpy_parameter_set,
                     parameter_set_xml, write_container_description)
from .read import SspScene, read_ssp

__all__ = ["CW_ANNOTATION", "CW_NS", "NS", "OMS_NS", "OSP_NS", "FMU_TYPE", "PARAMETER_SET", "build_ssp",
           "container_description", "export_ssp", "fmpy_parameter_set", "parameter_set_xml",
           "write_container_description", "SspScene", "read_ssp"]
