"""Aerial registration on a small synthetic city (bindings, not accuracy: see the C++ tests)."""
import numpy as np
import pytest

import mvkp

pytestmark = pytest.mark.skipif(not mvkp.HAS_AERIAL, reason="built without the aerial components")


@pytest.fixture(scope="module")
def city():
    # A scene `mvkp register` registers (1.3 px) as the aerial code stands; the
    # test accepts "no registration found" too: it tests the binding, not the method.
    return mvkp.make_city(6, width=500, height=500, buildings=20, min_scale=0.7, max_scale=1.4,
                          max_perspective=0.0, photo_max_side=800)


def test_city(city):
    assert city.depth.dtype == np.float32 and city.depth.shape == (500, 500)
    assert city.photo.dtype == np.uint8 and city.photo.ndim == 3
    assert city.photo_to_depth.shape == (3, 3)
    assert len(city.footprints) > 0 and "City(" in repr(city)


def test_segment_and_register(city):
    depth_regions = mvkp.segment_depth(city.depth)
    assert depth_regions and depth_regions[0].contour.shape[1] == 2
    photo_regions = mvkp.segment_optical(city.photo)
    assert isinstance(photo_regions, list)
    r = mvkp.register_contours(photo_regions, depth_regions, seed=1)
    assert isinstance(r.ok, bool) and isinstance(r.reason, str)
    r2 = mvkp.register_aerial(city.depth, city.photo, model="auto")
    assert r2.time_ms["total"] > 0 and len(r2.depth_regions) == len(depth_regions)
    if r2.ok:
        h, w = city.photo.shape[:2]
        assert r2.homography.shape == (3, 3)
        assert mvkp.mean_corner_error(r2.homography, city.photo_to_depth, w, h) < 5.0
        assert r2.correspondences.shape[1] == 4 and r2.region_matches
        assert 0.0 <= r2.ambiguity_px <= 5.0  # the answer is determined to the default 5 px
        assert r2.relocated_px >= 0.0
        e = r2.edge  # the image check of the answer: edges, and the roofs' colours
        assert e["contrast"] > 0 and e["regions_on_edges"] <= e["regions"]
        assert e["roof_regions"] >= 0 and (e["roof_contrast"] is None) == (e["roof_regions"] == 0)
    else:
        assert r2.homography is None and r2.reason.startswith("no registration found")
        assert r2.lean_depth_px_per_m is None


def test_register_aerial_method_and_confidence():
    # issue 21: a small tile with 4 buildings (synth-city --buildings 4 --width 200 --height 200 --seed 1,
    # scene 6), which the outline search registers; the answer says which method gave it
    c = mvkp.make_city(1000009, width=200, height=200, buildings=4)
    r = mvkp.register_aerial(c.depth, c.photo, method="outlines")
    assert r.ok, r.reason
    assert r.method == "outlines" and 0.5 <= r.confidence <= 1.0
    h, w = c.photo.shape[:2]
    assert mvkp.mean_corner_error(r.homography, c.photo_to_depth, w, h) < 5.0
    assert r.time_ms["outline_search"] > 0
    lean = r.lean_depth_px_per_m  # estimated only with >= 6 outlines of several heights: none here
    assert len(lean) == 2 and all(np.isfinite(lean))
    r2 = mvkp.register_aerial(c.depth, c.photo, method="regions")
    assert r2.method in (None, "regions") and (r2.ok or r2.confidence == 0.0)
    with pytest.raises(ValueError, match="method"):
        mvkp.register_aerial(c.depth, c.photo, method="fourier")


