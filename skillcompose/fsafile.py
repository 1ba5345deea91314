"""FSA files: a YAML format written for people first, read safely, saved in place.

A file looks like this (every key but ``format``, ``start`` and ``states`` is optional)::

    # Pour water: a hand-written solution.
    format: 1
    name: pour_water
    start: Recognise
    step_limit: 20              # more steps than this ends the run with `timeout`
    terminals: [success, failure]
    states:
      Recognise:
        skill: RecogniseObject
        transitions: {success: Approach}
      Approach:
        skill: MoveToObject
        params:
          approach: 0.1         # m
        transitions:
          success: Grasp
          failure: Approach     # retry
      ...

A transition's target is a state name or a terminal outcome, which ends the run. Parameters
are in the skill's own units. Saving an FSA that was loaded from a file edits that file's
document in place, so comments, key order and formatting survive.

Loading accepts plain YAML 1.2 data only: no anchors, aliases or merge keys, and no tags but
the core ones (``!!str``, ``!!int``, ``!!float``, ``!!bool``, ``!!null`` on single values,
``!!seq`` and ``!!map``), whose values are checked. A file costs little whatever it holds: at
most :data:`MAX_FILE_BYTES`, nested at most :data:`MAX_DEPTH` levels, at most
:data:`MAX_VALUES` values and :data:`MAX_STATES` states, whole numbers within 64 bits, floats
finite unless written ``.inf``/``.nan``, ``step_limit`` at most
:data:`~skillcompose.fsa.MAX_STEP_LIMIT`. The text is parsed once; every problem is reported
with its file, line and column, the state and key, what was expected and the fix (the first
20, then a count of the rest).
"""

from __future__ import annotations

import dataclasses
import difflib
import io
import math
import os
import re
from collections.abc import Collection, Mapping
from contextlib import suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import MarkedYAMLError, YAMLError
from ruamel.yaml.events import (
    AliasEvent,
    CollectionEndEvent,
    CollectionStartEvent,
    DocumentStartEvent,
    MappingStartEvent,
    ScalarEvent,
    SequenceStartEvent,
)
from ruamel.yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode
from ruamel.yaml.parser import RoundTripParser
from ruamel.yaml.reader import ReaderError
from ruamel.yaml.representer import RoundTripRepresenter
from ruamel.yaml.scalarstring import DoubleQuotedScalarString

from .errors import FSAFileError, FSAValidationError, ParamError, Problem, UnknownSkillError, clip
from .files import NotARegularFile, atomic_write, read_limited
from .fsa import DEFAULT_STEP_LIMIT, DEFAULT_TERMINALS, FSA, Source, State, step_limit_problem
from .params import time_limit_problem

if TYPE_CHECKING:
    from .lookup import SkillLookup

__all__ = [
    "FORMAT_VERSION",
    "MAX_DEPTH",
    "MAX_FILE_BYTES",
    "MAX_STATES",
    "MAX_VALUES",
    "STATE_KEYS",
    "TOP_LEVEL_KEYS",
    "dumps_fsa",
    "load_fsa",
    "loads_fsa",
    "save_fsa",
]

FORMAT_VERSION = 1
TOP_LEVEL_KEYS = ("format", "name", "start", "step_limit", "terminals", "states", "meta")
REQUIRED_TOP_LEVEL = {"format": "format: 1", "start": "start: <name of the first state>",
                      "states": "states: {<name>: {skill: ..., transitions: {...}}}"}
STATE_KEYS = ("skill", "params", "transitions", "time_limit")
REQUIRED_STATE_KEYS = {"skill": "skill: <SkillName>",
                       "transitions": "transitions: {success: <state or terminal>}"}

MAX_FILE_BYTES = 256 * 1024
"""The largest FSA file read; a larger one is refused before it is parsed."""
MAX_DEPTH = 32
"""The deepest nesting of mappings and lists (a state's transitions are 4 levels deep)."""
MAX_STATES = 500
"""The most states an FSA file may hold."""
MAX_VALUES = 10_000
"""The most values (names, numbers, lists, mappings) a file may hold: 500 states of 20."""
_MAX_OPEN_BRACKETS = 256  # `[` and `{` open at once in the raw text, before parsing

_STD = "tag:yaml.org,2002:"
_HEADER = (
    "FSA file of skillcompose. Edit freely: rename states, change parameters (in the\n"
    "skill's units), re-route outcomes (to a state or a terminal outcome), add comments.\n"
    "Check it with `skillcompose validate FILE`, run it with `skillcompose run FILE`."
)


# ---------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------
def load_fsa(path: str | os.PathLike[str]) -> FSA:
    """Read an FSA file. Raises :class:`FSAFileError` naming file, line and fix."""
    p = Path(path)
    try:
        data = read_limited(p, MAX_FILE_BYTES)  # never waits on a pipe, never reads past
    except FileNotFoundError:
        raise FSAFileError([Problem("file not found", fix="check the path")], str(p)) from None
    except NotARegularFile as exc:
        problem = Problem(f"cannot read the file: {exc.strerror}",
                          fix="give the path of an FSA file")
        raise FSAFileError([problem], str(p)) from None
    except OSError as exc:
        problem = Problem(f"cannot read the file: {exc.strerror or exc}")
        raise FSAFileError([problem], str(p)) from None
    if len(data) > MAX_FILE_BYTES:
        head = data[:MAX_FILE_BYTES].decode("utf-8", "replace")
        raise FSAFileError([_too_large(*_line_col(head, MAX_FILE_BYTES))], str(p))
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, col = _line_col(data[:exc.start].decode("utf-8", "replace"), exc.start)
        raise FSAFileError([Problem(
            f"byte 0x{data[exc.start]:02x} is not UTF-8 text", line=line, column=col,
            fix="save the file as UTF-8",
        )], str(p)) from None
    return loads_fsa(text, str(p))


