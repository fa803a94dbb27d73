#!/usr/bin/env python3
"""Rename ncd's C++ namespaces so that namespace = folder (issue 31).

Usage: rename_ns.py DIR [PHASE...]   PHASE: app comms toolpath (default: all three)

Phases are cumulative by old namespace:
  app      : ncd::app (service/, api/, app/, core/) and ncd::fleet (api/)
  comms    : ncd::comms (link/, sim/, gcode/dialect/, api/)
  toolpath : ncd::toolpath (geometry/, gcode/, gcode/ngc/, cam/)

What it does, for every *.cpp/*.hpp under DIR (tests/ and bench/ included):
 1. namespace declarations: renamed by the folder the file is in (tests/<x>/ follows <x>/),
    the closing `}  // namespace ...` comment with them;
 2. derives a map symbol -> (old namespace, new namespace) from the namespace-scope
    declarations (types, aliases, functions, variables, unscoped enumerators, sub-namespaces)
    of the libraries' headers, so symbols added on other branches are covered;
 3. qualified uses (`toolpath::Path`, `ncd::comms::X`, a namespace alias to an old namespace)
    are rewritten by that map, in code and in comments;
 4. unqualified uses that were found because the old namespace enclosed the use and are no
    longer found (the two are now in different namespaces) get the new qualifier;
 5. `using namespace OLD;` becomes one using-directive per new namespace the scope uses;
 6. clang-format on every changed file.
"""
import os
import re
import subprocess
import sys
import textwrap
from collections import defaultdict

ROOT = os.path.abspath(sys.argv[1])
PHASES = sys.argv[2:] or ["app", "comms", "toolpath"]
OLD_ROOTS = set()
if "app" in PHASES:
    OLD_ROOTS |= {"app", "fleet"}
if "comms" in PHASES:
    OLD_ROOTS |= {"comms"}
if "toolpath" in PHASES:
    OLD_ROOTS |= {"toolpath"}

# (library, old root) -> new namespace (the old root prefix ncd::<root> is replaced by it)
TABLE = {
    ("geometry", "toolpath"): "ncd::geometry",
    ("gcode", "toolpath"): "ncd::gcode",
    ("gcode/ngc", "toolpath"): "ncd::gcode",
    ("gcode/dialect", "comms"): "ncd::gcode::dialect",
    ("cam", "toolpath"): "ncd::cam",
    ("link", "comms"): "ncd::link",
    ("sim", "comms"): "ncd::sim",
    ("service", "app"): "ncd::service",
    ("api", "app"): "ncd::api",
    ("api", "comms"): "ncd::api",
    ("api", "fleet"): "ncd::api",
    ("app", "app"): "ncd::app",
    ("core", "app"): "ncd",
}
BENCH = {"chamfer_bench.cpp": "cam", "ngc_interpreter_bench.cpp": "gcode",
         "block_encoder_bench.cpp": "link"}
LIBS = ["core", "geometry", "gcode", "gcode/ngc", "gcode/dialect", "cam", "feed", "surface",
        "motion", "link", "sim", "service", "api", "app"]

KEYWORDS = set("""alignas alignof and asm auto bool break case catch char char8_t char16_t char32_t
class co_await co_return co_yield concept const consteval constexpr constinit const_cast continue
decltype default delete do double dynamic_cast else enum explicit export extern false final float
for friend goto if inline int long mutable namespace new noexcept not nullptr operator or override
private protected public register reinterpret_cast requires return short signed sizeof static
static_assert static_cast struct switch template this thread_local throw true try typedef typeid
typename union unsigned using virtual void volatile wchar_t while""".split())
# keywords after which an identifier followed by '(' is a call, not a declaration
EXPR_KW = {"return", "else", "case", "throw", "new", "delete", "co_return", "co_await", "and",
           "or", "not", "do", "sizeof", "co_yield"}

TOKEN_RE = re.compile(r"""
 (?P<comment>//[^\n]*|/\*.*?\*/)
|(?P<pp>^[ \t]*\#(?:\\\n|[^\n])*)
|(?P<raw>(?:u8|u|U|L)?R"(?P<delim>[^(\s]{0,16})\(.*?\)(?P=delim)")
|(?P<string>(?:u8|u|U|L)?"(?:\\.|[^"\\\n])*")
|(?P<char>(?:u8|u|U|L)?'(?:\\.|[^'\\\n])+')
|(?P<number>\.?[0-9](?:[eEpP][+-]|[0-9A-Za-z_.']|)*)
|(?P<ident>[A-Za-z_][A-Za-z_0-9]*)
|(?P<punct>::|->|&&|\|\||<<|>>|[{}()\[\];,<>=&*~.:+\-/%!?|^])
|(?P<ws>\s+)
|(?P<other>.)
""", re.S | re.M | re.X)


