"""Mutations of iem namelist inputs for tests/fuzz/fuzz.py: what docs/input.md allows, a
small parser of the namelist text (groups, assignments and their spans), the cheap bases made
from the shipped scenes, and the mutators; case k of a seed is always the same mutation."""
from __future__ import annotations

import math
import random
import re
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
INPUT_NAME = "case.nml"

# ---- what the documentation allows (docs/input.md) -----------------------------------------
# type: r real, i integer, l logical, e enumeration, p path, t text; a2/a4: 2 or 4 reals
GT0, GE0 = (lambda v: v > 0), (lambda v: v >= 0)
WHERE = ["left", "right", "bottom", "top", "box", "point", "all", "segment", "circle", "boundary",
         "shape", "face"]
# the geometric node-set keys of &bc and &load (each only with its where)
SET_KEYS = {"segment": ("a4", None), "center": ("a2", None), "radius": ("r", GT0),
            "shape": ("t", None), "normal": ("a2", None)}
SCHEMA: dict[str, dict[str, tuple]] = {
    "run": {
        "analysis": ("e", ["dynamic", "static"]), "integrator": ("e", ["rk4", "verlet"]),
        "t_end": ("r", GT0), "dt": ("r", GE0), "dt_safety": ("r", lambda v: 0 < v <= 1),
        "output_interval": ("r", GE0), "history_interval": ("r", GE0),
        "progress_interval": ("r", GT0), "output_file": ("p", None), "overwrite": ("l", None),
        "energy_warn": ("r", GE0), "energy_stop": ("r", GE0), "check_interval": ("i", 1),
        "checkpoint_interval": ("r", GE0), "checkpoint_file": ("p", None),
        "restart": ("p", None), "allow_unstable_dt": ("l", None)},
    "static": {
        "load_steps": ("i", 1), "tolerance": ("r", lambda v: 0 < v < 1),
        "max_iterations": ("i", 1), "method": ("e", ["kinetic", "viscous"]),
        "mass": ("e", ["lumped", "gershgorin"])},
    "geometry": {
        "length": ("r", GT0), "height": ("r", GT0), "thickness": ("r", GT0),
        "nx": ("i", 1), "ny": ("i", 1), "cell_size": ("r", GT0),
        "plane": ("e", ["stress", "strain"]), "cell": ("e", ["paper", "bending"]),
        "background": ("t", None), "image": ("p", None), "image_levels": ("i", 0),
        "image_materials": ("t", None), "pieces": ("e", ["warn", "allow", "one"])},
    "material": {
        "name": ("t", None), "E": ("r", GT0), "nu": ("r", lambda v: -1 < v < 0.5), "density": ("r", GT0),
        "nonlinear": ("l", None), "tensile_strength": ("r", GT0),
        "compressive_strength": ("r", GT0), "shear_strength": ("r", GT0),
        "history_depth": ("i", 2)},
    "damping": {
        "kind": ("e", ["none", "mass", "stiffness", "rayleigh", "capped"]),
        "ratio": ("r", lambda v: 0 <= v < 1), "frequency": ("r", GT0), "alpha": ("r", GE0),
        "beta": ("r", GE0), "cap_frequency": ("r", GT0)},
    "bc": {
        "name": ("t", None),
        "where": ("e", WHERE),
        "box": ("a4", None), "point": ("a2", None), **SET_KEYS,
        "kind": ("e", ["fix", "velocity"]),
        "dofs": ("e", ["x", "y", "xy"]), "velocity": ("a2", None),
        "time_function": ("e", ["constant", "step", "ramp"]), "t_start": ("r", GE0),
        "t_ramp": ("r", GE0), "t_release": ("r", GT0)},
    "load": {
        "name": ("t", None), "kind": ("e", ["nodal", "edge", "gravity"]),
        "where": ("e", WHERE),
        "box": ("a4", None), "point": ("a2", None), **SET_KEYS, "force": ("a2", None),
        "traction": ("a2", None), "accel": ("a2", None),
        "time_function": ("e", ["constant", "step", "ramp"]), "t_start": ("r", GE0),
        "t_ramp": ("r", GE0)},
    "initial": {"velocity": ("a2", None), "angular_velocity": ("r", None),
                "center": ("a2", None)},
    "probe": {"name": ("t", None), "x": ("r", None), "y": ("r", None), "springs": ("l", None)},
    # no shipped scene has a &shape yet: these name its keys (unknown in other groups);
    # points holds 3 to 256 vertices, not four values
    "shape": {"name": ("t", None), "kind": ("e", ["rectangle", "circle", "polygon"]),
              "box": ("a4", None), "center": ("a2", None), "radius": ("r", GT0),
              "points": ("a4", None), "material": ("t", None)},
}
# &material may be repeated, each with its own name: the shipped scenes' one has none, so a
# doubled &material is two unnamed ones, which must be refused (see m_group)
ONCE = {"run", "geometry", "damping", "initial", "static"}