def test_register_aerial_coarse_photo_upscaled():
    # issue 21: coarse photos (2-3 depth px per photo px) are also segmented upscaled; the C++ test
    # Aerial.CoarsePhotosAreSegmentedUpscaled checks the method, this the binding: over the scenes of
    # `synth-city --style suburb --width 600 --height 600 --buildings 40 --min-scale 2 --max-scale 3
    # --seed 77` (2 and 5 answer upscaled with GCC; counted, another compiler draws other scenes)
    upscaled = 0
    for i in range(6):
        c = mvkp.make_city(77 * 1000003 + i, width=600, height=600, buildings=40, min_scale=2.0, max_scale=3.0,
                           style="suburb")
        r = mvkp.register_aerial(c.depth, c.photo, method="regions")
        if r.ok:
            h, w = c.photo.shape[:2]
            assert mvkp.mean_corner_error(r.homography, c.photo_to_depth, w, h) < 5.0
        if r.photo_segmentation_upscale > 1:
            upscaled += 1
            assert r.ok
            off = mvkp.register_aerial(c.depth, c.photo, method="regions", photo_min_side=0)
            assert off.photo_segmentation_upscale == 1 and not off.ok
        else:
            assert r.photo_segmentation_upscale == 1
    assert upscaled >= 1
    with pytest.raises(ValueError, match="photo_min_side"):
        mvkp.register_aerial(c.depth, c.photo, photo_min_side=-1)


def test_shadow_compensation(city):
    # relit first: opt-in; the fallback (a second pass on the photo relit
    # when the photo as it is gives nothing): on by default. make_city's
    # photo has cast shadows (a random sun): relit first, its step is found
    # and part of it relit
    off = mvkp.register_aerial(city.depth, city.photo, shadow_fallback=False)
    assert set(off.shadows) == {"applied", "log_step_bgr", "fraction", "votes", "fallback_answer"}
    assert not off.shadows["applied"] and off.shadows["log_step_bgr"] is None and off.shadows["fraction"] == 0
    assert not off.shadows["fallback_answer"]
    s = mvkp.register_aerial(city.depth, city.photo, shadow_compensation=True).shadows
    assert s["applied"] and s["votes"] >= 40 and not s["fallback_answer"]
    b, g, red = s["log_step_bgr"]
    assert red <= g + 0.02 and g <= b + 0.02 and b < 0  # blue drops least
    assert 0 < s["fraction"] < 0.4
    d = mvkp.register_aerial(city.depth, city.photo)
    if off.ok:  # the first pass answered: no second pass
        assert d.ok and not d.shadows["fallback_answer"]


def test_aerial_bad_input(city):
    with pytest.raises(ValueError, match="float32"):
        mvkp.segment_depth(city.photo)
    with pytest.raises(TypeError):
        mvkp.register_aerial(None, city.photo)
    with pytest.raises(ValueError, match="4-channel"):
        mvkp.register_aerial(city.depth, np.zeros((50, 50, 4), np.uint8))
    with pytest.raises(ValueError, match="unknown Model"):
        mvkp.register_aerial(city.depth, city.photo, model="projective")
    with pytest.raises(ValueError, match="relocate_cells"):
        mvkp.register_aerial(city.depth, city.photo, edge_options=mvkp.EdgeEvidenceOptions(relocate_cells=1))
    with pytest.raises(ValueError, match="relocate_lean_gain"):
        mvkp.register_aerial(city.depth, city.photo, edge_options=mvkp.EdgeEvidenceOptions(relocate_lean_gain=-0.1))
    with pytest.raises(ValueError, match="relocate_rms_free_gain"):
        mvkp.register_aerial(city.depth, city.photo, relocate_rms_free_gain=-0.1)
    with pytest.raises(ValueError, match="lean_min_roof_ratio"):
        mvkp.register_aerial(city.depth, city.photo, lean_min_roof_ratio=-0.5)


