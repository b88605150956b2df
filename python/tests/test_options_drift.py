"""Every field of every bound C++ options struct is exposed with its C++ default.

The fields and defaults are read from the headers (cxx_options.py) and compared
with a default-constructed Python object, so an option added to, renamed in or
re-defaulted in a header fails here until the binding follows. The stubs'
keyword arguments are checked against the same classes (test_stubs.py).
"""
import re

import pytest

import mvkp
from conftest import SOURCE_DIR
from cxx_options import struct_fields

SRC = SOURCE_DIR / "src" / "mvkp"

BOUND = [
    ("train/trainer.h", "TrainOptions", "TrainOptions"),
    ("match/matcher.h", "MatchOptions", "MatchOptions"),
    ("recognize/recognizer.h", "RecognizerOptions", "RecognizerOptions"),
    ("index/ffva.h", "FfvaOptions", "FfvaOptions"),
    ("index/ffva.h", "IndexLoadOptions", "IndexLoadOptions"),
    ("cdikp/cdikp.h", "CdikpOptions", "CdikpOptions"),
    ("augment/augment.h", "AugmentOptions", "AugmentOptions"),
    ("local/local_features.h", "LocalFeatureOptions", "LocalFeatureOptions"),
    ("local/pair_match.h", "PairMatchOptions", "PairMatchOptions"),
    ("synth/synth.h", "SceneOptions", "SceneOptions"),
    ("quality/quality.h", "QualityOptions", "QualityOptions"),
]
AERIAL = [
    ("buildings/depth_regions.h", "DepthSegmentOptions", "DepthSegmentOptions"),
    ("ortho/optical_regions.h", "OpticalSegmentOptions", "OpticalSegmentOptions"),
    ("shapes/shape_context.h", "ShapeContextOptions", "ShapeContextOptions"),
    ("shapes/register.h", "RegistrationOptions", "RegistrationOptions"),
    ("city/synth_city.h", "CityOptions", "CityOptions"),
    ("geo/raster.h", "LasRasterOptions", "LasRasterOptions"),
    ("geo/raster.h", "DepthReadOptions", "DepthReadOptions"),
]
if (SRC / "shapes/edge_evidence.h").exists():
    AERIAL.append(("shapes/edge_evidence.h", "EdgeEvidenceOptions", "EdgeEvidenceOptions"))
if mvkp.HAS_AERIAL:
    BOUND += AERIAL


def literal(text):
    """The value of a C++ default initialiser, or NotImplemented when it is not a literal."""
    t = text.strip()
    if t in ("true", "false"):
        return t == "true"
    if t.startswith('"') and t.endswith('"'):
        return t[1:-1]
    m = re.fullmatch(r"(?:[\w:]+::)?(k\w+)", t)  # Enum::kName
    if m:
        return ("enum", m.group(1)[1:].lower())
    num = re.sub(r"(?<=[\d.])[fF]\b|(?<=\d)(?:LL|ULL|L|U|u|ll)\b", "", t).replace("'", "")
    if re.fullmatch(r"[\d.eE+\-*/<> ()]+", num):
        return eval(num, {})  # digits and operators only, e.g. 1.0 / 16, 1 << 30
    return NotImplemented


@pytest.mark.parametrize("header,struct,pyname", BOUND, ids=[b[1] for b in BOUND])
def test_fields_and_defaults(header, struct, pyname):
    fields = struct_fields(SRC / header, struct)
    assert fields, f"no fields parsed from {header}:{struct}"
    cls = getattr(mvkp, pyname)
    obj = cls()
    exposed = set(obj.to_dict())
    missing = [f.name for f in fields if f.name not in exposed]
    assert not missing, f"{struct} fields not bound in python/src: {missing}"
    extra = exposed - {f.name for f in fields}
    assert not extra, f"{pyname} exposes fields that are not in {struct}: {extra}"
    for f in fields:
        value = getattr(obj, f.name)
        if f.default is None or f.default == "{}":
            continue  # default-constructed member (nested options, std::function, models)
        want = literal(f.default)
        if want is NotImplemented:
            continue  # a call (e.g. RecognitionMatchDefaults()): covered by the object itself
        if isinstance(want, tuple):
            assert str(value) == want[1] and type(value)(want[1]) == value, f"{struct}.{f.name}: C++ default {f.default}, Python {value!r}"
        elif isinstance(want, float) or isinstance(value, float):
            assert value == pytest.approx(want, rel=1e-6), f"{struct}.{f.name}: C++ {f.default}, Python {value!r}"
        else:
            assert value == want, f"{struct}.{f.name}: C++ default {f.default}, Python {value!r}"


def test_kwargs_are_the_fields():
    # Functions take exactly the options' fields as keywords: any field works ...
    for name in mvkp.TrainOptions().to_dict():
        if name != "progress":
            mvkp.TrainOptions(**{name: getattr(mvkp.TrainOptions(), name)})
    # ... and values set by keyword are those the C++ struct receives.
    o = mvkp.MatchOptions(ratio=0.7, geometry="affine", index="brute")
    assert o.ratio == pytest.approx(0.7) and str(o.geometry) == "affine" and o.index == "brute"
    r = mvkp.RecognizerOptions(match={"max_points": 300}, search="words")
    assert r.match.max_points == 300 and str(r.search) == "words"
    assert mvkp.RecognizerOptions().match == mvkp.recognition_match_defaults()


def test_parser_sees_tricky_declarations():
    names = [f.name for f in struct_fields(SRC / "quality/quality.h", "QualityOptions")]
    assert {"w_detection", "w_stable", "w_coverage", "train", "match", "scene"} <= set(names)
    names = [f.name for f in struct_fields(SRC / "train/trainer.h", "TrainOptions")]
    assert "stats_views" in names and "progress" in names and "Check" not in names
