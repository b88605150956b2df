#!/usr/bin/python3
"""Doxygen INPUT_FILTER for mvkp's headers (docs/Doxyfile.in): they document
with plain // comments, which Doxygen ignores. Prints FILE with:

  - the leading comment block (before any code) as the file's documentation
    (/// \\file ...);
  - a comment line before a declaration as a Doxygen comment (///);
  - a comment after code on the same line as a member comment (///<), and
    comment-only lines that continue it (indented past the code) too.

Line numbers are kept, so Doxygen's warnings point at the real lines. Files
other than *.h pass through unchanged."""
import re
import sys

CODE_COMMENT = re.compile(r"^(?P<code>.*?\S.*?)(?P<ws>\s+)//(?P<text>(?:[^/].*)?)$")
ONLY_COMMENT = re.compile(r"^(?P<indent>\s*)//(?P<text>(?:[^/!].*)?)$")
# Closing braces, namespaces, preprocessor lines: a trailing comment there is a
# note to the reader, not a member's documentation.
NOT_A_MEMBER = re.compile(r"^\s*(}|namespace\b|#|public:|private:|protected:)")


def outside_strings(code):
    """True if `code` (the part before //) has no unterminated string literal."""
    return code.count('"') % 2 == 0


HASH_WORD = re.compile(r"(?<=\s)#(?=\w)")


def doc(text):
    """Comment text as Doxygen reads it: '#word' would be a link request."""
    return HASH_WORD.sub(r"\\#", text)


def filter_header(lines):
    out = []
    in_header = True  # still in the leading comment block
    prev_trailing_col = None  # column of the // of a member comment on the previous line
    for line in lines:
        body = line.rstrip("\n")
        m = ONLY_COMMENT.match(body)
        if in_header:
            if m:
                text = m.group("text")
                # "\\file" at the end of the first line: the block documents
                # this file (no name follows it on that line).
                out.append("///" + doc(text) + (" \\file" if not out else "") + "\n")
                continue
            if body.strip():
                in_header = False
            # a blank line inside the leading block ends it too
            elif out:
                in_header = False
        if m:
            col = len(m.group("indent"))
            if prev_trailing_col is not None and col >= prev_trailing_col - 2 and col > 0:
                out.append(m.group("indent") + "///<" + doc(m.group("text")) + "\n")
                continue  # keeps prev_trailing_col: continuation lines may follow
            out.append(m.group("indent") + "///" + doc(m.group("text")) + "\n")
            prev_trailing_col = None
            continue
        t = CODE_COMMENT.match(body)
        if t and outside_strings(t.group("code")) and "//" not in t.group("code") and not NOT_A_MEMBER.match(body):
            out.append(t.group("code") + t.group("ws") + "///<" + doc(t.group("text")) + "\n")
            prev_trailing_col = len(t.group("code")) + len(t.group("ws"))
            continue
        prev_trailing_col = None
        out.append(line if line.endswith("\n") else line + "\n")
    return out


def main():
    path = sys.argv[1]
    with open(path, encoding="utf-8", errors="replace") as f:
        lines = f.readlines()
    if path.endswith(".h"):
        lines = filter_header(lines)
    sys.stdout.write("".join(lines))


if __name__ == "__main__":
    main()
