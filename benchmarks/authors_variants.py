"""NR-MDP and M2TD3 with every detail of their authors' code that rrls leaves off by default, as
plug-in learners for ``rrls benchmark --algos`` (the ablation that measures those details)."""

from __future__ import annotations

from dataclasses import dataclass, replace

from rrls.agents.algos import m2td3, nrmdp
from rrls.agents.hparams import hp
from rrls.algorithms import ALGORITHMS, AlgorithmInfo, register_algorithm


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


def _renamed(algo: str, name: str, display: str, learner: type) -> AlgorithmInfo:
    """The built-in row ``algo`` (set use, adversary, warm-up, benchmark options) under another
    name, display and learner: nothing else can drift from the built-in."""
    learner_path = f"{__name__}:{learner.__name__}"
    return replace(ALGORITHMS[algo], name=name, display=display, learner=learner_path, paper=False)


#: the rows ``rrls benchmark`` reads, by the built-in they vary
VARIANTS = {
    "nrmdp": _renamed("nrmdp", "nrmdp-tessler", "NR-MDP (Tessler's code)", TesslerNRMDP),
    "m2td3": _renamed("m2td3", "m2td3-authors", "M2TD3 (authors' code)", AuthorsM2TD3),
}


def register() -> None:
    """Add the rows to ``rrls.algorithms.ALGORITHMS`` (in the benchmark's driver, and in each of
    its spawned processes, which import the driver's script again)."""
    for info in VARIANTS.values():
        register_algorithm(info)
