"""Scores of the paper (§5): the normalised score against the TD3 and M2TD3 references."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def normalized_score(v: ArrayLike, v_td3: ArrayLike, v_m2td3: ArrayLike) -> np.ndarray | np.float64:
    """``(v - v_td3) / |v_m2td3 - v_td3|``: 0 is TD3's score, 1 (or -1) is M2TD3's distance.

    >>> normalized_score(19.78, -123.64, 2322.73).round(2)  # DR's worst case on Ant (Table 4)
    np.float64(0.06)
    """
    v, v_td3, v_m2td3 = (np.asarray(x, dtype=np.float64) for x in (v, v_td3, v_m2td3))
    span = np.abs(v_m2td3 - v_td3)
    if np.any(span == 0):
        raise ValueError("TD3 and M2TD3 references are equal: the normalised score is undefined")
    return (v - v_td3) / span
