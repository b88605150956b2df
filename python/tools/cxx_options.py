"""Reads the fields of a C++ options struct (name, type, default) from a header.

Used at build time to generate the bindings' field lists (gen_fields.py, one
`.def_readwrite` per field), and by tests/test_options_drift.py to check that
every field is exposed with the same default. A small, purpose-built parser for
the style of mvkp's headers (one struct per `struct Name { ... };`, fields with
default member initialisers, comments anywhere), not a C++ parser.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path


@dataclass
class Field:
    name: str
    type: str
    default: str | None  # the initialiser text, None when there is none


def _strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    out = []
    for line in text.splitlines():
        # '//' outside a string literal
        in_str = False
        cut = len(line)
        for i, c in enumerate(line):
            if c == '"' and (i == 0 or line[i - 1] != "\\"):
                in_str = not in_str
            elif not in_str and line.startswith("//", i):
                cut = i
                break
        out.append(line[:cut])
    return "\n".join(out)


def _struct_body(text: str, name: str) -> str:
    m = re.search(r"\bstruct\s+" + re.escape(name) + r"\s*\{", text)
    if not m:
        raise KeyError(f"struct {name} not found")
    i = m.end()
    depth = 1
    start = i
    while depth:
        c = text[i]
        if c == "{":
            depth += 1
        elif c == "}":
            depth -= 1
        i += 1
    return text[start : i - 1]


def _statements(body: str) -> list[str]:
    """Splits a struct body at ';' outside braces/parens; drops inline function bodies."""
    stmts, cur = [], []
    depth = 0
    i = 0
    while i < len(body):
        c = body[i]
        if c in "{(":
            depth += 1
        elif c in "})":
            depth -= 1
            if depth == 0 and c == "}":
                before = "".join(cur)
                head = before[: before.rfind("{")] if "{" in before else before
                if "(" in head.split("=")[0]:  # a member function with a body
                    cur = []
                    i += 1
                    continue
        if c == ";" and depth == 0:
            stmts.append("".join(cur).strip())
            cur = []
        else:
            cur.append(c)
        i += 1
    return [" ".join(s.split()) for s in stmts if s.strip()]


def _split_top(s: str, sep: str = ",") -> list[str]:
    parts, cur, depth = [], [], 0
    for c in s:
        if c in "({[<":
            depth += 1
        elif c in ")}]>":
            depth -= 1
        if c == sep and depth == 0:
            parts.append("".join(cur).strip())
            cur = []
        else:
            cur.append(c)
    parts.append("".join(cur).strip())
    return parts


def _split_type(stmt: str) -> tuple[str, str]:
    """'std::array<double, 5> w{}' -> ('std::array<double, 5>', 'w{}')."""
    m = re.match(r"enum\s+class\s+(\w+)\s*(?::\s*[\w:]+\s*)?\{[^}]*\}\s*(.*)$", stmt)
    if m:
        return "enum " + m.group(1), m.group(2)
    i = 0
    m = re.match(r"(?:(?:const|static|constexpr|inline|mutable)\s+)*[\w:]+", stmt)
    if not m:
        raise ValueError(stmt)
    i = m.end()
    if i < len(stmt) and stmt[i] == "<":
        depth = 0
        while True:
            if stmt[i] == "<":
                depth += 1
            elif stmt[i] == ">":
                depth -= 1
                if depth == 0:
                    i += 1
                    break
            i += 1
    return stmt[:i].strip(), stmt[i:].strip()


def struct_fields(header: str | Path, name: str) -> list[Field]:
    """The data members of `struct name` in `header`, in declaration order."""
    text = _strip_comments(Path(header).read_text())
    fields: list[Field] = []
    for stmt in _statements(_struct_body(text, name)):
        if re.match(r"(static|using|friend|typedef|template|public|private|protected)\b", stmt):
            continue
        if re.match(r"enum\s+class\s+\w+\s*(?::\s*[\w:]+\s*)?\{[^}]*\}$", stmt):
            continue  # a nested enum type without a member
        type_, rest = _split_type(stmt)
        if "(" in rest.split("=")[0]:
            continue  # a member function declaration
        for decl in _split_top(rest):
            if "=" in decl:
                n, d = decl.split("=", 1)
                fields.append(Field(n.strip(), type_, d.strip()))
            elif "{" in decl:
                n, d = decl.split("{", 1)
                fields.append(Field(n.strip(), type_, "{" + d))
            else:
                fields.append(Field(decl.strip(), type_, None))
    return fields


def readwrite_lines(header: str | Path, name: str, cxx_name: str | None = None) -> list[str]:
    """pybind11 `.def_readwrite` lines binding every field of the struct."""
    cxx = cxx_name or name
    return [f'    .def_readwrite("{f.name}", &{cxx}::{f.name})  // {f.type}{" = " + f.default if f.default else ""}'
            for f in struct_fields(header, name)]


if __name__ == "__main__":  # HEADER STRUCT [CXXNAME]: prints the lines
    import sys

    print("\n".join(readwrite_lines(sys.argv[1], sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else None)))
