"""docs/protocol.md's wall-time figures are the estimates the code prints: the CPU table per
cluster size, and the one-GPU estimate from rrls's own H100 measurement (what the dry run with
``--device cuda`` prints, not the CPU figure)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rrls.benchmark.cpu_estimate import estimate, format_duration
from rrls.benchmark.gpu_estimate import GPU_RECORD, gpu_estimate
from rrls.benchmark.grid import make_spec

PAGE = (Path(__file__).resolve().parent.parent / "docs" / "protocol.md").read_text()


def test_the_cpu_table_is_the_estimate():
    spec = make_spec("paper")
    for cores, label in ((16, "16 (one machine)"), (64, "64"), (128, "128")):
        assert f"| {label} | ≈ {format_duration(estimate(spec, cores)['wall_s'])} |" in PAGE


def test_the_gpu_estimate_is_rrls_own_measurement_and_the_dry_run_prints_it(tmp_path, capsys):
    from rrls.cli import main

    spec = make_spec("paper", device="cuda")
    est = gpu_estimate(spec, len(spec.seeds))
    assert not est["measured"]  # K = 10 and DR/RARL/NR-MDP are extrapolated: the page says so
    assert (
        f"**≈ {format_duration(est['wall_s'])}** (training {format_duration(est['train_s'])}"
        in PAGE
    )
    assert f"against ≈ {format_duration(estimate(make_spec('paper'), 16)['wall_s'])} for" in PAGE
    assert (Path(__file__).resolve().parent.parent / GPU_RECORD).is_file()
    args = ["benchmark", "--out", str(tmp_path / "b"), "--dry-run", "--device", "cuda"]
    assert main(args) == 0
    out = capsys.readouterr()
    text = out.out + out.err
    assert f"estimate on one GPU (rrls's own H100 figures, {GPU_RECORD}" in text
    assert format_duration(est["wall_s"]) in text and "of compute (training" not in text


def test_an_algorithm_without_gpu_figures_is_td3s_scaled_by_its_cpu_rate():
    # RARL updates two players every step: on a CPU it trains at half TD3's rate, and the GPU
    # estimate, which has no RARL figure, counts that rather than taking TD3's rate as it is
    from rrls.algorithms import ALGORITHMS, TD3_CPU, TD3_GPU
    from rrls.benchmark.gpu_estimate import stored_rate

    td3 = dict(TD3_GPU)
    for k in td3:
        assert stored_rate("td3", k) == (td3[k], True)
        assert stored_rate("dr", k) == (td3[k], False)  # DR trains TD3's learner
        rarl, measured = stored_rate("rarl", k)
        assert not measured
        assert rarl == pytest.approx(td3[k] * ALGORITHMS["rarl"].cpu_steps_per_s / TD3_CPU)
        assert rarl < 0.6 * td3[k]
    assert stored_rate("m2td3", 8) == (1_172.0, True)  # measured figures are used as they are


def test_the_throughput_table_states_the_estimates_constants():
    # "94 / 103 / 57" (TD3, M2TD3, SAC) and RARL's and NR-MDP's "46 and 84", which are TD3's
    # times the ratios measured side by side ("73 / 76 / 36 / 65 / 85": TD3, DR, RARL, NR-MDP,
    # M2TD3)
    from rrls.algorithms import ALGORITHMS, SAC_CPU, TD3_CPU

    rate = {a: ALGORITHMS[a].cpu_steps_per_s for a in ALGORITHMS}
    assert f"| {TD3_CPU:.0f} / {rate['m2td3']:.0f} / {SAC_CPU:.0f} (" in PAGE
    assert f"(their constants: {rate['rarl']:.0f} and {rate['nrmdp']:.0f})" in PAGE
    side_by_side = dict(zip(("td3", "dr", "rarl", "nrmdp", "m2td3"), (73, 76, 36, 65, 85)))
    assert " / ".join(map(str, side_by_side.values())) + ": RARL and NR-MDP" in PAGE
    for algo in ("rarl", "nrmdp"):
        ratio = side_by_side[algo] / side_by_side["td3"]
        assert rate[algo] == round(TD3_CPU * ratio)
        assert f"{ratio:.2f}×" in PAGE