EXTREMES = ["1e400", "-1e400", "1e308", "1e-320", "0", "-0.0", "-1", "2147483648",
            "9223372036854775808", "-1e308", "-9223372036854775809", "2147483647",
            "1.7976931348623157e308", "4.9e-324", "1e-300", "1000000000"]
NONFINITE = ["NaN", "Inf", "-Inf", "+nan", "-Infinity", "nan", "+Inf"]
# ---- the namelist text ----------------------------------------------------------------------
@dataclass
class Assign:
    group: int
    key: str
    key_start: int
    start: int          # value span in the text (trimmed)
    end: int


@dataclass
class Group:
    name: str
    start: int          # offset of '&'
    end: int            # offset just after the closing '/' line (its newline included)
    slash: int          # offset of the closing '/' (-1: none)


def code_end(line: str) -> int:
    """Where the code of a line ends: at a '!' outside quotes, else at its end."""
    quote = ""
    for i, c in enumerate(line):
        if quote:
            if c == quote:
                quote = ""
        elif c in "'\"":
            quote = c
        elif c == "!":
            return i
    return len(line)


def outside_quotes(code: str, pos: int) -> bool:
    """Whether position pos of a line's code is outside any quoted string."""
    quote = ""
    for c in code[:pos]:
        if quote:
            if c == quote:
                quote = ""
        elif c in "'\"":
            quote = c
    return not quote


KEY_RE = re.compile(r"(?<![\w'\".])([A-Za-z_]\w*)\s*=")


def parse(text: str) -> tuple[list[Group], list[Assign]]:
    """Groups and assignments of a namelist text in the simple layout of the shipped inputs."""
    groups: list[Group] = []
    assigns: list[Assign] = []
    offset = 0
    current = -1
    for line in text.splitlines(keepends=True):
        code = line[:code_end(line)]
        body_from = 0
        m = re.match(r"\s*&(\w+)", code)
        if m and current < 0:
            groups.append(Group(m.group(1).lower(), offset + m.start(1) - 1, -1, -1))
            current = len(groups) - 1
            body_from = m.end()
        if current >= 0:
            stripped = code.rstrip()
            closes = stripped.endswith("/") and outside_quotes(code, len(stripped) - 1)
            limit = len(stripped) - 1 if closes else len(code)
            keys = [k for k in KEY_RE.finditer(code, body_from, limit)
                    if outside_quotes(code, k.start())]
            for n, k in enumerate(keys):
                vend = keys[n + 1].start() if n + 1 < len(keys) else limit
                value = code[k.end():vend]
                lead = len(value) - len(value.lstrip())
                value = value.strip().rstrip(",").rstrip()
                s = offset + k.end() + lead
                assigns.append(Assign(current, k.group(1).lower(), offset + k.start(), s,
                                      s + len(value)))
            if closes:
                groups[current].slash = offset + len(stripped) - 1
                groups[current].end = offset + len(line)
                current = -1
        offset += len(line)
    if current >= 0:
        groups[current].end = len(text)
    return groups, assigns