@pytest.mark.skipif(not __import__("os").environ.get("MVKP_CLI"), reason="MVKP_CLI not set")
def test_register_aerial_equals_cli(city, tmp_path):
    import json
    import os
    import subprocess

    city.save(str(tmp_path))
    depth, res_m = mvkp.read_depth(str(tmp_path / "depth.tif"))
    photo = mvkp.read_optical(str(tmp_path / "photo.png"))
    r = mvkp.register_aerial(depth, photo)
    out = subprocess.run([os.environ["MVKP_CLI"], "register", str(tmp_path / "depth.tif"), str(tmp_path / "photo.png"),
                          "--json"], capture_output=True, text=True, timeout=120, check=True)
    j = json.loads(out.stdout)
    assert j["ok"] == r.ok and j["reason"] == r.reason
    if r.ok:
        assert j["model"] == r.model and j["relocated_px"] == pytest.approx(r.relocated_px)
        np.testing.assert_allclose(np.array(j["homography"]), r.homography, rtol=1e-9, atol=1e-9)


@pytest.mark.skipif(not __import__("os").environ.get("MVKP_CLI"), reason="MVKP_CLI not set")
def test_view_registrar_equals_cli(tmp_path):
    """Stage 2 (issue 22): ViewRegistrar gives the cameras `mvkp register-all` gives, right on the check points."""
    import json
    import os
    import subprocess

    cli = os.environ["MVKP_CLI"]
    subprocess.run([cli, "synth-oblique", "-o", str(tmp_path), "--n", "1", "--views", "2", "--seed", "2", "--style",
                    "dense", "--tilt", "35", "50", "--gsd", "0.25", "0.4"], check=True, capture_output=True, timeout=120)
    d = tmp_path / "city_0000"
    t = json.load(open(d / "truth.json"))
    lean = [x / t["res_m"] for x in t["lean_m_per_m"]]
    json.dump({"homography": t["photo_to_depth"], "lean_depth_px_per_m": lean}, open(d / "stage1.json", "w"))
    depth, _ = mvkp.read_depth(str(d / "depth.tif"))
    nadir = mvkp.read_optical(str(d / "photo.png"))
    reg = mvkp.ViewRegistrar(depth, nadir, np.array(t["photo_to_depth"]), res_m=t["res_m"], lean=tuple(lean))
    assert reg.tiles >= 4 and reg.train_ms > 0 and "ViewRegistrar(" in repr(reg)
    views = [str(d / ("oblique_%02d.png" % k)) for k in range(2)]
    out = subprocess.run([cli, "register-all", str(d / "depth.tif"), str(d / "photo.png")] + views +
                         ["--stage1", str(d / "stage1.json"), "--res", str(t["res_m"]), "--json"],
                         capture_output=True, text=True, timeout=240, check=True)
    cli_views = json.loads(out.stdout)["views"]
    answered = 0
    for k, path in enumerate(views):
        r = reg.register(mvkp.read_optical(path), hfov=50.0)
        assert r["ok"] == cli_views[k]["ok"], (r["reason"], cli_views[k]["reason"])
        assert r["matches"].shape == (len(r["inlier"]), 4) and r["inlier"].sum() == r["inliers"]
        if not r["ok"]:
            assert r["camera"] is None and r["reason"].startswith("no registration")
            continue
        answered += 1
        np.testing.assert_allclose(r["camera"], np.array(cli_views[k]["camera"]), rtol=1e-9, atol=1e-6)
        v = json.load(open(d / ("oblique_%02d.json" % k)))
        X = np.array([c["world_m"] + [1] for c in v["check_points"]]) @ r["camera"].T
        err = np.linalg.norm(X[:, :2] / X[:, 2:] - np.array([c["oblique_px"] for c in v["check_points"]]), axis=1)
        assert err.mean() <= 5, err.mean()
        g = r["refinement"]
        assert g["refined"] == cli_views[k]["refinement"]["refined"]
        if g["refined"]:  # refitted on correlation matches all over the view: sub-pixel
            assert g["inliers"] >= 30 and err.mean() <= 1.0, (g, err.mean())
        ol, cli_ol = r["outline_refinement"], cli_views[k]["outline_refinement"]
        assert (ol["ran"], ol["replaced"], ol["pairs"], ol["first_pairs"]) == \
            (cli_ol["ran"], cli_ol["replaced"], cli_ol["pairs"], cli_ol["first_pairs"])
        assert ol["pairs"] <= ol["visible"] and (not ol["replaced"] or ol["move_px"] > 1.5)
    assert answered >= 1
    # the same stage 1 again: the same cameras (the tiles are kept)
    reg.restage(np.array(t["photo_to_depth"]), lean=tuple(lean))
    again = reg.register(mvkp.read_optical(views[0]), hfov=50.0)
    assert again["ok"] == cli_views[0]["ok"]
    if again["ok"]:
        np.testing.assert_allclose(again["camera"], np.array(cli_views[0]["camera"]), rtol=1e-9, atol=1e-6)
    with pytest.raises(mvkp.InvalidArgumentError):
        reg.restage(np.zeros((3, 3)))  # singular
    with pytest.raises(ValueError):
        mvkp.ViewRegistrar(depth, nadir, np.eye(3), res_m=0)
    with pytest.raises(ValueError):
        mvkp.ViewRegistrar(depth, nadir, np.eye(2), res_m=0.5)
    with pytest.raises(mvkp.InvalidArgumentError):
        mvkp.ViewRegistrar(depth, nadir, np.eye(3), res_m=0.5, tile_px=10)
    with pytest.raises(ValueError):
        mvkp.ViewRegistrar(depth, nadir, np.eye(3), res_m=0.5, method="sift")
    # method 2, feature fusion: the same answers as register-all --method fusion, right or none
    fus = mvkp.ViewRegistrar(depth, nadir, np.array(t["photo_to_depth"]), res_m=t["res_m"], lean=tuple(lean),
                             method="fusion")
    assert fus.tiles == 0  # no MVKP training
    out = subprocess.run([cli, "register-all", str(d / "depth.tif"), str(d / "photo.png")] + views +
                         ["--stage1", str(d / "stage1.json"), "--res", str(t["res_m"]), "--json", "--method", "fusion",
                          "--no-correct-stage1"], capture_output=True, text=True, timeout=240, check=True)
    for k, (path, cv_) in enumerate(zip(views, json.loads(out.stdout)["views"])):
        r = fus.register(mvkp.read_optical(path), hfov=50.0)
        assert r["method"] == "fusion" and r["fusion"] is not None and cv_["requested_method"] == "fusion"
        assert r["ok"] == cv_["ok"], (r["reason"], cv_["reason"])
        if r["ok"]:
            np.testing.assert_allclose(r["camera"], np.array(cv_["camera"]), rtol=1e-9, atol=1e-6)
            v = json.load(open(d / ("oblique_%02d.json" % k)))
            X = np.array([c["world_m"] + [1] for c in v["check_points"]]) @ r["camera"].T
            err = np.linalg.norm(X[:, :2] / X[:, 2:] - np.array([c["oblique_px"] for c in v["check_points"]]), axis=1)
            assert err.mean() <= 5, err.mean()