def loads_fsa(text: str, path: str | None = None) -> FSA:
    """Parse FSA text; ``path`` is used in error messages only."""
    if not isinstance(text, str):
        raise TypeError(f"loads_fsa takes the file's text (str), got {type(text).__name__}"
                        + ("; decode it: data.decode('utf-8')" if isinstance(
                            text, (bytes, bytearray)) else ""))
    return _Reader(text, path).read()


def _line_col(text: str, offset: int) -> tuple[int, int]:
    """1-based line and column of character ``offset`` of ``text``."""
    offset = min(offset, len(text))
    line = text.count("\n", 0, offset) + 1
    return line, offset - (text.rfind("\n", 0, offset) + 1) + 1


def _too_large(line: int, column: int) -> Problem:
    return Problem(
        f"the file is larger than {MAX_FILE_BYTES // 1024} KiB, the most an FSA file may be",
        fix=f"keep FSA files under {MAX_FILE_BYTES // 1024} KiB (at most {MAX_STATES} "
        "states); split a large FSA into nested FSAs", line=line, column=column,
    )


class _Refused(Exception):
    """Reading stops at once: the file would cost too much (or is refused outright)."""

    def __init__(self, problem: Problem) -> None:
        super().__init__(problem.message)
        self.problem = problem


def _at(mark: Any, problem: Problem) -> Problem:
    """``problem`` at the 1-based position of the parser's 0-based ``mark`` (1:1 if None)."""
    line, col = (mark.line + 1, mark.column + 1) if mark is not None else (1, 1)
    return dataclasses.replace(problem, line=line, column=col)


class _GuardedParser(RoundTripParser):
    """The YAML parser with the format's limits checked on each event, before the
    (recursive) composer builds a node from it.

    Nesting deeper than :data:`MAX_DEPTH` and aliases stop the parse; anchors, tags other
    than the core schema's and YAML versions other than 1.2 are noted in ``problems``.
    """

    def __init__(self, loader: Any) -> None:
        super().__init__(loader)
        self.problems: list[Problem] = []
        self.depth = 0
        self.values = 0
        self.last_mark: Any = None

    @property
    def current_event(self) -> Any:
        return self._event

    @current_event.setter
    def current_event(self, event: Any) -> None:
        """The parser keeps each event it produces here: it is inspected once, on arrival."""
        if event is not None:
            self._inspect(event)
        self._event = event

    def _inspect(self, event: Any) -> None:
        mark = self.last_mark = event.start_mark
        if isinstance(event, CollectionEndEvent):
            self.depth -= 1
        elif isinstance(event, AliasEvent):
            raise _Refused(_at(mark, Problem(
                f"YAML aliases (*{event.anchor}) are not allowed in FSA files",
                fix="write the value out in full")))
        elif isinstance(event, DocumentStartEvent):
            version = getattr(event, "version", None)
            if version is not None and tuple(version) != (1, 2):
                self.problems.append(_at(mark, Problem(
                    f"%YAML {'.'.join(map(str, version))} documents are not read: "
                    "FSA files are YAML 1.2", fix="remove the %YAML line")))
        elif isinstance(event, (ScalarEvent, CollectionStartEvent)):
            self.values += 1
            if self.values > MAX_VALUES:
                raise _Refused(_at(mark, Problem(
                    f"the file holds more than {MAX_VALUES} values (names, numbers, lists "
                    f"and mappings)", fix=f"an FSA file has at most {MAX_STATES} states; "
                    "split a large FSA into nested FSAs")))
            if isinstance(event, CollectionStartEvent):
                self.depth += 1
                if self.depth > MAX_DEPTH:
                    raise _Refused(_at(mark, Problem(
                        f"the data is nested more than {MAX_DEPTH} levels deep",
                        fix="FSA files are shallow: a state is 4 levels deep; flatten this "
                        "value")))
            if event.anchor is not None:
                self.problems.append(_at(mark, Problem(
                    f"YAML anchor &{event.anchor} is not allowed in FSA files",
                    fix="remove the anchor and write each value out in full")))
                event.anchor = None  # reported: the composer need not keep (or warn about) it
            tag = _tag_text(event.tag)
            kind, tags = _EXPLICIT_TAGS[type(event)]
            if tag and tag != "!" and tag not in tags:
                allowed = ", ".join(sorted(_short_tag(t) for t in tags))
                self.problems.append(_at(mark, Problem(
                    f"YAML tag {tag!r} is not allowed here in FSA files (they are plain "
                    f"data: no code, and on a {kind} only {allowed})",
                    fix=f"remove {_short_tag(tag)}")))


def _tag_text(tag: Any) -> str:
    if tag is None:
        return ""
    return tag if isinstance(tag, str) else str(getattr(tag, "value", None) or tag)


def _short_tag(tag: str) -> str:
    return "!!" + tag[len(_STD):] if tag.startswith(_STD) else tag


_EXPLICIT_TAGS = {  # the tags allowed on each kind of node, and its name in messages
    ScalarEvent: ("single value",
                  frozenset(_STD + t for t in ("str", "int", "float", "bool", "null"))),
    SequenceStartEvent: ("list", frozenset({_STD + "seq"})),
    MappingStartEvent: ("mapping", frozenset({_STD + "map"})),
}
_INT_RE = re.compile(r"[-+]?(?:0b[01_]*[01][01_]*|0o[0-7_]*[0-7][0-7_]*"
                     r"|0x[0-9a-fA-F_]*[0-9a-fA-F][0-9a-fA-F_]*|[0-9_]*[0-9][0-9_]*)")