def value_of(text: str, key: str, group: str = "run") -> str | None:
    """The (last) value of a key in a group, quotes removed; None when not given."""
    groups, assigns = parse(text)
    found = None
    for a in assigns:
        if groups[a.group].name == group and a.key == key:
            found = text[a.start:a.end]
    if found is None:
        return None
    found = found.strip()
    if len(found) >= 2 and found[0] in "'\"" and found[-1] == found[0]:
        return found[1:-1]
    return found


def with_extension(path: str, ext: str) -> str:
    """docs/output.md: the extension of the file name replaced (or ext appended)."""
    slash = path.rfind("/")
    dot = path.rfind(".")
    if dot > slash + 1:
        return path[:dot] + ext
    return path + ext


def sidecar_of(path: str) -> str:
    if path.endswith(".xmf"):
        return path + ".xmf"
    return with_extension(path, ".xmf")


def run_files(text: str) -> dict[str, str]:
    """The files a run of this input writes: output, sidecar, checkpoint."""
    out = value_of(text, "output_file")
    out = "iem_out.h5" if not out else out.rstrip()
    chk = value_of(text, "checkpoint_file")
    chk = with_extension(out, ".chk") if not chk or not chk.strip() else chk.rstrip()
    return {"output": out, "sidecar": sidecar_of(out), "checkpoint": chk}


# ---- bases: the shipped scenes made cheap -----------------------------------------------------
def shrink(text: str) -> str:
    """A cheap version of a shipped scene: coarse grid, short dynamic run, two load steps."""
    groups, assigns = parse(text)
    static = value_of(text, "analysis") == "static"
    edits = []
    for a in assigns:
        g = groups[a.group].name
        v = text[a.start:a.end]
        if g == "geometry" and a.key == "nx":
            edits.append((a, str(min(int(v), 10))))
        elif g == "geometry" and a.key == "ny":
            edits.append((a, str(min(int(v), 2))))
        elif g == "run" and a.key == "t_end" and not static:
            edits.append((a, repr(float(v) / 10)))
        elif g == "static" and a.key == "load_steps":
            edits.append((a, "2"))
    for a, new in sorted(edits, key=lambda e: -e[0].start):
        text = text[:a.start] + new + text[a.end:]
    return text


@dataclass
class Base:
    name: str
    text: str
    static: bool
    seconds: float = 0.0


def load_bases() -> list[Base]:
    bases = []
    for p in sorted((ROOT / "inputs").glob("*.nml")):
        text = shrink(p.read_text())
        bases.append(Base(p.stem, text, value_of(text, "analysis") == "static"))
    return bases


# ---- cases ---------------------------------------------------------------------------------
@dataclass
class Case:
    index: int
    base: str
    kind: str                       # mutation family
    what: str                       # the mutation, in words
    data: bytes                     # the mutated input
    ranks: int = 1
    must_refuse: str = ""           # why a refusal is the only acceptable outcome
    group: str = ""                 # the group and key a targeted mutation touches
    key: str = ""
    setup: list = field(default_factory=list)   # ('dir'|'fifo'|'file'|'symlink', ...)
    outside: list = field(default_factory=list) # paths outside the folder it may write
    probe_name: str = ""            # a probe whose group must exist after exit 0


def classify(literal: str, kind: str, rng) -> str:
    """Why the value `literal` must be refused for a key of this type ('' if it need not)."""
    s = literal.strip()
    low = s.lower().lstrip("+-")
    if s == "":
        return "empty value (a namelist null keeps the default silently)"
    if low.startswith("nan") or low.startswith("inf"):
        return "non-finite value"
    if kind in ("r", "a2", "a4"):
        try:
            v = float(s)
        except ValueError:
            return "not a number"
        if math.isinf(v):
            return "value overflows a double"
        if callable(rng) and not rng(v):
            return "out of range"
        return ""
    if kind == "i":
        if not re.fullmatch(r"[+-]?\d+", s):
            return "not an integer"
        v = int(s)
        if not -2**31 <= v < 2**31:
            return "integer overflow"
        if isinstance(rng, int) and v < rng:
            return "out of range"
        return ""
    return ""