class Tok:
    __slots__ = ("kind", "s", "e", "t")

    def __init__(self, kind, s, e, t):
        self.kind, self.s, self.e, self.t = kind, s, e, t


def tokenize(text):
    out = []
    for m in TOKEN_RE.finditer(text):
        k = m.lastgroup
        if k == "delim":
            k = "raw"
        if k == "ws":
            continue
        if k in ("raw", "string", "char"):
            k = "str"
        out.append(Tok(k, m.start(), m.end(), m.group()))
    return out


def lib_of(rel):
    parts = rel.split("/")
    if parts[0] == "tests" and len(parts) > 2:
        d = parts[1]
        return d if d in LIBS else None
    if parts[0] == "bench":
        return BENCH.get(parts[-1])
    if parts[0] in ("gcode",) and len(parts) > 2 and parts[1] in ("ngc", "dialect"):
        return "gcode/" + parts[1]
    return parts[0] if parts[0] in LIBS else None


def new_full(rel, old_full):
    """New name of namespace old_full declared in file rel, or None if it does not move."""
    m = re.match(r"ncd::(toolpath|comms|app|fleet)((?:::\w+)*)$", old_full)
    if not m or m.group(1) not in OLD_ROOTS:
        return None
    root, rest = m.group(1), m.group(2)
    lib = lib_of(rel)
    if rel.startswith("tests/gcode/") and root == "comms":
        lib = "gcode/dialect"
    if rel.startswith("tests/api/") and root == "comms":
        lib = "api"
    key = (lib, root)
    if key not in TABLE:
        raise SystemExit(f"rename_ns: {rel}: no rule for namespace {old_full} in library {lib}")
    return TABLE[key] + rest


def within(inner, outer):
    return inner == outer or inner.startswith(outer + "::")


def rel_name(ns):
    """How to write namespace ns (absolute) as a qualifier from inside ncd."""
    return "ncd" if ns == "ncd" else ns[len("ncd::"):]


# ---------------------------------------------------------------- scan of one file
class Frame:
    __slots__ = ("kind", "old", "new", "open_tok", "rename_tok", "written")

    def __init__(self, kind, old=None, new=None):
        self.kind, self.old, self.new = kind, old, new
        self.rename_tok = None
        self.written = None


def code_tokens(toks):
    return [t for t in toks if t.kind not in ("comment", "pp")]


def walk(rel, toks, on_ns_symbol=None, on_decl=None):
    """Walk the code tokens keeping a scope stack; yields (index, token, frames) for tokens.
    Calls on_ns_symbol(kind, name, old_ns, new_ns) for namespace-scope declarations."""
    code = code_tokens(toks)
    frames = [Frame("ns", "", "")]
    stmt = []  # tokens of the current namespace-scope statement
    i = 0
    n = len(code)
    paren = 0
    results = []
    while i < n:
        t = code[i]
        top = frames[-1]
        if t.t == "namespace" and t.kind == "ident" and paren == 0:
            # namespace A::B {   |  namespace {  |  namespace A = B;
            j = i + 1
            names = []
            while j < n and (code[j].kind == "ident" or code[j].t == "::"):
                if code[j].kind == "ident":
                    names.append(code[j].t)
                j += 1
            if j < n and code[j].t == "{":
                cur = next(f for f in reversed(frames) if f.kind == "ns")
                if names:
                    old = "::".join(([cur.old] if cur.old else []) + names)
                    fr = Frame("ns", old, None)
                    fr.written = (code[i + 1].s, code[j - 1].e, "::".join(names))
                    if on_ns_symbol and cur.old:
                        on_ns_symbol("namespace", names[0], cur.old, cur.new)
                else:
                    fr = Frame("anon", cur.old, None)
                frames.append(fr)
                results.append(("nsopen", i, fr, code))
                stmt = []
                i = j + 1
                continue
            results.append(("nsalias", i, None, code))
            # skip to ;
            while j < n and code[j].t != ";":
                j += 1
            i = j + 1
            stmt = []
            continue
        if t.t in ("(", "["):
            paren += 1
        elif t.t in (")", "]"):
            paren -= 1
        if t.t in ("{", "}") and paren > 0:  # a braced initializer or lambda inside ( )
            stmt.append(t)
            results.append(("tok", i, frames[-1], code))
            i += 1
            continue
        if t.t == "{":
            kind = "block"
            if top.kind in ("ns", "anon") and paren == 0:
                kind = classify_open(stmt, frames, on_ns_symbol)
            elif top.kind == "class" and paren == 0:
                kind = "class"  # nested type or member function body: both fine as blocks
                kind = "block" if any(x.t == "(" for x in stmt) else "class"
            elif top.kind == "enum":
                kind = "block"
            frames.append(Frame(kind, top.old, top.new))
            frames[-1].open_tok = len(stmt)
            stmt = []
            i += 1
            continue
        if t.t == "}":
            if len(frames) > 1:
                fr = frames.pop()
                if fr.kind == "enum" and on_ns_symbol and fr.new == "unscoped":
                    pass
                results.append(("close", i, fr, code))
            stmt = []
            i += 1
            continue
        if t.t == ";" and paren == 0:
            if top.kind in ("ns", "anon"):
                classify_stmt(stmt, frames, on_ns_symbol)
            stmt = []
            i += 1
            continue
        if top.kind == "enum_unscoped" and on_ns_symbol:
            prev = code[i - 1].t if i else ""
            if t.kind == "ident" and prev in ("{", ","):
                cur = frames[-2] if len(frames) > 1 else frames[-1]
                nsf = next(f for f in reversed(frames[:-1]) if f.kind in ("ns", "anon"))
                if nsf.kind == "ns":
                    on_ns_symbol("var", t.t, nsf.old, nsf.new)
        stmt.append(t)
        results.append(("tok", i, frames[-1], code))
        i += 1
    return results, code