_FLOAT_RE = re.compile(r"[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?(?:[eE][-+]?[0-9]+)?"
                       r"|\.[0-9_]*[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?)")
_INF_RE = re.compile(r"[-+]?\.(?:inf|Inf|INF)")
_NAN_RE = re.compile(r"\.(?:nan|NaN|NAN)")
_BOOLS = {"true": True, "True": True, "TRUE": True,
          "false": False, "False": False, "FALSE": False}
_NULLS = frozenset({"", "~", "null", "Null", "NULL"})
_INT_MIN, _INT_MAX = -(2**63), 2**63 - 1


class _BadScalar(ValueError):
    """A scalar cannot be converted; the message says why, ``fix`` how to repair it."""

    def __init__(self, message: str, fix: str) -> None:
        super().__init__(message)
        self.fix = fix


def _to_int(text: str) -> int:
    fix = "write a whole number such as 3, or quote it to keep it as text"
    if not _INT_RE.fullmatch(text):
        raise _BadScalar(f"{clip(text)!r} is not a whole number", fix)
    s = text.replace("_", "")
    sign = -1 if s[0] == "-" else 1
    body = s.lstrip("+-")
    base = {"0b": 2, "0o": 8, "0x": 16}.get(body[:2], 10)
    digits = (body[2:] if base != 10 else body).lstrip("0") or "0"
    # more than 64 digits is more than 64 bits in any base: out of range (and int() is slow)
    value = None if len(digits) > 64 else sign * int(digits, base)
    if value is None or not _INT_MIN <= value <= _INT_MAX:
        raise _BadScalar(
            f"whole number {clip(text)} is out of range [-2**63, 2**63 - 1]",
            "use a smaller number, or quote it to keep it as text",
        )
    return value


def _to_float(text: str) -> float:
    if _INF_RE.fullmatch(text):
        return -math.inf if text.startswith("-") else math.inf
    if _NAN_RE.fullmatch(text):
        return math.nan
    fix = "write a number such as 0.5, 1e-3, .inf or .nan, or quote it to keep it as text"
    if not _FLOAT_RE.fullmatch(text):
        raise _BadScalar(f"{clip(text)!r} is not a number", fix)
    value = float(text.replace("_", ""))
    if math.isinf(value):
        raise _BadScalar(
            f"number {clip(text)} is too large (beyond ±1.8e308)",
            "write .inf or -.inf for infinity, or a smaller number",
        )
    return value


def _str_tag(tag: Any) -> Any:
    """The text tag, of the same kind as ``tag`` (a string or the YAML library's Tag)."""
    if isinstance(tag, str):
        return _STD + "str"
    return type(tag)(suffix=_STD + "str")


_BRACKETS = re.compile(r"[\[\]{}]")
_DIRECTIVE = re.compile(r"^%YAML(?:[ \t]+(\S*))?", re.MULTILINE)


def _check_flow_depth(text: str) -> None:
    """Refuse more than ``_MAX_OPEN_BRACKETS`` brackets open at once, before the YAML
    scanner, which slows down with the square of the flow nesting (2,000 levels: seconds).
    Brackets inside text count too; the parser then checks the real depth exactly."""
    if text.count("[") + text.count("{") <= _MAX_OPEN_BRACKETS:
        return
    depth = 0
    for m in _BRACKETS.finditer(text):
        if m.group() in "[{":
            depth += 1
            if depth > _MAX_OPEN_BRACKETS:
                line, col = _line_col(text, m.start())
                raise _Refused(Problem(
                    f"more than {_MAX_OPEN_BRACKETS} brackets are open here: the data is "
                    f"nested more than {MAX_DEPTH} levels deep",
                    fix="FSA files are shallow: a state is 4 levels deep; flatten this value",
                    line=line, column=col,
                ))
        elif depth:
            depth -= 1


def _check_directives(text: str) -> None:
    """Refuse ``%YAML`` versions other than 1.2 before the parser, which asserts on some."""
    if "%YAML" not in text:
        return
    for m in _DIRECTIVE.finditer(text):
        if m.group(1) != "1.2":
            line, col = _line_col(text, m.start())
            raise _Refused(Problem(
                f"%YAML {m.group(1) or ''} documents are not read: FSA files are YAML 1.2",
                fix="remove the %YAML line", line=line, column=col,
            ))