def wrong_typed(kind: str, r: random.Random) -> tuple[str, str]:
    """A value of the wrong type for a key of this type, and why it must be refused."""
    if kind in ("r", "i"):
        pool = [("'text'", "a string for a number"), (".true.", "a logical for a number"),
                ("1.0, 2.0", "an array for a scalar"), ("1.0 2.0 3.0", "an array for a scalar"),
                ("", "empty value (a namelist null keeps the default silently)"),
                ("(1.0, 2.0)", "a complex for a number"), ("3*1.0", "a repeat count for a scalar"),
                ("1.0.0", "not a number"), ("1e", "not a number"), ("0x10", "not a number")]
        if kind == "i":
            pool += [("2.5", "a real for an integer"), ("1e3", "a real for an integer")]
    elif kind == "l":
        pool = [("1", "an integer for a logical"), ("'yes'", "a string for a logical"),
                ("2.5", "a real for a logical"), ("", "empty value"),
                (".true., .false.", "an array for a scalar")]
    elif kind in ("e", "p", "t"):
        pool = [("5", "an integer for a string"), ("1.5e3", "a real for a string"),
                (".true.", "a logical for a string"), ("", "empty value"),
                ("'a', 'b'", "an array for a scalar")]
    else:  # arrays
        pool = [("'text'", "a string for a number"), ("1.0", "too few values"),
                ("1.0, 2.0, 3.0, 4.0, 5.0", "too many values"), ("", "empty value"),
                (".true., .false.", "logicals for numbers")]
    return r.choice(pool)


def out_of_range(kind: str, rng, r: random.Random) -> str | None:
    """A value just outside the documented range, or None."""
    if kind == "i" and isinstance(rng, int):
        return str(rng - r.choice([1, 2, 100]))
    if kind == "r" and callable(rng):
        cands = [v for v in (0.0, -1e-12, -1.0, 1.0, 1.5, 0.5, -0.5, -1.0, 1e-12, 2.0)
                 if not rng(v)]
        return repr(r.choice(cands)) if cands else None
    if kind == "e":
        return r.choice(["'bogus'", "''", "'" + "x" * 40 + "'", "' '"])
    return None


def splice(text: str, start: int, end: int, new: str) -> str:
    return text[:start] + new + text[end:]


def set_run(text: str, key: str, value: str) -> str:
    """Give &run key = value (replacing an existing assignment, else adding one)."""
    groups, assigns = parse(text)
    hits = [a for a in assigns if groups[a.group].name == "run" and a.key == key]
    if hits:
        return splice(text, hits[-1].start, hits[-1].end, value)
    g = next(g for g in groups if g.name == "run")
    return splice(text, g.slash, g.slash, f"  {key} = {value}\n")


