"""Type stubs of the built module.

    PYTHONPATH=build/python /usr/bin/python3 python/tools/gen_stubs.py [--output FILE]

The build runs it after linking the module (<build>/python/mvkp/__init__.pyi,
what is installed); python/mvkp/__init__.pyi in the source tree is a snapshot
of it for reading, refreshed with --output python/mvkp/__init__.pyi.

Signatures and docstrings come from pybind11; functions that take options as
keyword arguments get one keyword per options field, typed and defaulted from a
default-constructed options object, so the stubs list exactly what the C++
structs have.
"""
import enum
import inspect
import re
import sys

import mvkp
from mvkp import _mvkp

# Which options classes' fields a **kwargs function takes (first class wins on
# a name both have), and defaults that differ from the class's.
KWARGS = {
    "train": ["TrainOptions"],
    "match": ["MatchOptions"],
    "pair": ["TrainOptions", "MatchOptions", "PairMatchOptions", "LocalFeatureOptions"],
    "make_scene_view": ["SceneOptions"],
    "assess_target": ["QualityOptions"],
    "FfvaIndex": ["FfvaOptions"],
    "load_index": ["IndexLoadOptions"],
    "augment": ["AugmentOptions"],
    "segment_depth": ["DepthSegmentOptions"],
    "segment_optical": ["OpticalSegmentOptions"],
    "register_contours": ["RegistrationOptions"],
    "register_aerial": ["RegistrationOptions"],
    "make_city": ["CityOptions"],
    "read_depth": ["DepthReadOptions"],
    "Matcher.__init__": ["MatchOptions"],
    "Recognizer.__init__": ["RecognizerOptions"],
    "Database.recognizer": ["RecognizerOptions"],
    "Database.add": ["TrainOptions"],
    "Cdikp.__init__": ["CdikpOptions"],
}
OVERRIDES = {"Database.add": {"max_object_side": 320, "min_scale": 0.25}}  # `mvkp db add` training defaults

IMAGE_ARGS = {"image", "frame", "image1", "image2", "target", "background", "src", "photo"}


# Properties whose C++ lambdas return py::object: their Python types.
PROPERTY_TYPES = {
    "homography": "numpy.ndarray | None", "outline": "numpy.ndarray | None", "edge": "dict[str, Any] | None",
    "model": "str | None", "size": "tuple[int, int]", "meta": "dict[str, Any]",
    "descriptors": "numpy.ndarray", "labels": "numpy.ndarray", "depth": "numpy.ndarray", "photo": "numpy.ndarray",
}


def py_type(tname):
    t = tname.replace("mvkp._mvkp.", "")
    t = re.sub(r"\bhandle\b", "Any", t)
    t = re.sub(r"numpy\.ndarray\[[^\]]*\]", "numpy.ndarray", t)
    t = t.replace("object", "Any").replace("List[", "list[").replace("Dict[", "dict[").replace("Tuple[", "tuple[")
    t = t.replace("Callable[[int, int], None]", "Callable[[int, int], None] | None")
    return t


def value_type(v):
    if isinstance(v, bool):
        return "bool"
    if isinstance(v, int):
        return "int"
    if isinstance(v, float):
        return "float"
    if isinstance(v, str):
        return "str"
    if v is None:
        return "Callable[[int, int], None] | None"
    if isinstance(v, list):
        return "list[float]"
    name = type(v).__qualname__
    if hasattr(type(v), "__members__"):
        return f"{name} | str"
    return name


def value_repr(v):
    if hasattr(type(v), "__members__"):
        return repr(str(v))
    if isinstance(v, float):
        return repr(float("%.7g" % v))
    if v is None or isinstance(v, (bool, int, str)):
        return repr(v)
    return "..."


def fields(cls_name):
    obj = getattr(mvkp, cls_name)()
    return [(n, getattr(obj, n)) for n in obj.to_dict()]


def kw_params(key):
    out, seen = [], set()
    over = OVERRIDES.get(key, {})
    for cls in KWARGS[key]:
        for n, v in fields(cls):
            if n in seen:
                continue
            seen.add(n)
            default = "..." if n in over or hasattr(v, "to_dict") else value_repr(v)
            if n in over:
                default = repr(over[n])
            t = value_type(v)
            if hasattr(v, "to_dict"):
                t = f"{t} | dict[str, Any]"
            out.append(f"{n}: {t} = {default}")
    return out


