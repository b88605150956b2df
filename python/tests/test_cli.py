"""python3 -m mvkp forwards to the command-line tool."""
import os
import subprocess
import sys

import pytest


def run(*args):
    return subprocess.run([sys.executable, "-m", "mvkp", *args], capture_output=True, text=True, timeout=60)


@pytest.mark.skipif(not os.environ.get("MVKP_CLI") and not __import__("shutil").which("mvkp"),
                    reason="no mvkp CLI (set MVKP_CLI)")
def test_help_and_exit_codes(tmp_path):
    r = run("--help")
    assert r.returncode == 0, r.stderr
    assert "train" in r.stdout and "match" in r.stdout
    r = run("no-such-command")
    assert r.returncode == 2 and "unknown command" in r.stderr
    r = run("match", str(tmp_path / "missing.mvkp"), str(tmp_path / "missing.png"))
    assert r.returncode == 1


def test_missing_cli(tmp_path):
    env = dict(os.environ, MVKP_CLI=str(tmp_path / "nope"))
    r = subprocess.run([sys.executable, "-m", "mvkp", "--help"], capture_output=True, text=True, env=env, timeout=60)
    assert r.returncode != 0 and "nope" in r.stderr


@pytest.mark.skipif(not os.environ.get("MVKP_CLI"), reason="MVKP_CLI not set")
def test_python_match_equals_cli(model, target, tmp_path):
    import json

    import numpy as np

    import mvkp

    model.save(str(tmp_path / "t.mvkp"))
    frame, _ = mvkp.make_scene_view(target, 3)
    mvkp.save_image(str(tmp_path / "f.png"), frame)
    out = subprocess.run([os.environ["MVKP_CLI"], "match", str(tmp_path / "t.mvkp"), str(tmp_path / "f.png"), "--json"],
                         capture_output=True, text=True, timeout=60, check=True)
    j = json.loads(out.stdout)
    r = mvkp.Matcher(mvkp.Model.load(str(tmp_path / "t.mvkp"))).match(mvkp.load_image(str(tmp_path / "f.png")))
    assert j["found"] and r.found and j["inliers"] == r.inliers and j["matches"] == len(r.matches)
    np.testing.assert_allclose(np.array(j["homography"]), r.homography, rtol=1e-12, atol=1e-9)