def test_cast_shadow_fallback(city):
    # the shadows the depth casts at a refused candidate pose, relit when a
    # sun stands out there (on by default; runs only when the photo as it is
    # gives no registration)
    keys = {"found", "applied", "fallback_answer", "reason", "azimuth_deg", "length_depth_px_per_m", "contrast",
            "margin", "log_step_bgr", "fraction"}
    off = mvkp.register_aerial(city.depth, city.photo, cast_shadow_fallback=False)
    assert set(off.cast_shadows) == keys
    assert not off.cast_shadows["found"] and not off.cast_shadows["applied"]
    assert not off.cast_shadows["fallback_answer"]
    d = mvkp.register_aerial(city.depth, city.photo)
    assert set(d.cast_shadows) == keys
    if off.ok:  # the first pass answered: no later pass ran
        assert d.ok and not d.cast_shadows["found"] and not d.cast_shadows["fallback_answer"]
    if d.cast_shadows["fallback_answer"]:
        assert d.ok and d.cast_shadows["applied"] and d.method != "outlines"
        assert all(s < 0 for s in d.cast_shadows["log_step_bgr"])
    if d.cast_shadows["applied"]:
        assert d.cast_shadows["found"] and 0 <= d.cast_shadows["azimuth_deg"] < 360
        assert d.cast_shadows["margin"] >= 0.15 and 0 < d.cast_shadows["fraction"] < 0.5


