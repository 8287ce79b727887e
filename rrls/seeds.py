"""The grammar of ``--seeds``, one for every command (``rrls train``, ``benchmark``,
``quickstart``): a list of seeds written as comma-separated integers and inclusive ranges.

``0-4`` is seeds 0, 1, 2, 3, 4; ``0,3,5`` those three; ``0-2,7`` four; a lone ``3`` is the one
seed 3 (``--seed 3`` says the same where a command takes one seed). ``rrls benchmark --seeds 3``
used to mean *three seeds*, 0-2; that form is now refused with the two ways to write what was
meant (:func:`count_form`). Seeds are < 2**32 and a list holds at most ``MAX_SEEDS``, checked
before any list is made; the grammar is linear in the text's length. Nothing here imports
anything: every layer may use it.
"""

from __future__ import annotations

#: what the help texts and error messages show
EXAMPLES = "0-4, 0,3,5 or 0-2,7"
#: the most seeds one list may give, and the largest seed (numpy's SeedSequence takes any, but
#: run directories and reports are per seed: 10 000 runs of a cell is far beyond any benchmark)
MAX_SEEDS = 10_000
MAX_SEED = 2**32 - 1


def seed_message(value: object) -> str:
    """The one wording of a bad seed, in every command and flag."""
    return f"a seed is an integer from 0 to {MAX_SEED}, got {value}"


def parse_seeds(text: str) -> list[int]:
    """The seeds ``text`` lists: comma-separated integers >= 0 and inclusive ranges ``LOW-HIGH``.

    Refused with a one-line ``ValueError``: empty, not an integer, negative, a decreasing range
    or a seed given twice (two runs into one directory).

    >>> parse_seeds("0-2,7"), parse_seeds("3")
    ([0, 1, 2, 7], [3])
    """
    seeds: list[int] = []
    seen: set[int] = set()
    for part in str(text).split(","):
        part = part.strip()
        if not part:
            raise ValueError(f"--seeds {text!r}: empty item (write {EXAMPLES})")
        if part.startswith("-"):
            raise ValueError(f"--seeds {text!r}: {seed_message(part)}")
        first, dash, last = part.partition("-")
        try:
            low = int(first)
            high = int(last) if dash else low
        except ValueError:
            raise ValueError(
                f"--seeds {text!r}: {part!r} is not a seed or a range of seeds (write {EXAMPLES};"
                " seeds are integers >= 0)"
            ) from None
        if high < low:
            raise ValueError(f"--seeds {text!r}: the range {part!r} is empty (write low-high)")
        if low < 0 or high > MAX_SEED:
            raise ValueError(f"--seeds {text!r}: {seed_message(high if high > MAX_SEED else low)}")
        if len(seeds) + high - low + 1 > MAX_SEEDS:  # before the list is made
            raise ValueError(f"--seeds {text!r}: more than {MAX_SEEDS:,} seeds (at most that many)")
        block = range(low, high + 1)
        twice = [s for s in block if s in seen]  # linear: each seed is looked up once
        if twice:
            raise ValueError(f"--seeds {text!r} gives seed {', '.join(map(str, twice))} twice")
        seeds.extend(block)
        seen.update(block)
    return seeds


def count_form(text: str) -> int | None:
    """``N`` when ``text`` is a bare integer: the retired *count* form of ``rrls benchmark
    --seeds N`` (seeds 0..N-1, refused now); ``None`` for anything else (a list or a range)."""
    text = str(text).strip()
    return int(text) if text.isdigit() else None


def as_range(seeds: list[int]) -> str:
    """The shortest ``--seeds`` text for ``seeds`` (``[0, 1, 2]`` -> ``0-2``).

    >>> as_range([0, 1, 2]), as_range([0, 3, 4, 5]), as_range([4])
    ('0-2', '0,3-5', '4-4')
    """
    parts: list[str] = []
    for s in sorted(seeds):
        if parts and s == int(parts[-1].split("-")[-1]) + 1:
            parts[-1] = f"{parts[-1].split('-')[0]}-{s}"
        else:
            parts.append(str(s))
    return ",".join(p if "-" in p or len(seeds) > 1 else f"{p}-{p}" for p in parts)


__all__ = [
    "EXAMPLES",
    "MAX_SEED",
    "MAX_SEEDS",
    "as_range",
    "count_form",
    "parse_seeds",
    "seed_message",
]
