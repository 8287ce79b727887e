"""The GPU records state only what their logs show: each figure quoted in a record's prose is
read back from the logs shipped beside it (or from the earlier record it cites)."""

from __future__ import annotations

import re
from pathlib import Path

GPU = Path(__file__).resolve().parents[1] / "docs" / "results" / "gpu"


def test_the_third_lease_quotes_its_logs():
    page = " ".join((GPU / "h100-2026-11-28.md").read_text().split())
    log = (GPU / "h100-2026-11-28" / "tests.log").read_text()
    passed, seconds = re.search(r"(\d+) passed, \d+ deselected, .* in ([\d.]+)s", log).groups()
    assert f"**{passed} passed in {float(seconds):.0f} s**" in page
    assert f"CUDA tests: {passed} / {passed} pass" in page
    assert " failed" not in log
    book = (GPU / "h100-2026-11-28" / "runbook.md").read_text()
    tests_wall = int(re.search(r"CUDA tests: ok in (\d+) s", book).group(1))
    limit = int(re.search(r"`timeout (\d+) python3 benchmarks/gpu_runbook.py", page).group(1))
    assert f"stopped by that `timeout` {limit - tests_wall} s after it started" in page
    assert "GPU speed table" not in book  # it never finished: no row is claimed
    first = (GPU / "h100-2026-11-25.md").read_text()
    per_run = int(re.search(r"\| cuda \| td3 \| 8 \| [\d ]+ \| (\d+) \|", first).group(1))
    assert f"({per_run} env steps/s per run" in page
    assert f"300 000 steps take about {300_000 / per_run / 60:.0f} minutes" in page
