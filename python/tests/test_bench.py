"""bench_overhead.py runs (a smoke test: tiny sizes, no threshold; the figure is measured separately)."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest


@pytest.mark.skipif(not os.environ.get("MVKP_MATCH_BENCH"), reason="MVKP_MATCH_BENCH not set")
def test_bench_overhead_smoke():
    script = Path(__file__).resolve().parents[1] / "bench_overhead.py"
    out = subprocess.run([sys.executable, str(script), "--frames", "2", "--rounds", "1", "--blocks", "1"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout)
    assert r["cpp_ms_per_frame"] > 0 and r["python_ms_per_frame"] > 0 and r["found"] == 2