def ns_frame(frames):
    return next(f for f in reversed(frames) if f.kind in ("ns", "anon"))


def classify_open(stmt, frames, cb):
    texts = [x.t for x in stmt]
    for kw in ("struct", "class", "union", "enum"):
        if kw in texts:
            k = texts.index(kw)
            # skip 'enum class', attributes
            j = k + 1
            scoped = False
            while j < len(texts) and texts[j] in ("class", "struct", "alignas", "[", "]"):
                scoped = scoped or texts[j] in ("class", "struct")
                j += 1
            if "(" in texts[:k]:
                break
            name = texts[j] if j < len(texts) and stmt[j].kind == "ident" else None
            f = ns_frame(frames)
            if name and cb and f.kind == "ns" and (j + 1 >= len(texts) or texts[j + 1] != "::"):
                cb("type", name, f.old, f.new)
            if kw == "enum":
                return "enum" if scoped else "enum_unscoped"
            return "class"
    if "(" in texts:
        if cb:
            report_function(stmt, frames, cb)
        return "block"
    if "=" in texts:  # variable with brace initializer after '=' e.g. x = {..}
        if cb:
            classify_stmt(stmt, frames, cb)
        return "block"
    if stmt and cb:  # T name{...}
        f = ns_frame(frames)
        if stmt[-1].kind == "ident" and f.kind == "ns" and len(stmt) >= 2:
            cb("var", stmt[-1].t, f.old, f.new)
    return "block"


def report_function(stmt, frames, cb):
    texts = [x.t for x in stmt]
    k = texts.index("(")
    if k == 0 or stmt[k - 1].kind != "ident":
        return
    if "operator" in texts[:k]:
        return
    if k >= 2 and texts[k - 2] == "::":
        return  # out-of-class definition
    name = texts[k - 1]
    if name in KEYWORDS:
        return
    f = ns_frame(frames)
    if f.kind == "ns":
        cb("func", name, f.old, f.new)


def classify_stmt(stmt, frames, cb):
    if not stmt or not cb:
        return
    texts = [x.t for x in stmt]
    f = ns_frame(frames)
    if f.kind != "ns":
        return
    if texts[0] == "using":
        if len(texts) > 2 and texts[2] == "=":
            cb("type", texts[1], f.old, f.new)
        return
    if texts[0] == "template" and "using" in texts:
        k = texts.index("using")
        if k + 2 < len(texts) and texts[k + 2] == "=":
            cb("type", texts[k + 1], f.old, f.new)
        return
    if texts[0] == "typedef":
        cb("type", texts[-1], f.old, f.new)
        return
    if texts[0] in ("static_assert", "friend"):
        return
    for kw in ("struct", "class", "union", "enum"):
        if kw in texts and "(" not in texts[: texts.index(kw)] and "=" not in texts:
            j = texts.index(kw) + 1
            while j < len(texts) and texts[j] in ("class", "struct"):
                j += 1
            if j < len(texts) and stmt[j].kind == "ident":
                cb("type", texts[j], f.old, f.new)
            return
    eq = texts.index("=") if "=" in texts else len(texts)
    if "(" in texts[:eq]:
        report_function(stmt, frames, cb)
        return
    # variable
    k = eq
    while k > 0:
        k -= 1
        if stmt[k].kind == "ident" and texts[k] not in KEYWORDS:
            if k >= 1 and texts[k - 1] == "::":
                return
            cb("var", texts[k], f.old, f.new)
            return
        if texts[k] in ("]", "["):
            continue


