"""What SSP reading and writing share: the namespaces and a safe XML parser.

SSP 1.0 and 2.0 use the same namespace URIs (``http://ssp-standard.org/SSP1/...``);
a file says which version it is in its ``version`` attribute.
"""

from __future__ import annotations

import re

from lxml import etree

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "ssm": "http://ssp-standard.org/SSP1/SystemStructureParameterMapping",
    "ssb": "http://ssp-standard.org/SSP1/SystemStructureSignalDictionary",
}
OMS_NS = "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"
# The Open Simulation Platform's annotation (libcosim, ecos): ssc:Annotation
# type="com.opensimulationplatform", elements in OSP_NS.
OSP_ANNOTATION = "com.opensimulationplatform"
OSP_NS = "http://opensimulationplatform.com/SSP/OSPAnnotations"
# clockwork's own annotation (ssc:Annotation type="clockwork"): the master
# settings and what to record, so that an exported scene runs back the same.
CW_ANNOTATION = "clockwork"
CW_NS = "urn:clockwork:ssp:1"
VERSIONS = ("1.0", "2.0")


def q(prefix: str, tag: str) -> str:
    """The qualified name {namespace}tag."""
    ns = {"oms": OMS_NS, "osp": OSP_NS, "cw": CW_NS}.get(prefix) or NS[prefix]
    return f"{{{ns}}}{tag}"


class XmlError(ValueError):
    """str() says what is wrong with the document, with its line."""


# No DTD is loaded, no entity is expanded and nothing is fetched from the
# network; a document type declaration is refused outright (an SSP file never
# needs one), which closes the door on entity expansion ("billion laughs")
# and external entities.
_PARSER = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False,
                          remove_comments=True, remove_pis=True)


def parse_xml(data: bytes, kind: str = "SSP"):
    """The root element of an XML document (`kind`: whose files, for the
    message); raises XmlError."""
    try:
        root = etree.fromstring(data, _PARSER)
    except etree.XMLSyntaxError as e:
        msg = re.sub(r"(,? line \d+)*(, column \d+)?\s*$", "", str(e.msg or e))
        line = e.position[0] if e.position else None
        raise XmlError(f"malformed XML{f' at line {line}' if line else ''}: {msg}") from None
    if root is None:
        raise XmlError("malformed XML: empty document")
    tree = root.getroottree()
    if tree.docinfo.doctype or tree.docinfo.internalDTD is not None:
        raise XmlError(f"a DOCTYPE declaration: DTDs and entities are not allowed in {kind} files")
    return root


WARNINGS_SHOWN = 3  # warnings of one kind beyond this many are counted, not printed


class Warnings:
    """The warnings of reading one SSP: of each kind (what the lines are
    about, for the count), the first WARNINGS_SHOWN are kept and the rest
    counted."""

    def __init__(self):
        self._warned: dict[str, list[str]] = {}  # kind -> its warnings, in order

    def warn(self, label: str, key: str, text: str, kind: str | None = None) -> None:
        """A warning line about `key` of the file `label`."""
        self._warned.setdefault(kind or text, []).append(f"{label}: {key}: {text}")

    def lines(self) -> list[str]:
        """The warnings as printed: the first of each kind, then a count."""
        out = []
        for kind, lines in self._warned.items():
            out += lines[:WARNINGS_SHOWN]
            if len(lines) > WARNINGS_SHOWN:
                out.append(f"... and {len(lines) - WARNINGS_SHOWN:,} more like the last: {kind}")
        return out