class _Reader:
    def __init__(self, text: str, path: str | None) -> None:
        # YAML reads "\r\n" and "\r" as line breaks; the round trip's writer knows "\n"
        # only (it dropped the blank lines of a "\r\n" file): one kind of line end for both,
        # the file's own kept for writing it again
        self.newline = "\r\n" if text.count("\r\n") * 2 > text.count("\n") else "\n"
        self.text = text.replace("\r\n", "\n").replace("\r", "\n")
        self.path = path
        self.problems: list[Problem] = []
        self.positions: dict[tuple[str, ...], tuple[int, int]] = {}
        self.values: dict[int, Any] = {}  # id(scalar node) -> its value, set by check_tree

    # -- helpers ---------------------------------------------------------------------------
    def fail(
        self, node: Node, message: str, *, state: str | None = None,
        key: str | None = None, fix: str | None = None,
    ) -> None:
        self.report(node, Problem(message, state, key, fix))

    def report(self, node: Node, problem: Problem | None) -> bool:
        """Note ``problem`` (if any) at ``node``'s position; True when there was one."""
        if problem is not None:
            self.problems.append(_at(node.start_mark, problem))
        return problem is not None

    def raise_if_problems(self) -> None:
        if self.problems:
            raise FSAFileError(self.problems, self.path)

    def mark(self, path: tuple[str, ...], node: Node) -> None:
        self.positions[path] = (node.start_mark.line + 1, node.start_mark.column + 1)

    def check_tree(self, root: Node, constructor: Any) -> None:
        """Convert every scalar once and check every mapping's keys, iteratively.

        What passes here is what the round-trip constructor builds without error: core tags
        only, on the right kind of node; numbers in range; no duplicate or non-scalar keys.
        Problems name the value's path (``meta.a[2]``).
        """
        stack: list[tuple[Node, str]] = [(root, "")]
        while stack:
            node, label = stack.pop()
            if isinstance(node, ScalarNode):
                self.convert(node, label, constructor)
            elif isinstance(node, SequenceNode):
                stack.extend((v, f"{label}[{i}]") for i, v in enumerate(node.value))
            elif isinstance(node, MappingNode):
                self.check_keys(node, label or "the top level", constructor, stack)

    def check_keys(self, node: MappingNode, label: str, constructor: Any,
                   stack: list[tuple[Node, str]]) -> None:
        by_value: dict[Any, Node] = {}
        by_text: dict[str, Node] = {}
        prefix = "" if label == "the top level" else label + "."
        for k, v in node.value:
            if not isinstance(k, ScalarNode):
                self.fail(k, f"{label}: keys must be plain names, got {_node_kind(k)}",
                          fix="write the key as text")
                continue
            stack.append((v, prefix + clip(str(k.value), 30)))
            if not self.convert(k, label, constructor):
                continue
            value = self.values[id(k)]
            text = str(value)
            nan = isinstance(value, float) and math.isnan(value)
            first = by_text.get(text) or (None if nan else by_value.get(value))
            if first is not None:
                self.fail(k, f"{label}: key {clip(text)!r} appears twice (first on line "
                          f"{first.start_mark.line + 1})", key=text, fix="keep one of them")
                continue
            by_text[text] = k
            if not nan:
                by_value[value] = k

    def convert(self, node: ScalarNode, label: str, constructor: Any) -> bool:
        """Set ``self.values[id(node)]`` from a scalar with a core tag; False (and a problem
        naming ``label``) when it cannot be converted."""
        v = node.value
        tag = _tag_text(node.tag)
        name = tag[len(_STD):] if tag.startswith(_STD) else tag
        try:
            if name == "null":
                if v not in _NULLS:
                    raise _BadScalar(f"{clip(v)!r} is not empty (!!null)",
                                     "remove the !!null tag or the value")
                value: Any = None
            elif name == "bool":
                if v not in _BOOLS:
                    raise _BadScalar(f"{clip(v)!r} is not true or false",
                                     "write true or false")
                value = _BOOLS[v]
            elif name == "int":
                value = _to_int(v)
            elif name == "float":
                value = _to_float(v)
            elif name == "timestamp":  # an unquoted date: kept as its text, if it is a date
                try:
                    constructor.construct_yaml_timestamp(node)
                except Exception:
                    raise _BadScalar(f"{clip(v)!r} is not a valid date",
                                     "quote it to keep it as text") from None
                value = v
            elif name in ("value", "yaml"):  # `=` and friends: text
                node.tag = _str_tag(node.tag)
                value = v
            elif name == "str":
                value = v
            elif name == "merge":
                raise _BadScalar("merge keys (<<) are not allowed in FSA files",
                                 "write the keys out in full")
            else:
                raise _BadScalar(f"YAML tag {tag!r} is not allowed in FSA files",
                                 f"remove {_short_tag(tag)}")
        except _BadScalar as exc:
            self.fail(node, f"{label}: {exc}" if label else str(exc), fix=exc.fix)
            return False
        self.values[id(node)] = value
        return True

    def plain(self, node: Node) -> Any:
        """The node as plain Python data (its depth is bounded by :data:`MAX_DEPTH`)."""
        if isinstance(node, MappingNode):
            return {str(self.plain(k)): self.plain(v) for k, v in node.value}
        if isinstance(node, SequenceNode):
            return [self.plain(v) for v in node.value]
        return self.values[id(node)]

    def mapping(
        self, node: Node, what: str, allowed: tuple[str, ...] | None, *,
        state: str | None = None, fix: str | None = None,
    ) -> dict[str, tuple[Node, Node]] | None:
        if state is not None and what.startswith(f"state {state}"):  # said once, by state=
            what = what[len(f"state {state}"):].strip()
        if not isinstance(node, MappingNode):
            self.fail(node, f"{what or 'a state'} must be a mapping (key: value lines), "
                      f"got {_node_kind(node)}", state=state, fix=fix)
            return None
        out: dict[str, tuple[Node, Node]] = {}
        for k, v in node.value:  # plain, distinct keys: check_keys saw to that
            key = str(self.plain(k)) if k.value != "" else ""
            if allowed is not None and key not in allowed:
                close = difflib.get_close_matches(key, allowed, n=1)
                hint = f"did you mean {close[0]!r}?" if close else \
                    f"allowed keys are {', '.join(allowed)}"
                self.fail(k, f"{what + ': ' if what else ''}unknown key {key!r}", state=state,
                          key=key, fix=hint)
                continue
            out[key] = (k, v)
        return out

    def string(self, node: Node, what: str, *, state: str | None = None,
               key: str | None = None, fix: str | None = None) -> str:
        """The name ``node`` holds; "" (and a problem noted) when it holds no name."""
        if not isinstance(node, ScalarNode) or not str(node.tag).endswith(":str"):
            self.fail(node, f"{what} must be a name (text), got {_node_kind(node)}",
                      state=state, key=key, fix=fix)
        elif not node.value:
            self.fail(node, f"{what} is empty", state=state, key=key, fix=fix)
        else:
            return str(node.value)
        return ""

    # -- the format ------------------------------------------------------------------------
    def read(self) -> FSA:
        try:
            yaml, root = self.compose()
        except _Refused as exc:
            raise FSAFileError([exc.problem], self.path) from None
        self.raise_if_problems()
        if root is None:
            raise FSAFileError([Problem(
                "the file is empty", fix="an FSA file needs `format: 1`, `start:` and "
                "`states:`", line=1, column=1)], self.path)
        self.check_tree(root, yaml.constructor)
        self.raise_if_problems()
        return self.read_format(root)

    def compose(self) -> tuple[YAML, Node | None]:
        """Parse the text once into a node tree, within the format's limits."""
        if len(self.text) > MAX_FILE_BYTES:
            raise _Refused(_too_large(*_line_col(self.text, MAX_FILE_BYTES)))
        _check_flow_depth(self.text)
        _check_directives(self.text)
        yaml = YAML(typ="rt")
        yaml.Parser = _GuardedParser
        parser: _GuardedParser = yaml.parser
        try:
            root = yaml.compose(self.text)
        except MarkedYAMLError as exc:
            what = exc.problem or exc.context or "malformed YAML"
            mark = exc.problem_mark or exc.context_mark
            misaligned = _misaligned(self.text, mark) if _INDENT_ERRORS.search(what) else None
            raise _Refused(misaligned or _at(mark, Problem(
                f"not valid YAML: {what}", fix=_yaml_fix(what, self.text, mark),
            ))) from None
        except ReaderError as exc:
            line, col = _line_col(self.text, exc.position)
            char = exc.character
            code = f"{char:04x}" if isinstance(char, int) else str(char)
            raise _Refused(Problem(
                f"character U+{code.upper()} is not allowed in YAML ({exc.reason})",
                fix="delete it, or write it as an escape in a double-quoted string",
                line=line, column=col,
            )) from None
        except (YAMLError, RecursionError, ValueError, TypeError, LookupError,
                AttributeError, AssertionError) as exc:  # the YAML library's own slips
            raise _Refused(_at(parser.last_mark, Problem(
                f"not valid YAML: {type(exc).__name__}: {clip(str(exc), 80)}",
                fix="check the YAML near this line",
            ))) from None
        self.problems.extend(parser.problems)
        return yaml, root

    def read_format(self, root: Node) -> FSA:
        top = self.mapping(root, "the top level", TOP_LEVEL_KEYS,
                           fix="an FSA file is a mapping with format, start and states")
        self.raise_if_problems()
        assert top is not None
        for k, (kn, vn) in top.items():
            self.mark((k,), vn if k in ("start", "step_limit", "format") else kn)
        for req, example in REQUIRED_TOP_LEVEL.items():
            if req not in top:
                self.fail(root, f"missing top-level key {req!r}", key=req, fix=f"add `{example}`")
        if "format" in top:
            fnode = top["format"][1]
            fv = self.plain(fnode)
            if fv != FORMAT_VERSION or not isinstance(fv, int) or isinstance(fv, bool):
                self.fail(fnode, f"format {fv!r} is not supported; this version of "
                          f"skillcompose reads format {FORMAT_VERSION}", key="format",
                          fix=f"set `format: {FORMAT_VERSION}`")
        name = self.string(top["name"][1], "name", key="name") if "name" in top else ""
        start = ""
        if "start" in top:
            start = self.string(top["start"][1], "start", key="start",
                                fix="set `start:` to the name of the first state")
        step_limit: Any = DEFAULT_STEP_LIMIT
        if "step_limit" in top:
            node = top["step_limit"][1]
            step_limit = self.plain(node)
            if self.report(node, step_limit_problem(step_limit)):
                step_limit = DEFAULT_STEP_LIMIT
        terminals: tuple[str, ...] = DEFAULT_TERMINALS
        if "terminals" in top:
            node = top["terminals"][1]
            if not isinstance(node, SequenceNode):
                self.fail(node, "terminals must be a list of outcome names",
                          key="terminals", fix="for example `terminals: [success, failure]`")
            else:
                terminals = tuple(self.string(v, "a terminal outcome", key="terminals")
                                  for v in node.value)
        meta: dict[str, Any] = {}
        if "meta" in top:
            node = top["meta"][1]
            if not isinstance(node, MappingNode):
                self.fail(node, "meta must be a mapping", key="meta")
            else:
                meta = self.plain(node)
        states = self.read_states(*top["states"]) if "states" in top else {}
        self.raise_if_problems()
        source = FileOrigin(self.path, dict(self.positions), self.text, root=root,
                            newline=self.newline)
        try:
            return FSA(states, start, terminals, step_limit, name, meta, source)
        except FSAValidationError as exc:
            raise FSAFileError(exc.problems, self.path) from None

    def read_states(self, key: Node, node: Node) -> dict[str, State]:
        smap = self.mapping(node, "states", None,
                            fix="write each state as `<name>: {skill: ..., transitions: ...}`")
        if smap is None:
            return {}
        if not smap:
            self.fail(node, "states is empty", fix="add at least one state")
        if len(smap) > MAX_STATES:
            self.fail(key, f"{len(smap)} states; an FSA file holds at most {MAX_STATES}",
                      fix="split it into nested FSAs (registry.add_fsa)")
            return {}
        states: dict[str, State] = {}
        for sname, (kn, vn) in smap.items():
            self.mark(("states", sname), kn)
            st = self.read_state(sname, vn)
            if st is not None:
                states[sname] = st
        return states

    def read_state(self, sname: str, node: Node) -> State | None:
        fields = self.mapping(node, f"state {sname}", STATE_KEYS, state=sname,
                              fix="a state has `skill:`, `params:`, `transitions:` and "
                              "`time_limit:`")
        if fields is None:
            return None
        # every value below that cannot be read is a problem noted, and read_format raises
        # them all: a state read in part is never used
        for req, example in REQUIRED_STATE_KEYS.items():
            if req not in fields:
                self.fail(node, f"missing key {req!r}", state=sname, key=req,
                          fix=f"add `{example}`")
        skill = ""
        if "skill" in fields:
            self.mark(("states", sname, "skill"), fields["skill"][1])
            skill = self.string(fields["skill"][1], "skill", state=sname, key="skill",
                                fix="write the skill's name, e.g. `skill: GraspObject`")
        params: dict[str, Any] = {}
        if "params" in fields:
            pnode = fields["params"][1]
            self.mark(("states", sname, "params"), fields["params"][0])
            empty = isinstance(pnode, ScalarNode) and str(pnode.tag).endswith(":null")
            pmap = None if empty else self.mapping(
                pnode, f"state {sname} params", None, state=sname,
                fix="write `params: {name: value}`")
            for pname, (_, pv) in (pmap or {}).items():
                self.mark(("states", sname, "params", pname), pv)
                if isinstance(pv, SequenceNode) and all(
                    isinstance(item, ScalarNode) for item in pv.value
                ):  # a vector parameter: one flat list of numbers
                    params[pname] = tuple(self.plain(item) for item in pv.value)
                elif isinstance(pv, ScalarNode):
                    params[pname] = self.plain(pv)
                else:
                    self.fail(pv, f"parameter {pname!r} must be a single value (number, "
                              "true/false or text) or, for a vector parameter, a flat list "
                              f"of numbers; got {_node_kind(pv)}", state=sname, key=pname)
        transitions: dict[str, str] = {}
        if "transitions" in fields:
            self.mark(("states", sname, "transitions"), fields["transitions"][0])
            tmap = self.mapping(fields["transitions"][1], f"state {sname} transitions", None,
                                state=sname, fix="write `transitions: {outcome: target}`")
            for outcome, (_, tv) in (tmap or {}).items():
                self.mark(("states", sname, "transitions", outcome), tv)
                transitions[outcome] = self.string(
                    tv, f"the target of outcome {outcome!r}", state=sname, key=outcome,
                    fix="write a state name or a terminal outcome such as success")
        time_limit: float | None = None
        if "time_limit" in fields:
            tnode = fields["time_limit"][1]
            self.mark(("states", sname, "time_limit"), tnode)
            value = self.plain(tnode)
            if not self.report(tnode, time_limit_problem(value, sname)):
                time_limit = float(value)
        return State(skill, params, transitions, time_limit)


