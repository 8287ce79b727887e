"""The table of algorithms: every name the CLI, the benchmark spec, the pipeline, the report and
``rrls submit`` know, declared once (torch-free: the report and the spec read it without
importing training code).

A row says what the rest of rrls needs to know about an algorithm without loading it: its
display name, whether it is one of the paper's five baselines, whether it trains an adversary
(then the benchmark also plays it against its own adversary: the dynamic evaluation), how it
meets the uncertainty set (which decides where it can train: the Warp twin), the benchmark
options its ``Config`` takes and the learning rates ``--learning-rate`` sets, whether its mean
anchors the paper's normalised score (TD3's 0, M2TD3's 1: ``normalisers``), its measured
training speeds (the benchmark's estimates), and where its ``Learner`` lives. Nothing else in
rrls names an algorithm.
``rrls.agents.algorithm(name)`` loads it. Plug-ins add rows with ``register_algorithm`` (an
installed entry point of group ``rrls.algorithms`` is found without a row; it then reads as its
own name).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "ALGORITHMS",
    "ANCHORS",
    "ENTRY_POINTS",
    "SET_USES",
    "TD3_CPU",
    "TD3_GPU",
    "AlgorithmInfo",
    "algorithm_info",
    "algorithm_key",
    "built_in",
    "display_name",
    "normalisers",
    "paper_five",
    "plays_adversary",
    "plugin_entry_points",
    "register_algorithm",
    "sort_algos",
    "warmup",
]

#: the entry point group of installed learner plug-ins (value ``package.module:Learner``)
ENTRY_POINTS = "rrls.algorithms"
#: how a run meets the uncertainty set: only the nominal model; a uniformly drawn point per
#: episode (domain randomization); a point the learner chooses per episode (M2TD3); an
#: adversary moving the parameters at every step (RARL)
SET_USES = ("nominal", "random", "chosen", "adversary")
#: the values a row's mean may take in the paper's normalised score (v - v_0) / |v_1 - v_0|
#: (Tables 4-5): its two anchors, one row each
ANCHORS = (0.0, 1.0)
#: learning steps per CPU-second of one single-threaded Hopper run, measured in CPU time (robust
#: to a machine shared with other work) by ``python3 benchmarks/calibrate.py td3 m2td3 sac``:
#: CPU seconds of ``rrls train --threads 1`` for 3 000 steps (1 000 random) minus those of 1 000
#: random steps, on the 2-core development machine, quiet, 2026-11-24 (under load: 77 / 85 /
#: 47, CPU time grows with cache contention). DR trains TD3's learner, SAC-DR SAC's; a row that
#: gives none is taken as TD3's. RARL and NR-MDP train a second learner, their adversary: their
#: rates are TD3's times their ratio to TD3 measured beside it (``calibrate.py td3 dr rarl nrmdp
#: m2td3`` on an AVX2 EPYC under load, 2026-11-29: 73 / 76 / 36 / 65 / 85; the HalfCheetah
#: reference's runs took 2.0x and 1.2x TD3's time).
TD3_CPU = 94.0
SAC_CPU = 57.0
RARL_CPU = float(round(TD3_CPU * 36 / 73))  # both players updated every step: twice TD3's work
NRMDP_CPU = float(round(TD3_CPU * 65 / 73))
#: TD3's aggregated env steps/s of K runs trained together on one H100, ``(K, rate)``
#: (docs/results/gpu/h100-2026-11-25.md): the estimate of a row that gives none
TD3_GPU = ((1, 784.0), (8, 2_300.0), (32, 4_189.0))


@dataclass(frozen=True)
class AlgorithmInfo:
    """One row of the table (``learner``: ``package.module:Class``)."""

    name: str
    display: str
    learner: str
    paper: bool = False  # one of the paper's five baselines (its default grid)
    adversary: bool = False  # trains an adversary: the benchmark's dynamic evaluation plays it
    set_use: str = "nominal"  # how a run meets the uncertainty set (SET_USES)
    #: the benchmark options (``Benchmark`` fields) its ``Config`` takes beyond the shared ones, as
    #: ``Config`` keywords: ``options(spec) -> {field: value}``
    options: Callable[[Any], dict[str, Any]] | None = None
    cpu_steps_per_s: float = TD3_CPU  # see TD3_CPU
    #: aggregated env steps/s of K runs trained together on one H100, ``(K, rate)`` pairs
    #: measured (docs/results/gpu/h100-2026-11-25.md); empty: estimated as TD3's
    gpu_steps_per_s: tuple[tuple[int, float], ...] = ()
    #: random warm-up steps of its reference hyper-parameters (its ``Config`` default and what
    #: a preset that claims the paper's hyper-parameters gives it)
    learning_starts: int = 25_000
    #: the ``Config`` fields the benchmark's ``--learning-rate`` sets; none unless a row names
    #: them (a plug-in's ``Config`` and SAC's two rates are their own)
    rate_fields: tuple[str, ...] = ()
    #: its mean is this value of the paper's normalised score (one of ``ANCHORS``: TD3's 0,
    #: M2TD3's 1); None: it does not normalise. Set by the table's own rows only (``_row``), not
    #: a constructor argument: a plug-in's row, or a built-in's copied by ``dataclasses.replace``
    #: (``benchmarks/authors_variants.py``), cannot add a third anchor
    anchor: float | None = field(default=None, init=False)
    row: int = 100  # position in tables and figures (the paper's row order), then by name

    def __post_init__(self) -> None:
        if not self.name or self.name != self.name.strip():
            raise ValueError(f"algorithm name {self.name!r}: a non-empty word")
        if self.set_use not in SET_USES:
            raise ValueError(
                f"algorithm {self.name!r}: set_use {self.set_use!r}; valid: {', '.join(SET_USES)}"
            )
        if self.learner.count(":") != 1:
            raise ValueError(
                f"algorithm {self.name!r}: learner {self.learner!r} must be package.module:Class"
            )
        if isinstance(self.rate_fields, str) or not all(
            isinstance(f, str) and f.isidentifier() for f in self.rate_fields
        ):
            raise ValueError(
                f"algorithm {self.name!r}: rate_fields {self.rate_fields!r} must be a tuple of "
                "Config field names"
            )

    @property
    def needs_set(self) -> bool:
        """Trains over the uncertainty set (not only on the nominal model)."""
        return self.set_use != "nominal"

    def gpu_rate(self) -> Mapping[int, float]:
        """``{K: aggregated env steps/s}`` measured on one H100 (empty: none)."""
        return dict(self.gpu_steps_per_s)


def _m2td3_options(spec: Any) -> dict[str, Any]:
    return {"normalize_omega": spec.normalize_omega}


def _rarl_options(spec: Any) -> dict[str, Any]:
    """TC-RMDP's rate-limited game when the benchmark plays one (RARL's adversary)."""
    if spec.rate_limit is None:
        return {}
    options = {"rate_limit": spec.rate_limit, "rate_game": spec.rate_game}
    if spec.observe != "vanilla":
        options["observe"] = spec.observe
    return options


#: the one learning rate of TD3's ``Config`` (and of the learners built on it)
_TD3_RATE = ("learning_rate",)


def _row(
    name: str, display: str, row: int, anchor: float | None = None, **flags: Any
) -> AlgorithmInfo:
    """A built-in row: its learner in ``rrls.agents``, TD3's one rate unless it says otherwise,
    and its ``anchor`` of the normalised score (set here only: see ``AlgorithmInfo.anchor``)."""
    flags.setdefault("rate_fields", _TD3_RATE)
    info = AlgorithmInfo(name, display, f"rrls.agents.algos.{name}:Learner", row=row, **flags)
    if anchor is not None:
        if anchor not in ANCHORS:
            raise ValueError(f"algorithm {name!r}: anchor {anchor!r}; valid: {ANCHORS}")
        object.__setattr__(info, "anchor", anchor)  # frozen, and no constructor argument
    return info


#: built-in rows, in the CLI's and the benchmark's order (the paper's five first)
ALGORITHMS: dict[str, AlgorithmInfo] = {
    a.name: a
    for a in (
        _row("td3", "TD3", 0, paper=True, gpu_steps_per_s=TD3_GPU, anchor=0.0),
        _row("dr", "DR", 1, paper=True, set_use="random"),
        _row(
            "rarl",
            "RARL",
            3,
            paper=True,
            adversary=True,
            set_use="adversary",
            options=_rarl_options,
            cpu_steps_per_s=RARL_CPU,
        ),
        # its adversary acts on actions
        _row("nrmdp", "NR-MDP", 4, paper=True, adversary=True, cpu_steps_per_s=NRMDP_CPU),
        # the M2TD3 authors' start_steps = 1e5 (akimotolab/M2TD3's configs; SuReLI/TCRMDP
        # src/main_m2td3.py:16, the RRLS authors' port)
        _row(
            "m2td3",
            "M2TD3",
            2,
            paper=True,
            set_use="chosen",
            anchor=1.0,
            learning_starts=100_000,
            options=_m2td3_options,
            cpu_steps_per_s=103.0,
            gpu_steps_per_s=((1, 435.0), (8, 1_172.0), (32, 2_200.0)),
        ),
        # CleanRL's sac_continuous_action.py; its two rates (policy_lr, q_lr) are its own
        _row("sac", "SAC", 5, learning_starts=5_000, cpu_steps_per_s=SAC_CPU, rate_fields=()),
        _row(
            "sacdr",
            "SAC-DR",
            6,
            set_use="random",
            learning_starts=5_000,
            cpu_steps_per_s=SAC_CPU,
            rate_fields=(),
        ),
    )
}
_BUILT_IN = tuple(ALGORITHMS)


def register_algorithm(info: AlgorithmInfo) -> AlgorithmInfo:
    """Add a plug-in's row (its display name and flags reach the report and the benchmark);
    a built-in's row cannot be replaced."""
    if info.name in _BUILT_IN:
        raise ValueError(f"algorithm {info.name!r} is built in; pick another name")
    ALGORITHMS[info.name] = info
    return info