# ---------------------------------------------------------------- pass 1: the map
def all_files():
    out = []
    for d, dirs, files in os.walk(ROOT):
        dirs[:] = [x for x in dirs if x not in ("build", ".git", "node_modules", "third_party")]
        for f in files:
            if f.endswith((".cpp", ".hpp", ".h")):
                p = os.path.join(d, f)
                out.append(os.path.relpath(p, ROOT))
    return sorted(out)


FILES = all_files()
TEXT = {}
for rel in FILES:
    with open(os.path.join(ROOT, rel), encoding="utf-8") as fh:
        TEXT[rel] = fh.read()

# ---------------------------------------------------------------- hand fix-ups
# service/setpoint_file.hpp's ncd::app::SetpointSink (the setpoint file) derives from
# service/service.hpp's ncd::service::SetpointSink (the interface): in one namespace they
# collide, so the file's class becomes SetpointFileSink.
PRE_CHANGED = []


def fixup_setpoint_sink(rel, text):
    if "app" not in OLD_ROOTS:
        return text
    out = re.sub(r"\bapp::SetpointSink\b", "app::SetpointFileSink", text)
    if not re.search(r"namespace ncd::app\b", out):
        return out
    edits = []
    toks = tokenize(out)
    for k, t in enumerate(toks):
        if t.kind == "ident" and t.t == "SetpointSink" and not (
                k > 1 and toks[k - 1].t == "::" and toks[k - 2].t == "service"):
            edits.append(t)
    for t in reversed(edits):
        out = out[: t.s] + "SetpointFileSink" + out[t.e:]
    return out


# api/ is unity-built, and its files came from three namespaces: file-local names that were
# apart (ncd::fleet, ncd::comms, ncd::app) now meet in ncd::api. The newcomers' copies get a
# name of their own (the same rename, token by token, outside comments and strings).
API_RENAMES = {
    "api/mqtt_config.cpp": ({"app"}, {"kKeys": "kMqttKeys", "need_string": "need_mqtt_string"}),
    "api/control_server.cpp": ({"app", "comms"}, {
        "kMaxQueuedBytes": "kMaxQueuedControlBytes", "accept_next": "accept_next_client",
        "State": "ControlState"}),
}


def fixup_api_locals(rel, text):
    if rel not in API_RENAMES:
        return text
    need, names = API_RENAMES[rel]
    if not need <= OLD_ROOTS:
        return text
    toks = tokenize(text)
    # `State` is renamed only after `using State = ControlServer::State;` (the struct keeps
    # its name, and so does its constructor)
    alias_at = text.find("using State = ControlServer::State;")
    edits = []
    for k, t in enumerate(toks):
        if t.kind != "ident" or t.t not in names:
            continue
        if k and toks[k - 1].t in ("::", ".", "->"):
            continue
        if t.t == "State" and (alias_at < 0 or t.s < alias_at):
            continue
        edits.append(t)
    for t in reversed(edits):
        text = text[: t.s] + names[t.t] + text[t.e:]
    return text


for rel in FILES:
    fixed = fixup_api_locals(rel, fixup_setpoint_sink(rel, TEXT[rel]))
    if fixed != TEXT[rel]:
        TEXT[rel] = fixed
        with open(os.path.join(ROOT, rel), "w", encoding="utf-8") as fh:
            fh.write(fixed)
        PRE_CHANGED.append(rel)

SYM = defaultdict(lambda: defaultdict(set))  # name -> old_ns -> {new_ns}
KIND = defaultdict(set)                       # name -> kinds
DECLARED_NEW = defaultdict(set)               # new_ns -> names declared there (any file)
LIB_FUNCS = defaultdict(set)                  # lib -> names declared as functions/members/locals


def collect(rel, header):
    toks = tokenize(TEXT[rel])

    def cb(kind, name, old, _new):
        newns = resolve_new(rel, old)
        if newns is None:
            return
        DECLARED_NEW[newns].add(name)
        if header and not rel.startswith(("tests/", "bench/")):
            SYM[name][old].add(newns)
            KIND[name].add(kind)

    walk(rel, toks, cb)
    # declaration-like "T name(" anywhere in the file: members, locals, functions
    code = code_tokens(toks)
    lib = lib_of(rel)
    for i in range(1, len(code) - 1):
        if code[i].kind == "ident" and code[i + 1].t == "(" and decl_context(code, i):
            LIB_FUNCS[lib].add(code[i].t)


def resolve_new(rel, old):
    """New absolute name of the namespace 'old' when declared in file rel."""
    if not old:
        return None
    nf = new_full(rel, old)
    return nf if nf is not None else old