def m_value(base: Base, r: random.Random, c: Case) -> str:
    """A value replaced by an extreme, a non-finite, a wrong-typed or an out-of-range one."""
    text = base.text
    groups, assigns = parse(text)
    assigns = [a for a in assigns if a.key in SCHEMA.get(groups[a.group].name, {})]
    if r.random() < 0.25:
        # a key the base does not give, added to a group it has
        gi = r.randrange(len(groups))
        gname = groups[gi].name
        present = {a.key for a in assigns if a.group == gi}
        free = sorted(set(SCHEMA.get(gname, {})) - present)
        if not free:
            return ""
        key = r.choice(free)
        start = end = groups[gi].slash
        added = True
    else:
        a = r.choice(assigns)
        gname, key, start, end, added = groups[a.group].name, a.key, a.start, a.end, False
    kind, rng = SCHEMA[gname][key]
    c.group, c.key = gname, key
    family = r.choice(["extreme", "extreme", "nonfinite", "wrong_type", "out_of_range"])
    if kind == "t" and family != "wrong_type":
        family = "text"
    elif kind in ("e", "p", "l") and family in ("extreme", "nonfinite"):
        family = r.choice(["wrong_type", "out_of_range"])
    if kind in ("a2", "a4") and family in ("extreme", "nonfinite") and not added:
        parts = [p for p in re.split(r"[,\s]+", text[start:end]) if p]
        new = r.choice(EXTREMES if family == "extreme" else NONFINITE)
        i = r.randrange(len(parts))
        parts[i] = new
        value, why = ", ".join(parts), classify(new, "r", None)
        c.kind = f"value.{family}"
    elif family == "extreme" and kind in ("r", "i", "a2", "a4"):
        value = r.choice(EXTREMES)
        if kind == "a2":
            value = f"{value}, {value}"
        elif kind == "a4":
            value = ", ".join([value] * 4)
        why = classify(value.split(",")[0], "r" if kind.startswith("a") else kind, rng)
        c.kind = "value.extreme"
    elif family == "nonfinite" and kind in ("r", "a2", "a4"):
        value = r.choice(NONFINITE)
        if kind == "a2":
            value = f"0.0, {value}"
        why = "non-finite value"
        c.kind = "value.nonfinite"
    elif family == "text":
        value, why = r.choice([("'" + "n" * 100 + "'", ""), ("'a b'", ""), ("'t/x'", ""),
                               ("''", ""), ("'" + "\u00e9t\u00e9" + "'", ""), ("'a!b'", ""),
                               ("'it''s'", "")])
        if gname == "probe":
            # docs/input.md: required; letters, digits, _ - . only; unique
            if value == "'" + "n" * 100 + "'":
                c.probe_name = "n" * 100   # a long name must be kept whole, or refused
            else:
                why = "a probe name of letters, digits, _ - . only (required)"
        c.kind = "value.text"
    elif family == "out_of_range" and out_of_range(kind, rng, r) is not None:
        value = out_of_range(kind, rng, r)
        why = "out of range" if value.strip("'") not in ("", " ") else "empty string"
        if kind == "e" and value == "'" + "x" * 40 + "'":
            why = "not one of the allowed values"
        c.kind = "value.out_of_range"
    else:
        value, why = wrong_typed(kind, r)
        c.kind = "value.wrong_type"
    new = f"  {key} = {value}\n" if added else value
    c.what = f"&{gname} {key} = {value!s}" + (" (added)" if added else "")
    c.must_refuse = why
    return splice(text, start, end, new)


def m_key(base: Base, r: random.Random, c: Case) -> str:
    """A key replaced by an unknown one, or given twice in its group."""
    text = base.text
    groups, assigns = parse(text)
    a = r.choice(assigns)
    gname = groups[a.group].name
    c.group, c.key = gname, a.key
    if r.random() < 0.5:
        other = [k for g, ks in SCHEMA.items() if g != gname for k in ks
                 if k not in SCHEMA.get(gname, {})]
        new = r.choice(["bogus", a.key + "_x", a.key[:-1] or "q", a.key[::-1] + "z",
                        r.choice(other), "x" * 40, "_" + a.key, a.key + "1"])
        c.kind = "key.unknown"
        c.what = f"&{gname}: {a.key} renamed to {new}"
        c.must_refuse = "unknown variable"
        c.key = new
        return splice(text, a.key_start, a.key_start + len(a.key), new)
    value = text[a.start:a.end]
    kind = SCHEMA.get(gname, {}).get(a.key, ("?",))[0]
    if r.random() < 0.5:
        second, c.must_refuse = value, ""
        c.kind = "key.twice_same"
    else:
        second = {"r": "1.0", "i": "3", "l": ".false." if "true" in value.lower() else ".true.",
                  "a2": "0.5, 0.05", "a4": "0.0, 1.0, 0.0, 0.1"}.get(kind)
        if second is None:
            second = "'other'" if value != "'other'" else "'another'"
        c.must_refuse = "key given twice with different values: one is silently ignored"
        c.kind = "key.twice_different"
    c.what = f"&{gname}: {a.key} = {value} then {a.key} = {second}"
    g = groups[a.group]
    return splice(text, g.slash, g.slash, f"  {a.key} = {second}\n")