def split_doc(doc):
    """pybind11 docstring -> [(signature, text)] (several for overloads)."""
    doc = doc or ""
    lines = doc.strip().splitlines()
    if lines and lines[0].startswith("Overloaded function."):
        parts = re.split(r"^\d+\. ", "\n".join(lines[1:]), flags=re.M)
        res = []
        for p in parts:
            p = p.strip()
            if p:
                sig, _, text = p.partition("\n")
                res.append((sig, text.strip()))
        return res
    if not lines:
        return [("", "")]
    return [(lines[0], "\n".join(lines[1:]).strip())]


def render_sig(name, sig, key, method):
    m = re.match(r"^[\w.]+\((.*)\)(?: -> (.*))?$", sig)
    if not m:
        return f"def {name}(*args: Any, **kwargs: Any) -> Any: ..."
    args, ret = m.group(1), m.group(2) or "None"
    params = []
    depth, cur = 0, ""
    for c in args:
        if c in "([":
            depth += 1
        elif c in ")]":
            depth -= 1
        if c == "," and depth == 0:
            params.append(cur.strip())
            cur = ""
        else:
            cur += c
    if cur.strip():
        params.append(cur.strip())
    out = []
    for p in params:
        if p.startswith("**"):
            if key in KWARGS:
                if "*" not in out and not any(x.startswith("*") for x in out):
                    out.append("*")
                out += kw_params(key)
            else:
                out.append("**kwargs: Any")
            continue
        if p == "*" or p.startswith("*"):
            out.append(p if p == "*" else "*args: Any")
            continue
        pm = re.match(r"(\w+)(?:: ([^=]+?))?(?: = (.*))?$", p)
        if not pm:
            out.append(p)
            continue
        n, t, d = pm.group(1), pm.group(2), pm.group(3)
        if n == "self":
            out.append("self")
            continue
        t = py_type(t or "Any")
        if n in IMAGE_ARGS and t == "Any":
            t = "numpy.ndarray"
        if t == "Any" and n in ("H", "a", "b", "data", "queries", "keypoints", "descriptors", "codes1", "codes2", "depth"):
            t = "numpy.ndarray"
        if n == "options" and key in KWARGS and t == "Any":
            t = KWARGS[key][0]
        if n in ("depth_options", "optical_options", "edge_options"):
            t = {"depth_options": "DepthSegmentOptions", "optical_options": "OpticalSegmentOptions",
                 "edge_options": "EdgeEvidenceOptions"}[n]
        if d is not None:
            d = d.strip()
            if d.startswith("<") or "mvkp._mvkp" in d:
                d = "..."
            if d == "None" and t != "Any" and not t.endswith("| None"):
                t = f"{t} | None"
            out.append(f"{n}: {t} = {d}")
        else:
            out.append(f"{n}: {t}")
    ret = py_type(ret)
    if name == "__init__":
        ret = "None"
    return f"def {name}({', '.join(out)}) -> {ret}: ..."


def doc_block(text, indent):
    if not text:
        return []
    text = text.replace('"""', "'''")
    return [indent + '"""' + text.replace("\n", "\n" + indent) + '"""']


def emit_function(name, fn, key, indent, method=False):
    lines = []
    variants = split_doc(fn.__doc__)
    for sig, text in variants:
        if len(variants) > 1:
            lines.append(indent + "@overload")
        lines.append(indent + render_sig(name, sig, key, method))
        if text:
            lines[-1] = lines[-1][:-4]
            lines.extend(doc_block(text, indent + "    "))
    return lines