def decl_context(code, i):
    """True if code[i] (an identifier) stands where a declared name stands (after a type)."""
    if i == 0:
        return False
    p = code[i - 1]
    if p.kind == "ident":
        return p.t not in EXPR_KW and (p.t not in KEYWORDS or p.t in (
            "auto", "bool", "char", "double", "float", "int", "long", "short", "unsigned",
            "signed", "void", "const", "constexpr", "static", "inline", "virtual", "explicit",
            "override", "final", "struct", "class", "enum", "union", "typename", "friend",
            "consteval", "constinit", "size_t", "mutable", "extern", "thread_local", "volatile"))
    if p.t == ">":
        return True
    if p.t in ("&", "*") and i >= 2:
        pp = code[i - 2]
        if pp.t in (">", "const", "auto", "void", "char", "int", "double", "float", "bool"):
            return True
        if pp.kind != "ident" or pp.t in KEYWORDS:
            return False
        return pp.t[0].isupper() or (i >= 3 and code[i - 3].t == "::")
    if p.t == "~":
        return True
    return False


for rel in FILES:
    collect(rel, rel.endswith((".hpp", ".h")))


def lookup(name, old):
    """New namespace of symbol name declared in old namespace old (absolute); None if unknown."""
    d = SYM.get(name)
    if not d or old not in d:
        return None
    return d[old]


# ---------------------------------------------------------------- pass 2: rewrite
QUAL_ROOT = {"toolpath", "comms", "app", "fleet"} & OLD_ROOTS
problems = []
changed = []


def includes_of(text):
    return set(re.findall(r'#include\s+"([a-z_]+(?:/ngc|/dialect)?)/', text))


LIB_OF_NS = {v: k for (k, _), v in TABLE.items()}


def choose(rel, name, cands, text):
    cands = sorted(cands)
    if len(cands) == 1:
        return cands[0]
    inc = includes_of(text)
    own = new_of_file(rel)
    good = [c for c in cands if c in own]
    if not good:
        good = [c for c in cands if any(LIB_OF_NS.get(c2) == lib for c2 in [c] for lib in inc)]
    if len(good) == 1:
        return good[0]
    problems.append(f"{rel}: {name} is declared in {cands}; took {cands[0]}")
    return cands[0]


def new_of_file(rel):
    lib = lib_of(rel)
    return {v for (k, _), v in TABLE.items() if k == lib}


LOCAL_TYPE_RE = re.compile(r"\b(?:struct|class|union|enum(?:\s+class|\s+struct)?)\s+([A-Za-z_]\w*)"
                           r"\s*(?:final\s*)?[:{;]|\busing\s+([A-Za-z_]\w*)\s*=")


def local_types(rel):
    """Type names declared anywhere in rel or in the header of the same name (nested types
    hide a namespace's type of the same name inside their class)."""
    names = set()
    rels = [rel]
    if rel.endswith(".cpp"):
        rels.append(rel[:-4] + ".hpp")
    for r in rels:
        if r in TEXT:
            for m in LOCAL_TYPE_RE.finditer(TEXT[r]):
                names.add(m.group(1) or m.group(2))
    return names


