"""The report's caveats: a cell from fewer than 3 seeds is marked, one seed shows no "± 0.00",
and a normalisation whose span is within the baselines' seed spread is flagged."""

from __future__ import annotations

from rrls.report.caveats import FEW, few_seeds, unstable_normalisation
from rrls.report.cells import pm as _pm
from rrls.report.cells import tex_pm as _tex_pm


def cell(mean, std, n):
    return {"mean": mean, "std": std, "n_seeds": n}


def test_cells_say_how_many_seeds_they_rest_on():
    assert _pm(cell(5.0, 0.0, 1)) == f"5.00{FEW}"  # one seed: its value, no "± 0.00"
    assert _pm(cell(5.0, 1.0, 2)) == f"5.00 ± 1.00{FEW}"
    assert _pm(cell(5.0, 1.0, 3)) == "5.00 ± 1.00"
    assert _tex_pm(cell(5.0, 0.0, 1)) == "$5.00^{\\dagger}$"
    assert _tex_pm(cell(5.0, 1.0, 2)) == "$5.00 \\pm 1.00^{\\dagger}$"
    assert _tex_pm(cell(5.0, 1.0, 10)) == "$5.00 \\pm 1.00$"
    assert few_seeds(cell(1, 0, 2)) and not few_seeds(cell(1, 0, 3)) and not few_seeds(None)


def test_a_normalisation_within_the_seed_spread_is_flagged():
    def summary(td3, m2td3):
        return {
            "tasks": ["hopper"],
            "results": {"hopper": {"td3": {"worst_case": td3}, "m2td3": {"worst_case": m2td3}}},
        }

    noisy = unstable_normalisation(summary(cell(50.0, 40.0, 3), cell(60.0, 30.0, 3)))
    assert len(noisy) == 1 and "hopper worst case" in noisy[0] and "10.0" in noisy[0]
    assert unstable_normalisation(summary(cell(50.0, 5.0, 3), cell(90.0, 8.0, 3))) == []
    # both baselines failed alike: a span of 0 is within any spread
    assert unstable_normalisation(summary(cell(10.0, 0.0, 3), cell(10.0, 0.0, 3)))