def m_group(base: Base, r: random.Random, c: Case) -> str:
    """A group doubled, or its closing '/' removed."""
    text = base.text
    groups, _ = parse(text)
    g = r.choice(groups)
    c.group = g.name
    if r.random() < 0.5:
        c.kind = "group.doubled"
        c.what = f"&{g.name} given twice"
        if g.name in ONCE:
            c.must_refuse = "a group that may appear once is given twice"
        elif g.name == "material":
            c.must_refuse = "two materials without distinct names"
        elif g.name == "probe":
            c.must_refuse = "two probes with the same name"
        block = text[g.start:g.end]
        if not block.endswith("\n"):
            block += "\n"
        at = g.end if r.random() < 0.5 else len(text)
        sep = "" if at == g.end or text.endswith("\n") else "\n"
        return text[:at] + sep + block + text[at:]
    c.kind = "group.no_slash"
    c.what = f"the '/' closing &{g.name} removed"
    c.must_refuse = "a group not closed with '/'"
    return splice(text, g.slash, g.slash + 1, "")


def m_structure(base: Base, r: random.Random, c: Case) -> str:
    """A token or line dropped, doubled or truncated; a very long line."""
    text = base.text
    lines = text.splitlines(keepends=True)
    op = r.choice(["line.drop", "line.double", "line.truncate", "token.drop", "token.double",
                   "line.long"])
    c.kind = op
    code_lines = [i for i, l in enumerate(lines) if l[:code_end(l)].strip()]
    i = r.choice(code_lines)
    if op == "line.drop":
        c.what = f"line {i + 1} dropped: {lines[i].strip()[:60]!r}"
        del lines[i]
    elif op == "line.double":
        c.what = f"line {i + 1} doubled: {lines[i].strip()[:60]!r}"
        lines.insert(i, lines[i])
        stripped = lines[i][:code_end(lines[i])].strip()
        if stripped.startswith("&"):
            c.must_refuse = "a group opened inside a group"
        elif stripped == "/":
            c.must_refuse = "text outside any group ('/')"
    elif op == "line.truncate":
        body = lines[i].rstrip("\n")
        cut = r.randrange(0, max(1, len(body)))
        c.what = f"line {i + 1} truncated to {body[:cut]!r}"
        lines[i] = body[:cut] + "\n"
    elif op in ("token.drop", "token.double"):
        toks = list(re.finditer(r"[^\s,=]+", lines[i]))
        t = r.choice(toks)
        if op == "token.drop":
            lines[i] = lines[i][:t.start()] + lines[i][t.end():]
            c.what = f"line {i + 1}: token {t.group()!r} dropped"
        else:
            lines[i] = lines[i][:t.end()] + " " + t.group() + lines[i][t.end():]
            c.what = f"line {i + 1}: token {t.group()!r} doubled"
    else:
        n = r.choice([513, 600, 5000, 100000])
        style = r.choice(["comment", "blank", "value"])
        if style == "comment":
            lines.insert(i, "! " + "c" * n + "\n")
        elif style == "blank":
            lines.insert(i, " " * n + "\n")
        else:
            groups, assigns = parse(text)
            a = r.choice([a for a in assigns if groups[a.group].name == "geometry"
                          and a.key in ("length", "height")] or assigns)
            text2 = splice(text, a.start, a.start, "0" * n if text[a.start].isdigit()
                           else " " * n)
            c.what = f"a {n}-character pad in front of the value of {a.key}"
            return text2
        c.what = f"a line of {n} characters ({style}) before line {i + 1}"
    return "".join(lines)