def rewrite(rel):
    text = TEXT[rel]
    toks = tokenize(text)
    results, code = walk(rel, toks)
    own_types = local_types(rel)
    edits = []
    aliases = {}  # alias -> old absolute ns
    alias_uses = defaultdict(list)
    lib = lib_of(rel)

    # the frames carry old names; compute new names for namespace frames
    def fr_new(fr):
        if fr.new is None:
            fr.new = resolve_new(rel, fr.old) if fr.old else ""
        return fr.new

    skip_until = -1
    for kind, i, fr, _ in results:
        if i < skip_until:
            continue
        t = code[i]
        if kind == "nsopen":
            if fr.kind == "ns":
                parent_new = ""
                newns = fr_new(fr)
                if newns != fr.old:
                    s, e, written = fr.written
                    if written.startswith("ncd::") or written == "ncd":
                        edits.append((s, e, newns))
                    else:  # nested declaration: write relative to the enclosing frame
                        encl = fr.old[: -len(written) - 2]
                        encl_new = resolve_new(rel, encl) if encl else ""
                        if not within(newns, encl_new):
                            problems.append(f"{rel}: nested namespace {written} cannot move")
                        else:
                            edits.append((s, e, newns[len(encl_new) + 2:]))
            else:
                fr.new = None
            continue
        if kind == "close":
            if fr.kind == "ns" and fr.written:
                newns = fr_new(fr)
                if newns != fr.old:
                    # the comment after the brace
                    k = next((x for x in toks if x.s > t.s), None)
                    if k is not None and k.kind == "comment" and "\n" not in text[t.e:k.s]:
                        m = re.match(r"//\s*namespace\s+(\S+)", k.t)
                        if m:
                            written = fr.written[2]
                            newwritten = newns if written.startswith("ncd") else \
                                newns.split("::")[-1]
                            edits.append((k.s, k.e, f"// namespace {newwritten}"))
            continue
        if kind == "nsalias":
            # namespace A = ncd::toolpath;
            j = i + 1
            alias = code[j].t
            target = "".join(x.t for x in code[j + 2:] if True)
            k = j + 2
            parts = []
            while k < len(code) and code[k].t != ";":
                parts.append(code[k].t)
                k += 1
            target = "".join(parts)
            m = re.match(r"(?:::)?ncd::(toolpath|comms|app|fleet)$", target)
            if m and m.group(1) in QUAL_ROOT:
                aliases[alias] = ("ncd::" + m.group(1), code[j + 2].s, code[k - 1].e)
            continue
        # kind == tok
        nsf = None
        # innermost namespace frame of this token
        # (walk gave us the innermost frame; climb via old name)
        if t.kind != "ident":
            continue
        prev = code[i - 1] if i else None
        nxt = code[i + 1] if i + 1 < len(code) else None
        if prev is not None and prev.t in (".", "->"):
            continue
        ctx_old = fr.old or ""
        ctx_new = resolve_new(rel, ctx_old) if ctx_old else ""
        if prev is not None and prev.t == "::":
            continue
        # ---- qualified use: [ncd ::] ROOT :: X ...  or ALIAS :: X
        root_old = None
        start = t.s
        j = i
        full = False
        if t.t == "ncd" and nxt is not None and nxt.t == "::" and i + 2 < len(code) and \
                code[i + 2].t in QUAL_ROOT:
            full = True
            j = i + 2
        alias_use = None
        if code[j].t in QUAL_ROOT and j + 1 < len(code) and code[j + 1].t == "::" and \
                (full or code[j].t not in aliases):
            root_old = "ncd::" + code[j].t
        elif code[j].t in aliases and j + 1 < len(code) and code[j + 1].t == "::":
            root_old = aliases[code[j].t][0]
            alias_use = code[j].t
            full = True
        if root_old is not None:
            # using namespace ncd::toolpath;  handled below
            if i >= 2 and code[i - 1].t == "namespace" and code[i - 2].t == "using":
                pass
            elif j + 2 < len(code) and code[j + 2].kind == "ident":
                x = code[j + 2].t
                cands = lookup(x, root_old)
                if cands is None:
                    problems.append(f"{rel}: {root_old}::{x}: symbol not found in the map")
                else:
                    m = choose(rel, x, cands, text)
                    if alias_use is not None:
                        alias_uses[alias_use].append((start, code[j + 1].e, m))
                    elif full:
                        rep = ("ncd" if m == "ncd" else "ncd::" + rel_name(m)) + "::"
                    elif ctx_new and within(ctx_new, m) and m != "ncd" and \
                            not (KIND[x] & {"func", "var"}):
                        rep = ""  # a type of the namespace the use is in: no qualifier
                        # (a function keeps it: a member of that name may hide it)
                    else:
                        rep = rel_name(m) + "::"
                    if alias_use is None:
                        edits.append((start, code[j + 1].e, rep))
                skip_until = j + 2
                continue
        # ---- using namespace OLD;
        if t.t == "using" and nxt is not None and nxt.t == "namespace":
            k = i + 2
            parts = []
            while k < len(code) and code[k].t != ";":
                parts.append(code[k].t)
                k += 1
            written = "".join(parts).lstrip(":")
            absn = resolve_written(written, ctx_old)
            if absn and re.match(r"ncd::(toolpath|comms|app|fleet)$", absn) and \
                    absn.split("::")[1] in QUAL_ROOT:
                used = used_namespaces(code, k, absn, fr)
                if not used:
                    problems.append(f"{rel}: using namespace {written}: no symbol used; kept "
                                    "the first namespace of the library")
                    used = sorted({v for (kk, r), v in TABLE.items()
                                   if "ncd::" + r == absn})[:1]
                full_w = written.startswith("ncd")
                reps = []
                for m in sorted(used):
                    w = m if full_w or not ctx_new else rel_name(m)
                    reps.append(f"using namespace {w};")
                edits.append((t.s, code[k].e, " ".join(reps)))
                skip_until = k + 1
            continue
        # ---- unqualified use of a symbol that moved away
        if not ctx_old or t.t not in SYM:
            continue
        d = SYM[t.t]
        vis_old = [o for o in d if within(ctx_old, o)]
        if not vis_old:
            continue
        o = max(vis_old, key=len)
        if len(d[o]) > 1 and KIND[t.t] <= {"func"} and not (d[o] & new_of_file(rel)):
            continue  # overloads now in several namespaces: argument-dependent lookup
        m = choose(rel, t.t, d[o], text)
        if within(ctx_new, m):
            continue
        if t.t in DECLARED_NEW.get(ctx_new, ()) or any(
                t.t in DECLARED_NEW.get(a, ()) for a in ancestors(ctx_new)):
            continue  # declared in the new namespace too: overloads, ADL
        kinds = KIND[t.t]
        if prev is not None and prev.t in ("struct", "class", "enum", "union", "~", "namespace",
                                           "operator", "goto"):
            continue
        if "namespace" in kinds:
            if nxt is None or nxt.t != "::":
                continue
        elif kinds <= {"func"}:
            if nxt is None or nxt.t not in ("(", "<"):
                continue
            if nxt.t == "<":
                pass
            if decl_context(code, i):
                continue
            if t.t in LIB_FUNCS.get(lib, ()):
                problems.append(f"{rel}:{line_of(text, t.s)}: {t.t}( left unqualified "
                                f"(a function of that name is declared in {lib}/)")
                continue
        elif "var" in kinds and not (kinds & {"type"}):
            if nxt is not None and nxt.t == "(":
                continue
            if prev is not None and prev.kind == "ident" and prev.t not in EXPR_KW:
                continue  # a declaration of that name
        else:  # type
            if nxt is not None and nxt.t in ("(",) and decl_context(code, i):
                continue
            if t.t in own_types:
                problems.append(f"{rel}:{line_of(text, t.s)}: {t.t} left unqualified (a type "
                                "of that name is declared in this file)")
                continue
        edits.append((t.s, t.s, rel_name(m) + "::"))
    # an alias whose uses all land in one new namespace names that one (its uses unchanged);
    # otherwise each use is written in full
    for alias, (old, s, e) in aliases.items():
        targets = {m for _, _, m in alias_uses[alias]}
        if len(targets) == 1:
            edits.append((s, e, targets.pop()))
        else:
            for us, ue, m in alias_uses[alias]:
                edits.append((us, ue, "ncd::" + rel_name(m) + "::"))
    # comments: qualified names in comments follow the map
    for tk in toks:
        if tk.kind != "comment":
            continue
        new_c = comment_rewrite(tk.t, rel)
        if new_c != tk.t and not any(s <= tk.s < e or s == tk.s for s, e, _ in edits):
            edits.append((tk.s, tk.e, new_c))
    if not edits:
        return False
    edits.sort(key=lambda x: (x[0], x[1]))
    out = []
    pos = 0
    for s, e, rep in edits:
        if s < pos:
            continue
        out.append(text[pos:s])
        out.append(rep)
        pos = e
    out.append(text[pos:])
    new_text = "".join(out)
    if new_text != text:
        with open(os.path.join(ROOT, rel), "w", encoding="utf-8") as fh:
            fh.write(new_text)
        return True
    return False


