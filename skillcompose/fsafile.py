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
are in the skill's own units. Loading accepts plain YAML only (no tags, anchors or merge keys)
and reports every problem with its file, line and column, the state and key, what was
expected and the fix. Saving an FSA that was loaded from a file edits that file's document in
place, so comments, key order and formatting survive.
"""

from __future__ import annotations

import copy
import io
import math
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import MarkedYAMLError, YAMLError
from ruamel.yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from .errors import FSAFileError, FSAValidationError, Problem
from .fsa import DEFAULT_STEP_LIMIT, DEFAULT_TERMINALS, FSA, Source, State

if TYPE_CHECKING:
    from .registry import Registry

__all__ = [
    "FORMAT_VERSION",
    "STATE_KEYS",
    "TOP_LEVEL_KEYS",
    "dumps_fsa",
    "load_fsa",
    "loads_fsa",
    "save_fsa",
]

FORMAT_VERSION = 1
TOP_LEVEL_KEYS = ("format", "name", "start", "step_limit", "terminals", "states", "meta")
REQUIRED_TOP_LEVEL = ("format", "start", "states")
STATE_KEYS = ("skill", "params", "transitions", "time_limit")
REQUIRED_STATE_KEYS = ("skill", "transitions")

_STD = "tag:yaml.org,2002:"
_ALLOWED_TAGS = frozenset(
    _STD + t for t in ("str", "int", "float", "bool", "null", "map", "seq", "timestamp")
)
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
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FSAFileError([Problem("file not found", fix="check the path")], str(p)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise FSAFileError([Problem(f"cannot read the file: {exc}")], str(p)) from None
    return loads_fsa(text, str(p))


def loads_fsa(text: str, path: str | None = None) -> FSA:
    """Parse FSA text; ``path`` is used in error messages only."""
    return _Reader(text, path).read()


class _Reader:
    def __init__(self, text: str, path: str | None) -> None:
        self.text = text
        self.path = path
        self.problems: list[Problem] = []
        self.positions: dict[tuple[str, ...], tuple[int, int]] = {}

    # -- helpers ---------------------------------------------------------------------------
    def fail(
        self, node: Node | None, message: str, *, state: str | None = None,
        key: str | None = None, fix: str | None = None,
    ) -> None:
        line = col = None
        if node is not None and node.start_mark is not None:
            line, col = node.start_mark.line + 1, node.start_mark.column + 1
        self.problems.append(Problem(message, state, key, fix, line, col))

    def raise_if_problems(self) -> None:
        if self.problems:
            raise FSAFileError(self.problems, self.path)

    def mark(self, path: tuple[str, ...], node: Node) -> None:
        self.positions[path] = (node.start_mark.line + 1, node.start_mark.column + 1)

    def check_plain(self, node: Node, seen: set[int]) -> bool:
        """Reject tags, anchors, aliases and merge keys anywhere in the tree."""
        if id(node) in seen:
            self.fail(node, "YAML aliases (*name) are not allowed in FSA files",
                      fix="write the value out in full")
            return False
        seen.add(id(node))
        tag = node.tag if isinstance(node.tag, str) else getattr(node.tag, "value", "")
        ok = True
        if str(tag) not in _ALLOWED_TAGS:
            self.fail(node, f"YAML tag {tag!r} is not allowed in FSA files "
                      "(they are plain data: no tags, no code)", fix=f"remove {tag}")
            return False
        if getattr(node, "anchor", None):
            self.fail(node, f"YAML anchor &{node.anchor} is not allowed in FSA files",
                      fix="remove the anchor and write each value out in full")
            ok = False
        if isinstance(node, MappingNode):
            for k, v in node.value:
                ok = self.check_plain(k, seen) and ok
                ok = self.check_plain(v, seen) and ok
        elif isinstance(node, SequenceNode):
            for v in node.value:
                ok = self.check_plain(v, seen) and ok
        return ok

    def scalar(self, node: Node) -> Any:
        if not isinstance(node, ScalarNode):
            return self.plain(node)
        tag = str(node.tag)
        v = node.value
        if tag.endswith(":null"):
            return None
        if tag.endswith(":bool"):
            return v.lower() == "true"
        if tag.endswith(":int"):
            s = v.replace("_", "")
            sign = -1 if s.startswith("-") else 1
            body = s.lstrip("+-")
            if body[:2].lower() in ("0x", "0o", "0b"):
                return sign * int(body, 0)
            return sign * int(body, 10)
        if tag.endswith(":float"):
            low = v.lower().lstrip("+")
            if low == ".inf":
                return math.inf
            if low == "-.inf":
                return -math.inf
            if low == ".nan":
                return math.nan
            return float(v.replace("_", ""))
        return v

    def plain(self, node: Node) -> Any:
        if isinstance(node, MappingNode):
            return {str(self.scalar(k)): self.plain(v) for k, v in node.value}
        if isinstance(node, SequenceNode):
            return [self.plain(v) for v in node.value]
        return self.scalar(node)

    def mapping(
        self, node: Node, what: str, allowed: tuple[str, ...] | None, *,
        state: str | None = None, fix: str | None = None,
    ) -> dict[str, tuple[Node, Node]] | None:
        if not isinstance(node, MappingNode):
            self.fail(node, f"{what} must be a mapping (key: value lines), "
                      f"got {_node_kind(node)}", state=state, fix=fix)
            return None
        out: dict[str, tuple[Node, Node]] = {}
        for k, v in node.value:
            if not isinstance(k, ScalarNode):
                self.fail(k, f"{what}: keys must be plain names", state=state)
                continue
            key = str(self.scalar(k)) if k.value != "" else ""
            if key in out:
                first = out[key][0].start_mark.line + 1
                self.fail(k, f"{what}: key {key!r} appears twice (first on line {first})",
                          state=state, key=key, fix="keep one of them")
                continue
            if allowed is not None and key not in allowed:
                import difflib

                close = difflib.get_close_matches(key, allowed, n=1)
                hint = f"did you mean {close[0]!r}?" if close else \
                    f"allowed keys are {', '.join(allowed)}"
                self.fail(k, f"{what}: unknown key {key!r}", state=state, key=key, fix=hint)
                continue
            out[key] = (k, v)
        return out

    def string(self, node: Node, what: str, *, state: str | None = None,
               key: str | None = None, fix: str | None = None) -> str | None:
        if not isinstance(node, ScalarNode) or not str(node.tag).endswith(":str"):
            self.fail(node, f"{what} must be a name (text), got {_node_kind(node)}",
                      state=state, key=key, fix=fix)
            return None
        if not node.value:
            self.fail(node, f"{what} is empty", state=state, key=key, fix=fix)
            return None
        return str(node.value)

    # -- the format ------------------------------------------------------------------------
    def read(self) -> FSA:
        yaml = YAML(typ="rt")
        try:
            root = yaml.compose(self.text)
        except MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            line = mark.line + 1 if mark is not None else None
            col = mark.column + 1 if mark is not None else None
            what = exc.problem or exc.context or "malformed YAML"
            self.problems.append(Problem(
                f"not valid YAML: {what}", fix="check indentation, colons and quotes near "
                "this line", line=line, column=col,
            ))
            self.raise_if_problems()
            raise AssertionError("unreachable") from None
        except YAMLError as exc:
            self.problems.append(Problem(f"not valid YAML: {exc}"))
            self.raise_if_problems()
            raise AssertionError("unreachable") from None
        if root is None:
            self.problems.append(Problem(
                "the file is empty", fix="an FSA file needs `format: 1`, `start:` and "
                "`states:`"))
            self.raise_if_problems()
        assert root is not None
        self.check_plain(root, set())
        self.raise_if_problems()
        top = self.mapping(root, "the top level", TOP_LEVEL_KEYS,
                           fix="an FSA file is a mapping with format, start and states")
        self.raise_if_problems()
        assert top is not None
        for k, (kn, vn) in top.items():
            self.mark((k,), vn if k in ("start", "step_limit", "format") else kn)
        for req in REQUIRED_TOP_LEVEL:
            if req not in top:
                example = {"format": "format: 1", "start": "start: <name of the first state>",
                           "states": "states: {<name>: {skill: ..., transitions: {...}}}"}
                self.fail(root, f"missing top-level key {req!r}", key=req,
                          fix=f"add `{example[req]}`")
        if "format" in top:
            fnode = top["format"][1]
            fv = self.scalar(fnode)
            if fv != FORMAT_VERSION or isinstance(fv, bool):
                self.fail(fnode, f"format {fv!r} is not supported; this version of "
                          f"skillcompose reads format {FORMAT_VERSION}", key="format",
                          fix=f"set `format: {FORMAT_VERSION}`")
        name = ""
        if "name" in top:
            name = self.string(top["name"][1], "name", key="name") or ""
        start = ""
        if "start" in top:
            start = self.string(top["start"][1], "start", key="start",
                                fix="set `start:` to the name of the first state") or ""
        step_limit: Any = DEFAULT_STEP_LIMIT
        if "step_limit" in top:
            node = top["step_limit"][1]
            step_limit = self.scalar(node)
            if not isinstance(step_limit, int) or isinstance(step_limit, bool) or \
                    step_limit < 1:
                self.fail(node, f"step_limit must be a positive whole number, got "
                          f"{step_limit!r}", key="step_limit", fix="for example `step_limit: 20`")
                step_limit = DEFAULT_STEP_LIMIT
        terminals: tuple[str, ...] = DEFAULT_TERMINALS
        if "terminals" in top:
            node = top["terminals"][1]
            if not isinstance(node, SequenceNode):
                self.fail(node, "terminals must be a list of outcome names",
                          key="terminals", fix="for example `terminals: [success, failure]`")
            else:
                items = [self.string(v, "a terminal outcome", key="terminals")
                         for v in node.value]
                terminals = tuple(t for t in items if t)
        meta: dict[str, Any] = {}
        if "meta" in top:
            node = top["meta"][1]
            if not isinstance(node, MappingNode):
                self.fail(node, "meta must be a mapping", key="meta")
            else:
                meta = self.plain(node)
        states: dict[str, State] = {}
        if "states" in top:
            states = self.read_states(top["states"][1])
        self.raise_if_problems()
        document = YAML(typ="rt").load(self.text)
        source = Source(self.path, dict(self.positions), document)
        try:
            return FSA(states, start, terminals, step_limit, name, meta, source)
        except FSAValidationError as exc:
            raise FSAFileError(exc.problems, self.path) from None

    def read_states(self, node: Node) -> dict[str, State]:
        smap = self.mapping(node, "states", None,
                            fix="write each state as `<name>: {skill: ..., transitions: ...}`")
        if smap is None:
            return {}
        if not smap:
            self.fail(node, "states is empty", fix="add at least one state")
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
        ok = True
        for req in REQUIRED_STATE_KEYS:
            if req not in fields:
                example = {"skill": "skill: <SkillName>",
                           "transitions": "transitions: {success: <state or terminal>}"}
                self.fail(node, f"missing key {req!r}", state=sname, key=req,
                          fix=f"add `{example[req]}`")
                ok = False
        skill = ""
        if "skill" in fields:
            self.mark(("states", sname, "skill"), fields["skill"][1])
            skill = self.string(fields["skill"][1], "skill", state=sname, key="skill",
                                fix="write the skill's name, e.g. `skill: GraspObject`") or ""
            ok = ok and bool(skill)
        params: dict[str, Any] = {}
        if "params" in fields:
            pnode = fields["params"][1]
            self.mark(("states", sname, "params"), fields["params"][0])
            if isinstance(pnode, ScalarNode) and str(pnode.tag).endswith(":null"):
                pass
            else:
                pmap = self.mapping(pnode, f"state {sname} params", None, state=sname,
                                    fix="write `params: {name: value}`")
                for pname, (_, pv) in (pmap or {}).items():
                    self.mark(("states", sname, "params", pname), pv)
                    if isinstance(pv, SequenceNode) and all(
                        isinstance(item, ScalarNode) for item in pv.value
                    ):  # a vector parameter: one flat list of numbers
                        params[pname] = tuple(self.scalar(item) for item in pv.value)
                        continue
                    if not isinstance(pv, ScalarNode):
                        self.fail(pv, f"parameter {pname!r} must be a single value "
                                  f"(number, true/false or text) or, for a vector "
                                  f"parameter, a flat list of numbers; got {_node_kind(pv)}",
                                  state=sname, key=pname)
                        ok = False
                        continue
                    params[pname] = self.scalar(pv)
        transitions: dict[str, str] = {}
        if "transitions" in fields:
            self.mark(("states", sname, "transitions"), fields["transitions"][0])
            tmap = self.mapping(fields["transitions"][1], f"state {sname} transitions", None,
                                state=sname, fix="write `transitions: {outcome: target}`")
            if tmap is None:
                ok = False
            for outcome, (_, tv) in (tmap or {}).items():
                self.mark(("states", sname, "transitions", outcome), tv)
                target = self.string(tv, f"the target of outcome {outcome!r}", state=sname,
                                     key=outcome, fix="write a state name or a terminal "
                                     "outcome such as success")
                if target is None:
                    ok = False
                    continue
                transitions[outcome] = target
        time_limit: float | None = None
        if "time_limit" in fields:
            tnode = fields["time_limit"][1]
            self.mark(("states", sname, "time_limit"), tnode)
            value = self.scalar(tnode)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                    not math.isfinite(value) or value <= 0:
                self.fail(tnode, f"time_limit must be a positive number of seconds, got "
                          f"{value!r}", state=sname, key="time_limit",
                          fix="for example `time_limit: 2.0`")
                ok = False
            else:
                time_limit = float(value)
        return State(skill, params, transitions, time_limit) if ok else None


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
def dumps_fsa(fsa: FSA, registry: Registry | None = None, *, header: str | None = None) -> str:
    """The FSA as file text. A loaded FSA keeps its file's comments and layout.

    With a ``registry``, parameters of new states carry their unit and range as comments.
    """
    doc = fsa.source.document if fsa.source is not None else None
    if isinstance(doc, CommentedMap):
        doc = copy.deepcopy(doc)  # the loaded FSA keeps its own document untouched
        _sync_document(doc, fsa, registry, fsa.source.renames if fsa.source else {})
    else:
        doc = _new_document(fsa, registry, header)
    yaml = _yaml_out()
    buf = io.StringIO()
    yaml.dump(doc, buf)
    return buf.getvalue()


def save_fsa(
    fsa: FSA, path: str | os.PathLike[str], registry: Registry | None = None,
    *, header: str | None = None,
) -> FSA:
    """Write ``fsa`` to ``path`` atomically; return it bound to that file for later saves."""
    text = dumps_fsa(fsa, registry, header=header)
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", dir=p.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return loads_fsa(text, str(p))


def _yaml_out() -> YAML:
    yaml = YAML(typ="rt")
    yaml.indent(mapping=2, sequence=4, offset=2)
    yaml.width = 100
    return yaml


def _py(value: Any) -> Any:
    """Plain Python values for the emitter (numpy scalars become floats/ints)."""
    if isinstance(value, Mapping):
        return {str(k): _py(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_py(v) for v in value]
    if hasattr(value, "item") and callable(value.item):  # numpy scalar
        return value.item()
    return value


def _flow_list(items: list[Any]) -> CommentedSeq:
    seq = CommentedSeq(items)
    seq.fa.set_flow_style()
    return seq


def _param_comment(registry: Registry | None, skill: str, pname: str) -> str | None:
    if registry is None or skill not in registry:
        return None
    try:
        spec = registry.spec(skill).param(pname)
    except Exception:
        return None
    return spec.describe_range()


def _state_map(st: State, registry: Registry | None) -> CommentedMap:
    m = CommentedMap()
    m["skill"] = st.skill
    if st.params:
        pm = CommentedMap()
        for k, v in st.params.items():
            value = _py(v)
            pm[k] = _flow_list(value) if isinstance(value, list) else value
            c = _param_comment(registry, st.skill, k)
            if c:
                pm.yaml_add_eol_comment(c, k)
        m["params"] = pm
    tm = CommentedMap()
    for o, t in st.transitions.items():
        tm[o] = t
    m["transitions"] = tm
    if st.time_limit is not None:
        m["time_limit"] = st.time_limit
        m.yaml_add_eol_comment("s: a longer state ends with `timeout`", "time_limit")
    return m


def _new_document(fsa: FSA, registry: Registry | None, header: str | None) -> CommentedMap:
    doc = CommentedMap()
    doc["format"] = FORMAT_VERSION
    if fsa.name:
        doc["name"] = fsa.name
    doc["start"] = fsa.start
    doc["step_limit"] = fsa.step_limit
    doc["terminals"] = _flow_list(list(fsa.terminals))
    states = CommentedMap()
    for sname, st in fsa.states.items():
        states[sname] = _state_map(st, registry)
    doc["states"] = states
    if fsa.meta:
        doc["meta"] = _py(fsa.meta)
    text = _HEADER if header is None else header
    if text:
        doc.yaml_set_start_comment(text)
    doc.yaml_add_eol_comment("more steps than this end the run with `timeout`", "step_limit")
    return doc


def _set(m: CommentedMap, key: str, value: Any) -> None:
    """Assign only when the value changed, so untouched values keep their formatting."""
    value = _py(value)
    if key in m and _equal(_plain(m[key]), value) and _emits_exactly(m[key]):
        return
    if isinstance(value, list):  # terminals, vector parameters: one line (or a few)
        value = _flow_list(value)
    m[key] = value


def _emits_exactly(v: Any) -> bool:
    """False for a float the YAML library would write back with a different value.

    ruamel.yaml keeps a loaded float's formatting, but re-emits some long exponent forms
    with a changed last digit; such values are written afresh instead.
    """
    if not isinstance(v, float) or type(v) is float:
        return True
    buf = io.StringIO()
    _yaml_out().dump({"v": v}, buf)
    try:
        back = YAML(typ="safe").load(buf.getvalue())["v"]
    except Exception:
        return False
    return bool(back == float(v)) or (math.isnan(back) and math.isnan(float(v)))


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b and type(a) is type(b)) or (
        isinstance(a, (dict, list)) and a == b
    )


def _plain(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_plain(x) for x in v]
    if isinstance(v, bool):
        return bool(v)
    if isinstance(v, int):
        return int(v)
    if isinstance(v, float):
        return float(v)
    if isinstance(v, str):
        return str(v)
    return v


def _rename_key(m: CommentedMap, old: str, new: str) -> None:
    keys = list(m.keys())
    pos = keys.index(old)
    value = m[old]
    comment = m.ca.items.pop(old, None)
    del m[old]
    m.insert(pos, new, value)
    if comment is not None:
        m.ca.items[new] = comment


def _sync_map(m: CommentedMap, values: Mapping[str, Any]) -> None:
    for k in [k for k in m if k not in values]:
        del m[k]
    for k, v in values.items():
        _set(m, k, v)


def _sync_document(
    doc: CommentedMap, fsa: FSA, registry: Registry | None, renames: Mapping[str, str]
) -> None:
    _set(doc, "format", FORMAT_VERSION)
    if fsa.name or "name" in doc:
        _set(doc, "name", fsa.name)
    _set(doc, "start", fsa.start)
    if fsa.step_limit != DEFAULT_STEP_LIMIT or "step_limit" in doc:
        _set(doc, "step_limit", fsa.step_limit)
    if fsa.terminals != DEFAULT_TERMINALS or "terminals" in doc:
        _set(doc, "terminals", list(fsa.terminals))
    states = doc.get("states")
    if not isinstance(states, CommentedMap):
        states = CommentedMap()
        doc["states"] = states
    for old, new in renames.items():
        if old in states and new not in states:
            _rename_key(states, old, new)
    for gone in [k for k in states if k not in fsa.states]:
        del states[gone]
    for sname, st in fsa.states.items():
        cur = states.get(sname)
        if not isinstance(cur, CommentedMap):
            states[sname] = _state_map(st, registry)
            continue
        _set(cur, "skill", st.skill)
        if st.params or "params" in cur:
            pm = cur.get("params")
            if not isinstance(pm, CommentedMap):
                pm = CommentedMap()
                cur.insert(list(cur.keys()).index("skill") + 1 if "skill" in cur else 0,
                           "params", pm)
            _sync_map(pm, st.params)
        tm = cur.get("transitions")
        if not isinstance(tm, CommentedMap):
            tm = CommentedMap()
            cur["transitions"] = tm
        _sync_map(tm, st.transitions)
        if st.time_limit is not None:
            _set(cur, "time_limit", st.time_limit)
        elif "time_limit" in cur:
            del cur["time_limit"]
    if fsa.meta or "meta" in doc:
        if not isinstance(doc.get("meta"), CommentedMap):
            doc["meta"] = CommentedMap()
        _sync_map(doc["meta"], fsa.meta)
