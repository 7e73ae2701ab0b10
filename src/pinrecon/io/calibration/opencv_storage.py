"""OpenCV FileStorage text: the YAML, XML and JSON that ``cv::FileStorage`` writes.

Only the standard library is used (no PyYAML: OpenCV's ``%YAML:1.0`` header and
``!!opencv-matrix`` tags are not standard YAML anyway). :func:`parse_yaml` reads the YAML
subset these files and ROS ``camera_info`` files use: nested block mappings, block
sequences (``- item``), flow lists and mappings that may span lines, quoted and plain
scalars, ``#`` comments, tags, ``%`` directives and ``---`` markers. :func:`parse_xml`
reads ``<opencv_storage>`` XML. :func:`decode_matrices` turns every matrix node
(``{rows, cols, dt, data}``, tagged ``opencv-matrix`` or not) into a NumPy array.

Errors are :class:`~pinrecon.errors.InputError` naming the file and the line.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET

import numpy as np

from ...errors import InputError

__all__ = ["parse_yaml", "parse_xml", "decode_matrices", "TAG_KEY"]

TAG_KEY = "__tag__"  # where parse_yaml records a node's tag, e.g. "opencv-matrix"

_SPECIAL_FLOATS = {
    ".nan": math.nan,
    "nan": math.nan,
    ".inf": math.inf,
    "+.inf": math.inf,
    "-.inf": -math.inf,
    "inf": math.inf,
    "-inf": -math.inf,
}


def _scalar(token: str):
    """A plain (unquoted) YAML/XML scalar: int, float, bool, null or string."""
    low = token.lower()
    if low in _SPECIAL_FLOATS:
        return _SPECIAL_FLOATS[low]
    if low in ("true", "false"):
        return low == "true"
    if low in ("null", "~"):
        return None
    try:
        return int(token)
    except ValueError:
        pass
    try:
        return float(token)
    except ValueError:
        return token


def _unquote(token: str, file, line):
    q = token[0]
    if len(token) < 2 or token[-1] != q:
        raise InputError(f"line {line}: unterminated quoted string {token}", file=file)
    body = token[1:-1]
    return body.replace("''", "'") if q == "'" else body.replace('\\"', '"')


def _strip_comment(text: str) -> str:
    """Remove a ``#`` comment (at the start or after a space, outside quotes)."""
    quote = None
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "\"'":
            quote = ch
        elif ch == "#" and (i == 0 or text[i - 1] in " \t"):
            return text[:i]
    return text


def _bracket_depth(text: str) -> int:
    depth, quote = 0, None
    for ch in text:
        if quote:
            if ch == quote:
                quote = None
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
    return depth


def _logical_lines(text: str, file):
    """(indent, content, line number) per logical line; flow collections spanning several
    lines are joined; comments, blank lines, directives and document markers dropped."""
    out, pending = [], None
    for number, raw in enumerate(text.splitlines(), 1):
        body = _strip_comment(raw).rstrip()
        if pending is not None:
            pending[1] += " " + body.strip()
            if _bracket_depth(pending[1]) <= 0:
                out.append(tuple(pending))
                pending = None
            continue
        if not body.strip() or body.startswith("%") or body.strip() in ("---", "..."):
            continue
        if body.startswith("--- "):  # "--- !tag" on the document marker line
            continue
        content = body.lstrip(" ")
        if content.startswith("\t"):
            raise InputError(f"line {number}: tabs are not allowed for indentation", file=file)
        entry = [len(body) - len(content), content, number]
        if _bracket_depth(content) > 0:
            pending = entry
        else:
            out.append(tuple(entry))
    if pending is not None:
        raise InputError(f"line {pending[2]}: unclosed '[' or '{{'", file=file)
    return out