def test_cast_shadow_confirmation(city):
    # the pose the depth's cast shadows single out answers when its outlines
    # and roofs pass the checks on the relit photo (method "cast-shadows");
    # 0 turns it off, a negative margin is refused
    off = mvkp.register_aerial(city.depth, city.photo, cast_shadow_confirm_margin=0.0)
    assert off.method != "cast-shadows"
    d = mvkp.register_aerial(city.depth, city.photo)
    if d.method == "cast-shadows":
        assert d.ok and d.cast_shadows["fallback_answer"] and d.cast_shadows["margin"] >= 0.3
        assert 0 < d.confidence <= 1
    with pytest.raises(Exception):
        mvkp.register_aerial(city.depth, city.photo, cast_shadow_confirm_margin=-1.0)


def test_outline_roof_veto(city):
    # an outline-search answer needs its roofs set apart whatever its edges;
    # 0 gives the region routes' rule, a negative count is refused
    d = mvkp.register_aerial(city.depth, city.photo, method="outlines")
    e = mvkp.register_aerial(city.depth, city.photo, method="outlines", outline_roof_veto_regions=0)
    if d.ok:
        assert e.ok
    with pytest.raises(Exception):
        mvkp.register_aerial(city.depth, city.photo, outline_roof_veto_regions=-1)


def test_outline_objects_and_completeness(city):
    # the outline search's trees and hedges, and its completeness weight, can
    # be turned off; out-of-range values are refused
    d = mvkp.register_aerial(city.depth, city.photo, method="outlines")
    bare = mvkp.register_aerial(city.depth, city.photo, method="outlines", outline_objects=False,
                                outline_completeness=0.0)
    for r in (d, bare):
        assert r.method in ("outlines", "") or not r.ok
        if r.ok:
            assert r.confidence >= 0.5
    with pytest.raises(Exception):
        mvkp.register_aerial(city.depth, city.photo, outline_completeness=-1.0)
    with pytest.raises(Exception):
        mvkp.register_aerial(city.depth, city.photo, outline_completeness=5.0)


def test_outline_search_refuses_outlines_partly_on_other_ground():
    # issue 21/22: the nadir photo of another suburb (synth-oblique seed 117, city 1) was registered onto
    # city 0's depth by the outline search: 6 of 10 outlines on edges, confidence 0.51, but only 0.58 of
    # the outlines' arcs in view on edges (right answers: 0.84 or more, 72 of them over seven seed sets).
    depth = mvkp.make_city(117000351, style="suburb").depth
    other = mvkp.make_city(117000352, style="suburb").photo
    r = mvkp.register_aerial(depth, other)
    assert not r.ok, r.reason
    assert "arcs in view on edges (0.80 needed)" in r.reason, r.reason
    # without the floor the same pose is accepted: the floor is what refuses it
    r0 = mvkp.register_aerial(depth, other, outline_min_completeness=0.0)
    assert r0.ok and r0.method == "outlines", r0.reason


def test_outline_search_reports_a_pose_refined_out_of_view():
    # issue 21: the image check's refinement can leave just under the outline search's overlap floor
    # in view (seed 138's suburb 37, the refined pose's samples 0.23 in the photo against a floor of
    # 0.25). No answer, as before, but the reason says why and the score is the pose's, not -1e18.
    c = mvkp.make_city(138000451, style="suburb")
    r = mvkp.register_aerial(c.depth, c.photo, method="outlines")
    assert not r.ok
    assert "e+18" not in r.reason and "1000000000000000000" not in r.reason
    assert "of its outline samples fall in the photo" in r.reason, r.reason
    assert "confidence 0.00" in r.reason
    score = float(r.reason.split("score ")[1].split(",")[0])
    assert 0 < score < 1e6
