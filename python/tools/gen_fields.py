"""Build step: writes the `.def_readwrite` lines of one C++ options struct.

    gen_fields.py HEADER STRUCT CXXNAME OUT

OUT is #included inside the struct's py::class_ chain in python/src, so every
field of the header is bound, under its own name; tests/test_options_drift.py
then checks each default. The file is rewritten only when its text changes.
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from cxx_options import readwrite_lines  # noqa: E402


def main():
    header, struct, cxx, out = sys.argv[1:5]
    lines = readwrite_lines(header, struct, cxx)
    if not lines:
        sys.exit(f"gen_fields.py: no fields found for {struct} in {header}")
    text = f"// Generated from {Path(header).name} ({struct}) by python/tools/gen_fields.py; do not edit.\n" + "\n".join(lines) + "\n"
    p = Path(out)
    if not p.exists() or p.read_text() != text:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)


if __name__ == "__main__":
    main()