class _Flow:
    """Recursive-descent parser of one flow value: ``[a, b]``, ``{k: v}``, scalars."""

    def __init__(self, text, file, line):
        self.s, self.i, self.file, self.line = text, 0, file, line

    def error(self, what):
        raise InputError(f"line {self.line}: {what} in {self.s!r}", file=self.file)

    def skip(self):
        while self.i < len(self.s) and self.s[self.i] in " \t":
            self.i += 1

    def value(self, stops=""):
        self.skip()
        if self.i >= len(self.s):
            return None
        ch = self.s[self.i]
        if ch == "[":
            return self.sequence()
        if ch == "{":
            return self.mapping()
        if ch in "\"'":
            end = self.s.find(ch, self.i + 1)
            while ch == "'" and end != -1 and self.s[end + 1 : end + 2] == "'":
                end = self.s.find(ch, end + 2)
            if end == -1:
                self.error("unterminated quoted string")
            token, self.i = self.s[self.i : end + 1], end + 1
            return _unquote(token, self.file, self.line)
        j = self.i
        while j < len(self.s) and self.s[j] not in stops:
            j += 1
        token, self.i = self.s[self.i : j].strip(), j
        return _scalar(token) if token else None

    def sequence(self):
        self.i += 1
        items = []
        while True:
            self.skip()
            if self.i >= len(self.s):
                self.error("unclosed '['")
            if self.s[self.i] == "]":
                self.i += 1
                return items
            items.append(self.value(",]"))
            self.skip()
            if self.i < len(self.s) and self.s[self.i] == ",":
                self.i += 1
            elif self.i < len(self.s) and self.s[self.i] != "]":
                self.error("expected ',' or ']'")

    def mapping(self):
        self.i += 1
        out = {}
        while True:
            self.skip()
            if self.i >= len(self.s):
                self.error("unclosed '{'")
            if self.s[self.i] == "}":
                self.i += 1
                return out
            key = self.value(":,}")
            self.skip()
            if self.i >= len(self.s) or self.s[self.i] != ":":
                self.error("expected 'key: value'")
            self.i += 1
            out[str(key)] = self.value(",}")
            self.skip()
            if self.i < len(self.s) and self.s[self.i] == ",":
                self.i += 1

    def whole(self):
        v = self.value()
        self.skip()
        if self.i != len(self.s):
            self.error("unexpected text after the value")
        return v


_KEY = re.compile(r"""^("(?:[^"\\]|\\.)*"|'(?:[^']|'')*'|[^"'#:][^:]*?)\s*:(?:\s+(.*))?$""")


def _split_key(content, file, line):
    m = _KEY.match(content)
    if not m:
        raise InputError(f"line {line}: expected 'key: value', got {content!r}", file=file)
    key = m.group(1)
    key = _unquote(key, file, line) if key[0] in "\"'" else key.strip()
    return key, (m.group(2) or "").strip()


def _tagged(rest):
    """Split a leading tag (``!!opencv-matrix``, ``!map``) from the value text."""
    if rest.startswith("!"):
        tag, _, rest = rest.partition(" ")
        return tag.lstrip("!"), rest.strip()
    return None, rest


def _attach_tag(value, tag):
    if tag and isinstance(value, dict):
        value[TAG_KEY] = tag
    return value


def _block(lines, i, indent, file):
    if lines[i][1] == "-" or lines[i][1].startswith("- "):
        return _sequence(lines, i, indent, file)
    return _mapping(lines, i, indent, file)


def _nested(lines, i, indent, file):
    """The value of ``key:`` (or ``-``) with nothing after it: the deeper block that
    follows, a block sequence at the same indentation, or null."""
    if i < len(lines) and lines[i][0] > indent:
        return _block(lines, i, lines[i][0], file)
    if (
        i < len(lines)
        and lines[i][0] == indent
        and (lines[i][1] == "-" or lines[i][1].startswith("- "))
    ):
        return _sequence(lines, i, indent, file)
    return None, i


def _mapping(lines, i, indent, file):
    out = {}
    while i < len(lines):
        ind, content, line = lines[i]
        if ind < indent:
            break
        if ind > indent:
            raise InputError(f"line {line}: unexpected indentation", file=file)
        if content == "-" or content.startswith("- "):
            break
        key, rest = _split_key(content, file, line)
        tag, rest = _tagged(rest)
        i += 1
        if rest:
            value = _Flow(rest, file, line).whole()
        else:
            value, i = _nested(lines, i, indent, file)
        out[key] = _attach_tag(value, tag)
    return out, i


