"""Train on a sample image, find it in generated views with known homographies."""
import numpy as np
import pytest

import mvkp


def corner_errors(outline, H_true, w, h):
    truth = mvkp.project_outline(H_true, w, h)
    return np.linalg.norm(outline - truth, axis=1)


def test_model_basics(model, target):
    h, w = target.shape
    assert model.size == (w, h)
    assert model.descriptors.dtype == np.float32
    assert model.descriptors.shape == (len(model.labels), model.params.dims)
    assert model.locations.shape[1] == 2
    assert "Model(" in repr(model)


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5, 6])
def test_found_within_5px(model, target, seed):
    frame, H = mvkp.make_scene_view(target, seed)
    assert frame.dtype == np.uint8 and frame.shape == (480, 640)
    assert H.shape == (3, 3) and H.dtype == np.float64
    r = mvkp.Matcher(model).match(frame)
    assert r.found, r
    h, w = target.shape
    err = corner_errors(r.outline, H, w, h)
    assert err.max() < 5.0, (seed, err)
    assert mvkp.mean_corner_error(r.homography, H, w, h) < 5.0
    assert r.matches.shape == (len(r.inlier_mask), 4) and r.matches.dtype == np.float32
    assert r.inlier_mask.sum() >= r.inliers > 0
    assert r.time_ms["total"] > 0
    assert "found=True" in repr(r)


def test_bgr_frame_and_options(model, target_bgr):
    frame, H = mvkp.make_scene_view(target_bgr, 11)
    assert frame.shape == (480, 640, 3)
    r = mvkp.match(model, frame, geometry="homography", ratio=0.85, max_points=500)
    assert r.found
    h, w = target_bgr.shape[:2]
    assert corner_errors(r.outline, H, w, h).max() < 5.0


def test_not_found_in_noise(model, rng):
    noise = rng.integers(0, 256, size=(480, 640), dtype=np.uint8)
    r = mvkp.Matcher(model).match(noise)
    assert not r.found and r.homography is None and r.outline is None
    assert not r


def test_save_load_roundtrip(model, target, tmp_path):
    p = tmp_path / "t.mvkp"
    model.save(str(p))
    m2 = mvkp.Model.load(str(p))
    assert np.array_equal(m2.descriptors, model.descriptors)
    assert np.array_equal(m2.labels, model.labels)
    m3 = mvkp.Model.from_bytes(model.to_bytes())
    assert np.array_equal(m3.locations, model.locations)
    frame, H = mvkp.make_scene_view(target, 3)
    assert mvkp.Matcher(m2).match(frame).found


def test_pair_mvkp_and_cdikp(target):
    frame, H = mvkp.make_scene_view(target, 2)
    h, w = target.shape
    r = mvkp.pair(target, frame, seed=42, ratio=0.85)
    assert r.found and r.method == "mvkp"
    assert mvkp.mean_corner_error(r.homography, H, w, h) < 5.0
    r2 = mvkp.pair(target, frame, method="cdikp", ratio=0.8)
    assert r2.method == "cdikp" and r2.keypoints1 > 0 and r2.keypoints2 > 0
    assert r2.matches.shape[1] == 4
    assert "cdikp" in mvkp.pair_methods()


def test_train_progress_callback(target):
    calls = []
    mvkp.train(target, views=20, camera_views=10, levels=2, locations=50, progress=lambda d, t: calls.append((d, t)))
    # Over both pyramid levels: 20 affine + 10 camera views each.
    assert calls and calls[-1] == (60, 60)
    assert all(t == 60 for _, t in calls) and [d for d, _ in calls] == sorted(d for d, _ in calls)


def test_cdikp_and_augment(target):
    c = mvkp.Cdikp(dims=20)
    kp, desc = c.detect_and_compute(target)
    assert kp.shape[1] == 7 and desc.shape == (len(kp), 20) and desc.dtype == np.float32
    assert np.allclose(np.linalg.norm(desc, axis=1), 1.0, atol=1e-3)
    kp2, desc2 = c.compute(target, kp[:10])
    assert np.allclose(desc2, desc[:10], atol=1e-5)
    codes = mvkp.augment(kp, desc, k=5)
    assert codes.shape == desc.shape and codes.dtype == np.uint8
    assert (np.sort(codes, axis=1) == np.arange(1, 21, dtype=np.uint8)).all()  # permutations of 1..dim
    pairs, dist = mvkp.match_codes(codes, codes, "spearman", 0.9)
    assert pairs.shape[1] == 2 and len(dist) == len(pairs)
    assert mvkp.code_similarity(codes[0], codes[0]) == pytest.approx(1.0)


def test_recognizer(model, target):
    rec = mvkp.Recognizer()
    rec.add("starry", model)
    assert "starry" in rec and len(rec) == 1
    frame, H = mvkp.make_scene_view(target, 4)
    res = rec.recognize(frame)
    assert res.ids == ["starry"], res
    h, w = target.shape
    assert mvkp.mean_corner_error(res.found[0].homography, H, w, h) < 5.0
    assert rec.recognize_one(frame, "starry").ids == ["starry"]
    assert rec.remove("starry") and len(rec) == 0