def emit_class(name, cls):
    lines = []
    is_enum = hasattr(cls, "__members__")
    bases = "Exception" if isinstance(cls, type) and issubclass(cls, BaseException) else ""
    lines.append(f"class {name}{'(' + bases + ')' if bases else ''}:")
    if cls.__doc__ and not is_enum:
        lines.extend(doc_block(cls.__doc__.strip(), "    "))
    if is_enum:
        doc = (cls.__doc__ or "").split("\n\nMembers:")[0].strip()
        if doc:
            lines.extend(doc_block(doc, "    "))
        for m in cls.__members__:
            lines.append(f"    {m}: {name}")
        lines.append(f"    def __init__(self, value: int | str) -> None: ...")
        lines += ["    @property", "    def name(self) -> str: ...", "    @property", "    def value(self) -> int: ..."]
        return lines
    is_options = hasattr(cls, "to_dict") and name.endswith(("Options",))
    if is_options:
        for n, v in fields(name):
            lines.append(f"    {n}: {value_type(v)}")
        lines.append(f"    def __init__(self, *, {', '.join(kw_params_for_class(name))}) -> None: ...")
        lines.append(f"    def to_dict(self) -> dict[str, Any]: ...")
        lines.append(f"    def copy(self) -> {name}: ...")
        if hasattr(cls, "check"):
            lines.append("    def check(self) -> None:")
            lines.extend(doc_block("Raises InvalidArgumentError naming the first bad option.", "        "))
        for sub in sorted(vars(cls)):
            v = getattr(cls, sub)
            if isinstance(v, type) and hasattr(v, "__members__"):
                lines.extend("    " + l for l in emit_class(sub, v))
        if hasattr(cls, "words"):
            lines.append("    @staticmethod")
            lines.append(f"    def words() -> {name}: ...")
        return lines
    for attr, v in vars(cls).items():
        if attr.startswith("__") and attr not in ("__init__", "__len__", "__contains__", "__iter__", "__enter__", "__exit__", "__bool__"):
            continue
        key = f"{name}.{attr}"
        if isinstance(v, property):
            sig = (v.fget.__doc__ or "").strip().splitlines()
            ret = "Any"
            text = (v.__doc__ or "").strip()
            if sig:
                m = re.match(r"^\(self: [^)]*\) -> (.*)$", sig[0])
                if m:
                    ret = py_type(m.group(1))
                text = text or "\n".join(sig[1:]).strip()
            if text.startswith("(self"):
                text = "\n".join(text.splitlines()[1:]).strip()
            if ret == "Any" and attr in PROPERTY_TYPES:
                ret = PROPERTY_TYPES[attr]
            lines.append("    @property")
            lines.append(f"    def {attr}(self) -> {ret}:" + ("" if text else " ..."))
            if text:
                lines.extend(doc_block(text, "        "))
        elif isinstance(v, staticmethod) or type(v).__name__ == "staticmethod":
            lines.append("    @staticmethod")
            lines.extend(emit_function(attr, getattr(cls, attr), key, "    "))
        elif callable(v) and hasattr(v, "__doc__") and type(v).__name__ in ("instancemethod", "builtin_function_or_method", "function"):
            lines.extend(emit_function(attr, v, key, "    ", method=True))
    if name in ("Error",) or bases:
        lines.append("    code: str")
    if len(lines) == 1 or (len(lines) == 2 and cls.__doc__):
        lines.append("    ...")
    return lines


def kw_params_for_class(name):
    KWARGS[name] = [name]
    return kw_params(name)


def main():
    out = [
        '"""Type stubs of the mvkp module (generated by python/tools/gen_stubs.py from the built module)."""',
        "from typing import Any, Callable, Iterator, overload",
        "",
        "import numpy",
        "",
        "__version__: str",
        "HAS_AERIAL: bool",
        "",
        "def to_cv_keypoints(keypoints: numpy.ndarray) -> list[Any]:",
        '    """cv2.KeyPoint list from an (n, 7) keypoint array (x, y, size, angle, response, octave, class_id)."""',
        "",
    ]
    errors = ["Error", "InvalidArgumentError", "IoError", "BadImageError", "BadModelError", "NoTextureError", "BadIndexError"]
    bases = {"Error": "RuntimeError", "InvalidArgumentError": "Error, ValueError", "IoError": "Error, OSError",
             "BadImageError": "Error, ValueError"}
    for e in errors:
        out.append(f"class {e}({bases.get(e, 'Error')}):")
        out.extend(doc_block(getattr(mvkp, e).__doc__.strip(), "    "))
        out.append("    code: str")
        out.append("")
    names = sorted(n for n in dir(_mvkp) if not n.startswith("_") and n not in errors and n != "HAS_AERIAL")
    for n in names:
        v = getattr(_mvkp, n)
        if isinstance(v, type):
            out.extend(emit_class(n, v))
            out.append("")
    for n in names:
        v = getattr(_mvkp, n)
        if not isinstance(v, type) and callable(v):
            out.extend(emit_function(n, v, n, ""))
            out.append("")
    text = "\n".join(out).rstrip() + "\n"
    if len(sys.argv) > 2 and sys.argv[1] == "--output":
        with open(sys.argv[2], "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