def m_bytes(base: Base, r: random.Random, c: Case) -> bytes:
    """Bytes flipped: non-ASCII, NUL, control and syntax characters."""
    data = bytearray(base.text.encode())
    n = r.choice([1, 1, 1, 2, 3, 8])
    pool = [0x00, 0x01, 0x07, 0x09, 0x0A, 0x0D, 0x1A, 0x7F, 0x80, 0xC3, 0xE2, 0xFF, 0xFE,
            ord("&"), ord("/"), ord("="), ord("'"), ord('"'), ord("!"), ord(","), ord("*"),
            ord("%"), ord("$")]
    flips = []
    for _ in range(n):
        pos = r.randrange(len(data))
        new = r.choice(pool) if r.random() < 0.7 else r.randrange(256)
        if r.random() < 0.1:  # a multibyte character instead of one byte
            chunk = r.choice(["é", "→", "\u00a0", "\ufeff", "𝔁"]).encode()
            data[pos:pos + 1] = chunk
            flips.append(f"@{pos}: {chunk!r}")
        else:
            flips.append(f"@{pos}: {bytes([data[pos]])!r}->{bytes([new])!r}")
            data[pos] = new
    c.kind = "bytes.flip"
    c.what = "bytes flipped " + ", ".join(flips)
    return bytes(data)