def _sequence(lines, i, indent, file):
    items = []
    while i < len(lines):
        ind, content, line = lines[i]
        if ind != indent or not (content == "-" or content.startswith("- ")):
            if ind > indent:
                raise InputError(f"line {line}: unexpected indentation", file=file)
            break
        rest = content[1:].strip()
        tag, rest = _tagged(rest)
        if not rest:
            value, i = _nested(lines, i + 1, indent, file)
        elif rest[0] not in "[{\"'" and _KEY.match(rest):
            # "- key: value": a mapping whose first entry is on the dash line
            inner = indent + (len(content) - len(rest))
            sub = [(inner, rest, line)] + lines[i + 1 :]
            value, used = _mapping(sub, 0, inner, file)
            i = i + used
        else:
            value, i = _Flow(rest, file, line).whole(), i + 1
        items.append(_attach_tag(value, tag))
    return items, i


def parse_yaml(text: str, file=None) -> dict:
    """Parse OpenCV FileStorage / ROS-style YAML text into dicts, lists and scalars."""
    lines = _logical_lines(text, file)
    if not lines:
        return {}
    value, i = _block(lines, 0, lines[0][0], file)
    if i != len(lines):
        raise InputError(f"line {lines[i][2]}: unexpected indentation", file=file)
    if not isinstance(value, dict):
        raise InputError("expected a mapping ('key: value' lines) at the top level", file=file)
    return value


def _xml_node(elem):
    children = list(elem)
    if children:
        if all(c.tag == "_" for c in children):
            return [_xml_node(c) for c in children]
        out = {c.tag: _xml_node(c) for c in children}
        if elem.get("type_id"):
            out[TAG_KEY] = elem.get("type_id")
        return out
    text = (elem.text or "").strip()
    if not text:
        return None
    if text[0] in "\"'":
        return text.strip("\"'")
    values = [_scalar(t) for t in text.split()]
    return values[0] if len(values) == 1 else values


def parse_xml(text: str, file=None) -> dict:
    """Parse ``<opencv_storage>`` XML into the same structure as :func:`parse_yaml`."""
    try:
        root = ET.fromstring(text.encode() if isinstance(text, str) else text)
    except ET.ParseError as exc:
        raise InputError(f"not valid XML ({exc})", file=file) from None
    if root.tag != "opencv_storage":
        raise InputError(f"expected an <opencv_storage> root element, got <{root.tag}>", file=file)
    return {c.tag: _xml_node(c) for c in root}


def _is_matrix_node(node) -> bool:
    return (
        isinstance(node, dict)
        and {"rows", "cols", "data"} <= set(node)
        and node.get(TAG_KEY, node.get("type_id", "opencv-matrix")) == "opencv-matrix"
    )


def _matrix(node, file, field):
    try:
        rows, cols = int(node["rows"]), int(node["cols"])
        data = np.asarray(node["data"], dtype=float).ravel()
    except (TypeError, ValueError, OverflowError):
        raise InputError(
            "a matrix needs integer rows, cols and numeric data", file=file, field=field
        ) from None
    m = re.match(r"^(\d*)", str(node.get("dt", "d")))
    channels = int(m.group(1)) if m and m.group(1) else 1
    if data.size != rows * cols * channels:
        raise InputError(
            f"matrix data has {data.size} numbers, expected rows x cols x channels = "
            f"{rows} x {cols} x {channels}",
            file=file,
            field=field,
        )
    return data.reshape((rows, cols, channels) if channels > 1 else (rows, cols))


def decode_matrices(node, file=None, field=None):
    """A copy of ``node`` with every matrix node replaced by a NumPy array (multi-channel
    matrices, e.g. ``dt: "2f"``, get a trailing channel axis)."""
    if _is_matrix_node(node):
        return _matrix(node, file, field)
    if isinstance(node, dict):
        return {
            k: decode_matrices(v, file, k if field is None else f"{field}.{k}")
            for k, v in node.items()
            if k != TAG_KEY
        }
    if isinstance(node, list):
        return [decode_matrices(v, file, f"{field}[{j}]") for j, v in enumerate(node)]
    return node