def _node_kind(node: Node) -> str:
    if isinstance(node, MappingNode):
        return "a mapping"
    if isinstance(node, SequenceNode):
        return "a list"
    tag = str(node.tag).rsplit(":", 1)[-1]
    return {"null": "nothing", "str": f"text {node.value!r}"}.get(tag, f"{tag} {node.value}")


# ---------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------
def dumps_fsa(fsa: FSA, registry: SkillLookup | None = None, *, header: str | None = None) -> str:
    """The FSA as file text. A loaded FSA keeps its file's comments and layout.

    With a ``registry``, parameters of new states carry their unit and range as comments.
    """
    if not isinstance(fsa, FSA):
        raise TypeError(f"dumps_fsa takes an FSA, got {clip(repr(fsa), 40)}; read a file "
                       "with load_fsa or build one with FSA(...)")
    origin = fsa.source
    doc = origin.document() if isinstance(origin, FileOrigin) else None
    if isinstance(doc, CommentedMap) and isinstance(origin, FileOrigin):
        _sync_document(doc, fsa, registry, origin.renames)
        text = _dump(doc)
        return text.replace("\n", "\r\n") if origin.newline == "\r\n" else text
    return _dump(_new_document(fsa, registry, header))


def in_layout_of(fsa: FSA, seed: FSA, keep: Collection[str], header: str) -> FSA:
    """``fsa``, to be written in the layout of the file ``seed`` was read from: its states
    named in ``keep`` keep their text and comments there, the others are written afresh,
    and the file starts with the comment ``header``. ``fsa`` itself if ``seed`` has no file.
    """
    doc = seed.source.document() if isinstance(seed.source, FileOrigin) else None
    if not isinstance(doc, CommentedMap):
        return fsa
    kept = doc.get("states")
    if isinstance(kept, CommentedMap):
        for gone in [k for k in kept if k not in keep]:
            del kept[gone]
    doc.yaml_set_start_comment(header)
    return fsa.replace(source=FileOrigin(None, {}, _dump(doc)))


