"""Bad input raises clear Python exceptions (never a crash)."""
import numpy as np
import pytest

import mvkp


def test_image_dtype_shape_none(model):
    m = mvkp.Matcher(model)
    with pytest.raises(TypeError, match=r"got None"):
        m.match(None)
    with pytest.raises(ValueError, match=r"uint8.*\(H, W\).*float32"):
        m.match(np.zeros((100, 100), np.float32))
    with pytest.raises(ValueError, match=r"\(H, W\).*4-channel"):
        m.match(np.zeros((100, 100, 4), np.uint8))
    with pytest.raises(ValueError, match=r"expected a uint8 numpy array of shape \(H, W\)"):
        m.match(np.zeros((2, 100, 100, 3), np.uint8))
    with pytest.raises(ValueError, match="bool"):
        m.match(np.zeros((100, 100), bool))
    with pytest.raises(ValueError, match="empty"):
        m.match(np.zeros((0, 100), np.uint8))
    with pytest.raises(mvkp.BadImageError):  # too small for a patch
        m.match(np.zeros((8, 8), np.uint8))
    with pytest.raises(TypeError):
        mvkp.train(None)


def test_non_contiguous_is_converted(model, target):
    frame, H = mvkp.make_scene_view(target, 5)
    fortran = np.asfortranarray(frame)
    strided = np.repeat(frame, 2, axis=1)[:, ::2]  # every other column: not contiguous
    assert np.array_equal(strided, frame) and not strided.flags.c_contiguous
    m = mvkp.Matcher(model)
    a, b, c = m.match(frame), m.match(fortran), m.match(strided)
    assert a.found and b.found and c.found
    np.testing.assert_array_equal(a.homography, b.homography)
    np.testing.assert_array_equal(a.homography, c.homography)
    # (H, W, 1) is gray
    d = m.match(frame[:, :, None])
    np.testing.assert_array_equal(a.homography, d.homography)


def test_error_classes_and_messages(tmp_path):
    assert issubclass(mvkp.InvalidArgumentError, ValueError)
    assert issubclass(mvkp.BadImageError, ValueError)
    assert issubclass(mvkp.IoError, OSError)
    for cls in (mvkp.InvalidArgumentError, mvkp.IoError, mvkp.BadModelError, mvkp.NoTextureError, mvkp.BadIndexError):
        assert issubclass(cls, mvkp.Error) and issubclass(cls, RuntimeError)
    with pytest.raises(mvkp.IoError, match="missing.mvkp") as e:
        mvkp.Model.load(str(tmp_path / "missing.mvkp"))
    assert e.value.code == "io"
    with pytest.raises(mvkp.NoTextureError):
        mvkp.train(np.full((200, 200), 128, np.uint8))
    with pytest.raises(mvkp.InvalidArgumentError, match="views must be in 10..5000, got 3"):
        mvkp.train(np.zeros((64, 64), np.uint8), views=3)


def test_corrupt_model_file(model, tmp_path):
    p = tmp_path / "m.mvkp"
    model.save(str(p))
    data = bytearray(p.read_bytes())
    data[len(data) // 2] ^= 0xFF
    bad = tmp_path / "bad.mvkp"
    bad.write_bytes(bytes(data))
    with pytest.raises(mvkp.BadModelError, match="bad.mvkp") as e:
        mvkp.Model.load(str(bad))
    assert e.value.code == "bad_model"
    trunc = tmp_path / "trunc.mvkp"
    trunc.write_bytes(bytes(data[:100]))
    with pytest.raises(mvkp.BadModelError, match="trunc.mvkp"):
        mvkp.Model.load(str(trunc))
    with pytest.raises(mvkp.BadModelError):
        mvkp.Model.from_bytes(b"not a model")


def test_bad_options():
    with pytest.raises(TypeError, match=r"unexpected keyword argument 'viewz'.*views"):
        mvkp.train(np.zeros((64, 64), np.uint8), viewz=10)
    with pytest.raises(TypeError, match=r"option 'views' expects int"):
        mvkp.TrainOptions(views="many")
    with pytest.raises(ValueError, match=r"unknown GeometryModel 'perspectiv'"):
        mvkp.MatchOptions(geometry="perspectiv")
    with pytest.raises(mvkp.InvalidArgumentError, match="ratio"):
        mvkp.MatchOptions(ratio=1.5).check()
    with pytest.raises(TypeError, match="model is None"):
        mvkp.Matcher(None)
    with pytest.raises(TypeError, match=r"train\(\): options must be a TrainOptions or None, got MatchOptions"):
        mvkp.train(np.zeros((64, 64), np.uint8), options=mvkp.MatchOptions())


def test_options_and_keywords_combine(model):
    base = mvkp.MatchOptions(ratio=0.7)
    m = mvkp.Matcher(model, base, max_points=300)
    assert m.options.ratio == pytest.approx(0.7) and m.options.max_points == 300
    assert base.max_points == 1000  # the given options are copied, not modified


def test_closed_database(tmp_path, target):
    db = mvkp.Database.create(str(tmp_path / "t.db"))
    db.close()
    assert db.closed
    for call in (lambda: len(db), lambda: "x" in db, db.list, lambda: db.add("a", target), db.recognizer,
                 lambda: db.model("a")):
        with pytest.raises(ValueError, match="closed"):
            call()
    db.close()  # idempotent
    with pytest.raises(mvkp.IoError):
        mvkp.Database(str(tmp_path / "none.db"))
    with pytest.raises(mvkp.IoError):
        mvkp.Database.create(str(tmp_path / "t.db"))  # exists
    (tmp_path / "junk.db").write_bytes(b"junk" * 100)
    with pytest.raises(mvkp.Error):
        mvkp.Database(str(tmp_path / "junk.db"))