def m_files(base: Base, r: random.Random, c: Case) -> str:
    """output_file, checkpoint_file or restart pointing somewhere they must not."""
    text = base.text
    files = run_files(text)
    out = files["output"]
    ops = ["out.long_path", "out.long_creatable", "out.missing_folder", "out.folder",
           "out.folder_slash", "out.devnull", "out.fifo", "out.symlink_folder",
           "out.is_input", "out.is_checkpoint", "out.empty", "out.not_overwrite",
           "chk.is_input", "chk.missing_folder", "restart.garbage", "restart.folder",
           "restart.fifo", "restart.output", "restart.missing", "out.spaces"]
    op = r.choice(ops)
    c.kind = op
    c.group, c.key = "run", "output_file"
    dyn_only = not base.static
    if op == "out.long_path":
        p = "/".join(["p" * 250] * 17) + "/o.h5"
        text = set_run(text, "output_file", f"'{p}'")
        c.what, c.must_refuse = f"output_file a path of {len(p)} characters", "no such folder"
    elif op == "out.long_creatable":
        parts = ["d" * 200] * 6
        c.setup.append(("dir", "/".join(parts)))
        p = "/".join(parts) + "/long_out.h5"
        # a quoted string continued over three records, each line below 512 characters
        cont = p[:400] + "\n" + p[400:800] + "\n" + p[800:]
        text = set_run(text, "output_file", f"'{cont}'")
        c.what = f"output_file a creatable path of {len(p)} characters, continued over 3 lines"
    elif op == "out.missing_folder":
        text = set_run(text, "output_file", "'no_such_folder/out.h5'")
        c.what, c.must_refuse = "output_file in a missing folder", "missing folder"
    elif op in ("out.folder", "out.folder_slash"):
        c.setup.append(("dir", "adir"))
        name = "adir" if op == "out.folder" else "adir/"
        text = set_run(text, "output_file", f"'{name}'")
        c.what, c.must_refuse = f"output_file = '{name}', a folder", "output_file is a folder"
    elif op == "out.devnull":
        text = set_run(text, "output_file", "'/dev/null'")
        if dyn_only:
            text = set_run(text, "checkpoint_file", "'devnull.chk'")
        c.outside = ["/dev/null.xmf", "/dev/null.chk", "/dev/null.chk.tmp"]
        c.what, c.must_refuse = "output_file = '/dev/null'", "output_file is not a regular file"
    elif op == "out.fifo":
        c.setup.append(("fifo", "fifo.h5"))
        text = set_run(text, "output_file", "'fifo.h5'")
        c.what, c.must_refuse = "output_file a FIFO", "output_file is not a regular file"
    elif op == "out.symlink_folder":
        c.setup += [("dir", "adir"), ("symlink", "dlink.h5", "adir")]
        text = set_run(text, "output_file", "'dlink.h5'")
        c.what, c.must_refuse = "output_file a symlink to a folder", "output_file is a folder"
    elif op == "out.is_input":
        name = r.choice([INPUT_NAME, "./" + INPUT_NAME, "../{folder}/" + INPUT_NAME])
        text = set_run(text, "output_file", f"'{name}'")
        text = set_run(text, "overwrite", ".true.")
        c.what, c.must_refuse = f"output_file = '{name}', the input", "output_file is the input"
    elif op == "out.is_checkpoint":
        if not dyn_only:
            text = set_run(text, "checkpoint_file", "'./x.h5'")
            c.must_refuse = "static run with checkpoint_file"
        else:
            text = set_run(text, "checkpoint_file", "'./x.h5'")
            c.must_refuse = "output_file and checkpoint_file are one file"
        text = set_run(text, "output_file", "'x.h5'")
        c.what = "output_file = 'x.h5', checkpoint_file = './x.h5'"
    elif op == "out.empty":
        text = set_run(text, "output_file", r.choice(["''", "' '"]))
        c.what, c.must_refuse = "output_file empty", "output_file names no file"
    elif op == "out.not_overwrite":
        text = set_run(text, "overwrite", ".false.")
        c.what, c.must_refuse = "overwrite = .false. (the output exists)", "output exists"
    elif op == "out.spaces":
        text = set_run(text, "output_file", "'  spaced out.h5'")
        c.what = "output_file = '  spaced out.h5' (leading blanks)"
    elif op == "chk.is_input":
        text = set_run(text, "checkpoint_file", f"'./{INPUT_NAME}'")
        c.key = "checkpoint_file"
        c.what = f"checkpoint_file = './{INPUT_NAME}', the input"
        c.must_refuse = "checkpoint_file is the input"
    elif op == "chk.missing_folder":
        text = set_run(text, "checkpoint_file", "'no_such_folder/x.chk'")
        if dyn_only:
            text = set_run(text, "checkpoint_interval", repr(float(value_of(text, "t_end")) / 2))
        c.key = "checkpoint_file"
        c.what = "checkpoint_file in a missing folder, checkpoint_interval = t_end/2"
        c.must_refuse = "checkpoint_file in a missing folder"
    else:
        c.key = "restart"
        if op == "restart.garbage":
            size = r.choice([0, 1, 7, 64, 100, 4096, 65536])
            c.setup.append(("file", "garbage.chk", r.randbytes(size)))
            target = "garbage.chk"
            c.what = f"restart = a garbage file of {size} bytes"
        elif op == "restart.folder":
            c.setup.append(("dir", "adir"))
            target, c.what = "adir", "restart = a folder"
        elif op == "restart.fifo":
            c.setup.append(("fifo", "fifo.chk"))
            target, c.what = "fifo.chk", "restart = a FIFO"
        elif op == "restart.output":
            target, c.what = out, "restart = the output file (an HDF5 file, not a checkpoint)"
        else:
            target, c.what = "missing.chk", "restart = a missing file"
        text = set_run(text, "restart", f"'{target}'")
        c.must_refuse = "restart is not a checkpoint of this model"
    return text


MUTATORS = [(m_value, 40), (m_key, 12), (m_group, 8), (m_structure, 14), (m_bytes, 12),
            (m_files, 14)]


def make_case(index: int, seed: int, bases: list[Base], two_rank_share: float) -> Case:
    """Case `index` of seed `seed`: always the same mutation of the same base."""
    r = random.Random(f"{seed}:{index}")
    base = bases[r.randrange(len(bases))]
    fn = r.choices([m for m, _ in MUTATORS], weights=[w for _, w in MUTATORS])[0]
    c = Case(index, base.name, "", "", b"")
    c.ranks = 2 if r.random() < two_rank_share else 1
    for _ in range(5):
        out = fn(base, r, c)
        if out:
            break
    c.data = out if isinstance(out, bytes) else out.encode()
    return c
