"""The Open Simulation Platform's system format (libcosim's
OspSystemStructure.xml, with the variable groups of *_OspModelDescription.xml
files), read into the scene model (``read``); docs/osp.md."""

from .read import SYSTEM_NS, OspScene, OtherXml, read_osp

__all__ = ["SYSTEM_NS", "OspScene", "OtherXml", "read_osp"]
