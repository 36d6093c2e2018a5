"""The Open Simulation Platform's system format (libcosim's
OspSystemStructure.xml, with the variable groups of *_OspModelDescription.xml
files), read into the scene model (``read``); docs/osp.md."""

from .read import OSP_NS, OspScene, OtherXml, read_osp

__all__ = ["OSP_NS", "OspScene", "OtherXml", "read_osp"]