def ancestors(ns):
    parts = ns.split("::") if ns else []
    return ["::".join(parts[:k]) for k in range(1, len(parts))]


def line_of(text, pos):
    return text.count("\n", 0, pos) + 1


def resolve_written(written, ctx_old):
    if written.startswith("ncd"):
        return written
    if re.match(r"(toolpath|comms|app|fleet)$", written):
        return "ncd::" + written
    return None


def used_namespaces(code, k, absn, fr):
    """New namespaces of the symbols of absn used after index k in the enclosing block."""
    depth = 0
    used = set()
    for x in code[k + 1:]:
        if x.t == "{":
            depth += 1
        elif x.t == "}":
            depth -= 1
            if depth < 0:
                break
        elif x.kind == "ident" and x.t in SYM and absn in SYM[x.t]:
            used |= SYM[x.t][absn]
    return used


CMT_RE = re.compile(r"\b(ncd::)?(toolpath|comms|app|fleet)::(\w+)")


def comment_rewrite(c, rel):
    def rep(m):
        root = m.group(2)
        if root not in QUAL_ROOT:
            return m.group(0)
        old = "ncd::" + root
        cands = SYM.get(m.group(3), {}).get(old)
        if not cands:
            return m.group(0)
        newns = sorted(cands)[0]
        if m.group(1):
            return ("ncd::" if newns == "ncd" else "ncd::" + rel_name(newns) + "::") + m.group(3)
        return ("ncd::" if newns == "ncd" else rel_name(newns) + "::") + m.group(3)
    return CMT_RE.sub(rep, c)


for rel in FILES:
    if rewrite(rel) or rel in PRE_CHANGED:
        changed.append(rel)

