"""NR-MDP and M2TD3 with every detail of their authors' code that rrls leaves off by default, as
plug-in learners for ``rrls benchmark --algos`` (the ablation that measures those details)."""

from __future__ import annotations

from dataclasses import dataclass

from rrls.agents import m2td3, nrmdp
from rrls.agents.hparams import hp
from rrls.algorithms import AlgorithmInfo, register_algorithm


@dataclass
class TesslerConfig(nrmdp.Config):
    """NR-MDP's table plus Tessler's ``ddpg.py`` defaults: pooled observation standardisation,
    Adam's L2 term 1e-2 on the critic."""

    normalize_obs: bool = hp(True, "Tessler's running observation standardisation")
    critic_weight_decay: float = hp(1e-2, "Adam's L2 term on the critic (Tessler's DDPG)")


class TesslerNRMDP(nrmdp.Learner):
    Config = TesslerConfig
    make_env = staticmethod(nrmdp.make_env)


@dataclass
class AuthorsConfig(m2td3.Config):
    """M2TD3's table plus its authors' trainer: unclipped exploration, one start state."""

    clip_exploration: bool = hp(False, "exploring actions stored and sent unclipped")
    same_start: bool = hp(True, "every episode reset with the run's first seed")


class AuthorsM2TD3(m2td3.Learner):
    Config = AuthorsConfig
    make_env = staticmethod(m2td3.make_env)


def _m2td3_options(spec) -> dict:
    return {"normalize_omega": spec.normalize_omega}


#: the rows ``rrls benchmark`` reads (display name, adversary, warm-up), by the built-in they vary
VARIANTS = {
    "nrmdp": AlgorithmInfo(
        "nrmdp-tessler", "NR-MDP (Tessler's code)", f"{__name__}:TesslerNRMDP", adversary=True
    ),
    "m2td3": AlgorithmInfo(
        "m2td3-authors",
        "M2TD3 (authors' code)",
        f"{__name__}:AuthorsM2TD3",
        set_use="chosen",
        learning_starts=100_000,
        options=_m2td3_options,
    ),
}


def register() -> None:
    """Add the rows to ``rrls.algorithms.ALGORITHMS`` (in the benchmark's driver, and in each of
    its spawned processes, which import the driver's script again)."""
    for info in VARIANTS.values():
        register_algorithm(info)
