"""SAC with domain randomisation: SAC (``rrls.agents.algos.sac``, Haarnoja et al. 2018) trained on
environments whose parameters are drawn uniformly from the uncertainty set at every episode
(``rrls.wrappers.DomainRandomization``), as DR is TD3 on them (Tobin et al. 2017).

Not "DR-SAC" (the distributionally robust SAC of Lemutisme/DR-SAC), a different method. The
learner is SAC's, unchanged; only the environment differs.
"""

from __future__ import annotations

from rrls.agents.algos.dr import make_env
from rrls.agents.algos.sac import Config, Learner

__all__ = ["Config", "Learner", "make_env"]
