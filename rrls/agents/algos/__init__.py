"""The algorithms, one file each, read top to bottom: its paper reference, its hyper-parameters
(``Config``, the paper's values) and its ``Learner``, on the shared infrastructure of
``rrls.agents`` (networks, replay, updates, the training driver). ``td3``, ``dr``, ``rarl``,
``nrmdp``, ``m2td3`` (the paper's five), ``sac``, ``sacdr``; ``rrls.algorithms`` is their table."""

__all__: list[str] = []