# Hand fix-ups after the rewrite: (phases needed, file, text, replacement). Each is a call of
# an overload set that is now split over two namespaces, where argument-dependent lookup no
# longer finds the one that was meant.
SED = [
    ({"app"}, "app/bench_service_io.cpp", "return to_json(core_.status());",
     "return api::to_json(core_.status());"),
    # the dashboard's files are embedded into api/ by a generated source
    ({"app"}, "web/embed.cmake", "namespace ncd::app {", "namespace ncd::api {"),
    ({"app"}, "web/embed.cmake", "}  // namespace ncd::app", "}  // namespace ncd::api"),
]
for need, rel, a, b in SED:
    if not need <= set(PHASES) or not os.path.exists(os.path.join(ROOT, rel)):
        continue
    path = os.path.join(ROOT, rel)
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    if a not in text:
        problems.append(f"{rel}: hand fix-up not applied, text not found: {a}")
        continue
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text.replace(a, b))
    if rel not in changed:
        changed.append(rel)

# ---------------------------------------------------------------- docs
DONE = {"app": "service/ is `ncd::service`, api/ `ncd::api` (its MQTT files were `ncd::fleet`), "
               "app/ `ncd::app`, and core/'s `output_file` and `toml_text` are in `ncd` with the "
               "rest of core/",
        "comms": "link/ is `ncd::link`, sim/ `ncd::sim` and gcode/dialect/ `ncd::gcode::dialect` "
                 "(api/control_server is `ncd::api` with the rest of api/)",
        "toolpath": "geometry/ is `ncd::geometry`, gcode/ `ncd::gcode` (gcode/ngc/ "
                    "`ncd::gcode::ngc`) and cam/ `ncd::cam`"}
LEFT = {"toolpath": "`ncd::toolpath` in geometry/, gcode/ and cam/ (`ncd::toolpath::ngc` in "
                    "gcode/ngc/)",
        "comms": "`ncd::comms` in link/, sim/, gcode/dialect/ and api/control_server",
        "app": "`ncd::fleet` in api/'s MQTT files; `ncd::app` in api/, service/ and core/ "
               "(`output_file`, `toml_text`) as well as app/"}
FINAL = """Namespaces follow the folders: a library's code is in `ncd::<folder>` (`ncd::geometry`,
`ncd::gcode` with `ncd::gcode::ngc` and `ncd::gcode::dialect` for its two sub-folders,
`ncd::cam`, `ncd::feed`, `ncd::surface`, `ncd::motion`, `ncd::link`, `ncd::sim`,
`ncd::service`, `ncd::api`, `ncd::app`), and core/ is in `ncd` itself (with `ncd::text` and
`ncd::ranges`). What a library's files share privately is in a `*_detail` namespace under the
library's (`ncd::link::dnc_detail`, `ncd::cam::chamfer_detail`, `ncd::feed::sampler_detail`).
So a qualifier says where a thing lives: `geometry::Path` is in geometry/, `link::DncSender` in
link/, `gcode::dialect::check_line` in gcode/dialect/.
"""


def wart_text():
    order = ["app", "comms", "toolpath"]
    done = [p for p in order if p in PHASES]
    if len(done) == 3:
        return FINAL
    left = [p for p in order if p not in PHASES]
    return textwrap.fill("Known wart: the folders were re-laid out and the C++ namespaces are being renamed "
            "after them (namespace = folder). Done: " + "; ".join(DONE[p] for p in done) +
            ". Still carrying the names of the former folders: " +
            "; ".join(LEFT[p] for p in left) + ". feed/, surface/ and motion/ have namespaces "
            "of their own name.", width=99, break_on_hyphens=False) + "\n"


def rewrite_doc(rel):
    path = os.path.join(ROOT, rel)
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    new = re.sub(r"`[^`\n]*`", lambda m: comment_rewrite(m.group(0), rel), text)
    if rel == "docs/architecture.md":
        new = re.sub(r"(?:Known wart: the folders were re-laid out|Namespaces follow the "
                     r"folders:).*?\n\n", lambda m: wart_text() + "\n", new, count=1, flags=re.S)
    if new != text:
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(new)
        changed.append(rel)


for d in ("docs",):
    for f in sorted(os.listdir(os.path.join(ROOT, d))):
        if f.endswith(".md"):
            rewrite_doc(d + "/" + f)
rewrite_doc("README.md")

for p in problems:
    print("rename_ns: note:", p, file=sys.stderr)
print(f"rename_ns: {len(changed)} files rewritten", file=sys.stderr)
code_changed = [c for c in changed if c.endswith((".cpp", ".hpp", ".h")) and c in TEXT]
if code_changed:
    subprocess.run(["clang-format", "-i"] + [os.path.join(ROOT, c) for c in code_changed],
                   check=True)
