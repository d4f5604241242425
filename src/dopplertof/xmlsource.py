"""Where a scene file's elements came from, so that Mitsuba's errors name the user's file.

The loader reads a scene file into an element tree, substitutes ``$name``, expands
``<include>``s and moves elements between scenes before Mitsuba parses the result as a
string; Mitsuba's errors then say ``At string (line 5, col 60)``, a position in that
rewritten text. :class:`Sources` keeps each parsed element's file and line, and
:meth:`Sources.locate` rewrites such a position to ``At scene.xml (line 7)``: the file and
line of the element that starts there (an element the loader made itself has none, and the
message is left as it is).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
import xml.parsers.expat

# Mitsuba's XML parser names a position in the string it was given (src/core/xml.cpp)
_STRING_POSITION = re.compile(r"\b(At|loading) string \(line (\d+), col (\d+)\)")


def _start_positions(text: bytes) -> list[tuple[int, int]]:
    """(line, column) of every element's start tag in document order: 1-based lines, 0-based
    columns, as expat counts them (the order of ``Element.iter()``)."""
    parser = xml.parsers.expat.ParserCreate()
    positions = []
    parser.StartElementHandler = lambda name, attributes: positions.append((parser.CurrentLineNumber, parser.CurrentColumnNumber))
    parser.Parse(text, True)
    return positions


class Sources:
    """The file and line of every element parsed through :meth:`parse`."""

    def __init__(self):
        self._lines = {}  # element -> (path, line)

    def parse(self, path: str):
        """The root of the XML file at ``path`` (``ET.parse``), its elements' lines kept.

        Raises
        ------
        ET.ParseError
            Malformed XML.
        """
        root = ET.parse(path).getroot()
        with open(path, "rb") as f:
            positions = _start_positions(f.read())
        for element, (line, _) in zip(root.iter(), positions):
            self._lines[element] = (path, line)
        return root

    def where(self, element) -> str | None:
        """``"scene.xml (line 7)"`` for a parsed element, else None."""
        if element not in self._lines:
            return None
        path, line = self._lines[element]
        return f"{path} (line {line})"

    def locate(self, message: str, xml_text: str, root) -> str:
        """``message`` with a position in ``xml_text`` (the serialised ``root``) replaced by
        the file and line of the element that starts there, where that element was parsed."""
        match = _STRING_POSITION.search(message)
        if match is None:
            return message
        at = (int(match.group(2)), int(match.group(3)) - 1)
        try:
            positions = _start_positions(xml_text.encode("utf-8"))
        except xml.parsers.expat.ExpatError:
            return message
        found = None
        for element, position in zip(root.iter(), positions):
            if position > at:
                break
            found = element
        where = None if found is None else self.where(found)
        if where is None:
            return message
        return message[: match.start()] + f"{match.group(1)} {where}" + message[match.end() :]