@dataclass(frozen=True)
class FileOrigin(Source):
    """The file layer's handle on the text an FSA was read from, owned by the writer: the
    text, the states renamed since (old -> new, so that a save tells a renamed state from a
    new one) and the node tree of the reader's one parse, from which each save builds the
    round-trip document (comments, order, formatting) without parsing again."""

    text: str = ""
    renames: Mapping[str, str] = field(default_factory=dict)
    root: Node | None = field(default=None, compare=False, repr=False)
    newline: str = field(default="\n", compare=False)  # the file's line end, when written

    def renamed(self, old: str, new: str) -> FileOrigin:
        renames = {k: (new if v == old else v) for k, v in self.renames.items()}
        if old not in self.renames.values():
            renames[old] = new
        return dataclasses.replace(self, renames=renames)

    def document(self) -> Any:
        """A fresh round-trip document of the text (the reader's nodes, else a parse)."""
        yaml = YAML(typ="rt")
        return yaml.load(self.text) if self.root is None else \
            yaml.constructor.construct_document(self.root)

    def __reduce__(self) -> tuple[Any, ...]:  # a copy sent elsewhere parses the text again
        return FileOrigin, (self.path, self.positions, self.text, self.renames)


def _dump(doc: Any) -> str:
    yaml = YAML(typ="rt")
    yaml.indent(mapping=2, sequence=4, offset=2)
    yaml.width = 100
    buf = io.StringIO()
    yaml.dump(_unfoldable(doc), buf)
    return buf.getvalue()


