"""Type stubs: generated from the built module (every options field a keyword with its default)."""
import ast
import subprocess
import sys
from pathlib import Path

import mvkp

PY = Path(__file__).resolve().parents[1]
BUILT = Path(mvkp.__file__).parent / "__init__.pyi"


def top_level(tree):
    return {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}


def test_built_stub_is_current():
    text = BUILT.read_text()
    ast.parse(text)
    fresh = subprocess.run([sys.executable, str(PY / "tools" / "gen_stubs.py")], capture_output=True, text=True,
                           check=True).stdout
    assert text == fresh


def test_stub_covers_module():
    tree = ast.parse(BUILT.read_text())
    public = {n for n in dir(mvkp) if not n.startswith("_") and n != "HAS_AERIAL" and callable(getattr(mvkp, n))}
    assert public - top_level(tree) == set()
    train = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "train")
    assert {a.arg for a in train.args.kwonlyargs} == set(mvkp.TrainOptions().to_dict())
    assert ast.get_docstring(train)
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "MatchOptions")
    fields = {n.target.id for n in cls.body if isinstance(n, ast.AnnAssign)}
    assert fields == set(mvkp.MatchOptions().to_dict())


def test_source_snapshot_has_the_same_api():
    """python/mvkp/__init__.pyi (for reading the source) lists the module's classes and functions.
    Refresh: PYTHONPATH=<build>/python python3 python/tools/gen_stubs.py --output python/mvkp/__init__.pyi"""
    snap = ast.parse((PY / "mvkp" / "__init__.pyi").read_text())
    assert top_level(snap) == top_level(ast.parse(BUILT.read_text()))


def test_py_typed_marker():
    assert (Path(mvkp.__file__).parent / "py.typed").exists()