def built_in() -> tuple[str, ...]:
    """The built-in algorithms' names (the paper's five, then SAC and SAC-DR)."""
    return _BUILT_IN


def paper_five() -> tuple[str, ...]:
    """The paper's five baselines, in the benchmark's order (its presets' default grid)."""
    return tuple(a.name for a in ALGORITHMS.values() if a.paper)


def normalisers() -> tuple[str, str]:
    """The rows whose means are 0 and 1 of the paper's normalised score (Tables 4-5: TD3's and
    M2TD3's): what every normalised cell, figure and caveat divides by, declared only here."""
    zero, one = (next(n for n, a in ALGORITHMS.items() if a.anchor == v) for v in ANCHORS)
    return zero, one


def plugin_entry_points() -> dict[str, str]:
    """Installed learner plug-ins: ``{name: "package.module:Learner"}``."""
    from importlib.metadata import entry_points

    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINTS)}


def algorithm_info(name: str) -> AlgorithmInfo | None:
    """``name``'s row: a declared one, an installed plug-in's (read as its own name), or
    ``package.module:Learner`` named directly; ``None`` for a name nothing declares."""
    if name in ALGORITHMS:
        return ALGORITHMS[name]
    target = plugin_entry_points().get(name) or (name if name.count(":") == 1 else None)
    if target is None:
        return None
    return AlgorithmInfo(name, name, target)