def _unfoldable(node: Any) -> Any:
    """``node`` with every plain string that holds a run of spaces double-quoted: the emitter
    folds a long plain string at its spaces, and reading it back turns a folded run of spaces
    into one (``"x" + 120 spaces + "y"`` came back as ``"x y"``); a double-quoted string is
    folded with escapes that keep every space."""
    if isinstance(node, (CommentedMap, CommentedSeq)):  # in place: comments stay
        for key, value in (node.items() if isinstance(node, CommentedMap) else
                           enumerate(node)):
            node[key] = _unfoldable(value)
    elif type(node) is dict:
        return {key: _unfoldable(value) for key, value in node.items()}
    elif type(node) is list:
        return [_unfoldable(value) for value in node]
    elif type(node) is str and ("  " in node or node != node.strip(" ")):
        return DoubleQuotedScalarString(node)
    return node


_INDENT_ERRORS = re.compile(r"mapping values are not allowed|expected <block end>|"
                            r"did not find expected key|could not find expected ':'")


def _content(line: str) -> bool:
    stripped = line.strip()
    return bool(stripped) and not stripped.startswith("#")


def _misaligned(text: str, mark: Any) -> Problem | None:
    """A key indented to no level of the mapping it sits in, at or just before the parser's
    error (which YAML often reports on the next line, in its own words): the line, where the
    keys around it start, and the fix; None when the indentation is not the slip."""
    if mark is None:
        return None
    lines = text.splitlines()
    for at in (mark.line, mark.line - 1):
        if not 0 <= at < len(lines) or not _content(lines[at]):
            continue
        open_levels: list[int] = []  # the indentations of the blocks still open
        previous: str | None = None
        for line in lines[:at]:
            if not _content(line):
                continue
            indent = len(line) - len(line.lstrip(" "))
            while open_levels and open_levels[-1] > indent:
                open_levels.pop()
            if not open_levels or open_levels[-1] < indent:
                open_levels.append(indent)
            previous = line
        line = lines[at]
        indent = len(line) - len(line.lstrip(" "))
        opens = previous is not None and re.split(r"\s#", previous)[0].rstrip().endswith(":")
        deeper = previous is not None and indent > len(previous) - len(previous.lstrip(" "))
        if indent in open_levels or (opens and deeper) or not open_levels:
            continue
        key = line.strip().split(":", 1)[0]
        assert previous is not None  # open_levels is not empty
        before = len(previous) - len(previous.lstrip(" "))
        like = before + 2 if opens else before  # beside the line above, or inside it
        return Problem(
            f"`{clip(key, 40)}` is indented {_spaces(indent)}, which lines up with no key "
            f"before it (they start at {', '.join(map(str, sorted(set(open_levels))))} "
            "spaces)",
            fix=f"indent it by {_spaces(like)}, "
                + ("inside the key above it" if opens else "like the key above it"),
            line=at + 1, column=indent + 1)
    return None


def _spaces(n: int) -> str:
    return "1 space" if n == 1 else f"{n} spaces"


def _yaml_fix(what: str, text: str, mark: Any) -> str:
    """The fix for a YAML syntax error, for the slips people make by hand; the general advice
    when the slip is not one of them."""
    near: list[str] = []  # the error's line and the one before it (YAML often sees a slip
    if mark is not None and getattr(mark, "line", None) is not None:  # a line late), bare:
        for line in text.splitlines()[max(0, mark.line - 1):mark.line + 1]:
            bare = re.sub(r"'[^']*'|\"[^\"]*\"", "''", line)  # no quoted text, no comment
            near.append(re.split(r"(?:^|\s)#", bare, maxsplit=1)[0])
    if "another document" in what or "document start" in what:
        if re.search(r"^---\s*$", text, re.M):
            return "an FSA file holds one document: remove the `---` line (or the second FSA)"
        return "an FSA file is one mapping of `key: value` lines; check the lines from here"
    if "'\\t'" in what or "\t" in what:
        return "replace the tab with spaces"
    if any("\u00a0" in line for line in near):
        return "a non-breaking space (U+00A0) is near here: replace it with a plain space"
    if "mapping values are not allowed" in what and any(
            re.match(r"\s*(?:-\s+)?[\w.-]+:[^\s:]", line) for line in near):
        return "put a space after each ':' that ends a key (`success: Grasp`)"
    return "check indentation, colons and quotes near this line"


def save_fsa(
    fsa: FSA, path: str | os.PathLike[str], registry: SkillLookup | None = None,
    *, header: str | None = None,
) -> FSA:
    """Write ``fsa`` to ``path`` atomically, keeping the mode of the file it replaces (a new
    file gets the umask's); return it bound to that file for later saves."""
    if Path(path).is_dir():
        raise IsADirectoryError(f"{path} is a folder: give save_fsa a file path, e.g. "
                       f"{Path(path) / 'fsa.yaml'}")
    text = dumps_fsa(fsa, registry, header=header)
    atomic_write(path, text.encode("utf-8"))
    return loads_fsa(text, str(Path(path)))