def _spelling(name: str) -> str:
    return "".join(c for c in name.lower() if c.isalnum())


def algorithm_key(name: str) -> str:
    """The name every command stores for ``name``: a declared row by its name or display name
    in any case and punctuation (``TD3``, ``NR-MDP``, ``nr_mdp`` → ``td3``, ``nrmdp``), an
    installed plug-in's entry point in any case, else ``name`` itself (``package.module:Learner``
    and submitted names; an unknown one is refused where it is used)."""
    if name in ALGORITHMS or ":" in name:
        return name
    wanted = _spelling(name)
    for info in ALGORITHMS.values():
        if wanted in (_spelling(info.name), _spelling(info.display)):
            return info.name
    for plugin in plugin_entry_points():
        if plugin.lower() == name.lower():
            return plugin
    return name


def display_name(name: str) -> str:
    """How tables and figures name ``name`` (a name no row declares reads as itself)."""
    info = ALGORITHMS.get(name)
    return info.display if info is not None else name


def warmup(name: str) -> int:
    """``name``'s random warm-up in its reference hyper-parameters (25 000, TD3's table, for a
    name no row declares)."""
    info = ALGORITHMS.get(name)
    return info.learning_starts if info is not None else AlgorithmInfo.learning_starts


def plays_adversary(name: str) -> bool:
    """Whether ``name`` trains an adversary (the benchmark's dynamic evaluation plays it)."""
    info = ALGORITHMS.get(name)
    return info is not None and info.adversary


def sort_algos(algos: Iterable[str]) -> list[str]:
    """The paper's row order first, then the others alphabetically (duplicates dropped)."""
    names = list(dict.fromkeys(algos))
    return sorted(names, key=lambda a: (ALGORITHMS[a].row if a in ALGORITHMS else 100, a))