def _py(value: Any) -> Any:
    """Plain Python values: of an FSA for the emitter (numpy scalars become floats/ints), of
    a document for comparing (the YAML library's scalars become bool/int/float/str)."""
    if isinstance(value, Mapping):
        return {str(k): _py(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_py(v) for v in value]
    for kind in (bool, int, float, str):
        if isinstance(value, kind):
            return kind(value)
    if hasattr(value, "item") and callable(value.item):  # numpy scalar
        return value.item()
    return value


def _state_map(st: State, registry: SkillLookup | None) -> CommentedMap:
    """A new state's mapping, its parameters' units and ranges and its time limit's unit as
    comments."""
    m = CommentedMap()
    _sync_state(m, st)
    if registry is not None:
        for k in st.params:
            with suppress(UnknownSkillError, ParamError):  # not the registry's: no comment
                comment = registry.spec(st.skill).param(k).describe_range()
                m["params"].yaml_add_eol_comment(comment, k)
    if st.time_limit is not None:
        m.yaml_add_eol_comment("s: a longer state ends with `timeout`", "time_limit")
    return m


def _new_document(fsa: FSA, registry: SkillLookup | None, header: str | None) -> CommentedMap:
    # the keys a new file always has, in order, for the sync to fill; meta as plain data
    doc = CommentedMap((k, None) for k in TOP_LEVEL_KEYS[:5] if k != "name" or fsa.name)
    if fsa.meta:
        doc["states"], doc["meta"] = CommentedMap(), _py(fsa.meta)
    _sync_document(doc, fsa, registry, {})
    text = _HEADER if header is None else header
    if text:
        doc.yaml_set_start_comment(text)
    doc.yaml_add_eol_comment("more steps than this end the run with `timeout`", "step_limit")
    return doc


def _set(m: CommentedMap, key: str, value: Any) -> None:
    """Assign only when the value changed, so untouched values keep their formatting."""
    value = _py(value)
    if key in m and _equal(_py(m[key]), value) and _emits_exactly(m[key]):
        return
    if isinstance(value, list):  # terminals, vector parameters: one line (or a few)
        value = CommentedSeq(value)
        value.fa.set_flow_style()
    m[key] = value


def _emits_exactly(v: Any) -> bool:
    """False for a float the YAML library would write back with a different value.

    ruamel.yaml keeps a loaded float's formatting, but re-emits some long exponent forms
    with a changed last digit; such values are written afresh instead.
    """
    if not isinstance(v, float) or type(v) is float:
        return True
    try:
        back = _to_float(RoundTripRepresenter().represent_scalar_float(v).value)
    except Exception:
        return False
    return back == float(v) or (math.isnan(back) and math.isnan(float(v)))


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b) and (type(a) is type(b) or isinstance(a, (dict, list)))


def _rename_key(m: CommentedMap, old: str, new: str) -> None:
    pos = list(m).index(old)
    value = m[old]
    comment = m.ca.items.pop(old, None)
    del m[old]
    m.insert(pos, new, value)
    if comment is not None:
        m.ca.items[new] = comment


def _child_map(m: CommentedMap, key: str) -> CommentedMap:
    """``m[key]``, made an empty mapping first unless it is one."""
    child = m.get(key)
    if not isinstance(child, CommentedMap):
        child = m[key] = CommentedMap()
    return child


def _sync_map(m: CommentedMap, values: Mapping[str, Any]) -> None:
    for k in [k for k in m if k not in values]:
        del m[k]
    for k, v in values.items():
        _set(m, k, v)


def _sync_document(
    doc: CommentedMap, fsa: FSA, registry: SkillLookup | None, renames: Mapping[str, str]
) -> None:
    _set(doc, "format", FORMAT_VERSION)
    if fsa.name or "name" in doc:
        _set(doc, "name", fsa.name)
    _set(doc, "start", fsa.start)
    if fsa.step_limit != DEFAULT_STEP_LIMIT or "step_limit" in doc:
        _set(doc, "step_limit", fsa.step_limit)
    if fsa.terminals != DEFAULT_TERMINALS or "terminals" in doc:
        _set(doc, "terminals", list(fsa.terminals))
    states = _child_map(doc, "states")
    for old, new in renames.items():
        if old in states and new not in states:
            _rename_key(states, old, new)
    for gone in [k for k in states if k not in fsa.states]:
        del states[gone]
    for sname, st in fsa.states.items():
        cur = states.get(sname)
        if isinstance(cur, CommentedMap):
            _sync_state(cur, st)
        else:
            states[sname] = _state_map(st, registry)
    if fsa.meta or "meta" in doc:
        if not isinstance(doc.get("meta"), dict):
            doc["meta"] = CommentedMap()
        _sync_map(doc["meta"], fsa.meta)


def _sync_state(cur: CommentedMap, st: State) -> None:
    _set(cur, "skill", st.skill)
    if st.params or "params" in cur:
        pm = cur.get("params")
        if not isinstance(pm, CommentedMap):
            pm = CommentedMap()
            cur.insert(list(cur.keys()).index("skill") + 1 if "skill" in cur else 0,
                       "params", pm)
        _sync_map(pm, st.params)
    _sync_map(_child_map(cur, "transitions"), st.transitions)
    if st.time_limit is not None:
        _set(cur, "time_limit", st.time_limit)
    elif "time_limit" in cur:
        del cur["time_limit"]
