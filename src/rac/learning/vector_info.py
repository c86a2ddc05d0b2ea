"""gymnasium's vector info layout: one dict for all the sub-environments, every key an array over
them and ``_key`` the mask of those that report it, nested dicts laid out alike (what
``SyncVectorEnv`` gathers, :class:`rac.learning.vector.ScenarioVectorEnv` builds, and SB3 callbacks
do not take). :func:`split_vector_info` turns it into one dict per sub-environment;
:func:`merge_vector_info` replaces some sub-environments' rows by another such dict's (a reset's).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["is_vector_info", "merge_vector_info", "split_vector_info"]


def is_vector_info(info: Mapping[str, Any]) -> bool:
    """Whether ``info`` is in the vector layout: some key has its mask ``_key`` beside it (a single
    environment's info dict has none)."""
    return any(key.startswith("_") and key[1:] in info for key in info)


def split_vector_info(info: Mapping[str, Any], n: int | None = None) -> list[dict[str, Any]]:
    """One info dict per sub-environment from gymnasium's vector layout: every key an array over
    the environments, ``_key`` the mask of those that report it (a key without one: every
    environment reports it), nested dicts laid out alike. The number of environments is ``n``, else
    read from the masks (``[]`` without any); a nested dict without masks of its own (as
    :class:`rac.learning.wrappers.RewardAutomatonVectorWrapper`'s ``rewards``) takes its parent's."""
    sizes = {len(value) for key, value in info.items() if key.startswith("_") and hasattr(value, "__len__")}
    if sizes:
        n = max(sizes)
    if n is None:
        return []
    out: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, value in info.items():
        if key.startswith("_"):
            continue
        mask = info.get(f"_{key}")
        parts = split_vector_info(value, n) if isinstance(value, Mapping) else None
        for env in range(n):
            if mask is not None and not mask[env]:
                continue
            item = parts[env] if parts is not None else value[env]
            out[env][key] = item.item() if hasattr(item, "item") and getattr(item, "ndim", 1) == 0 else item
    return out


def merge_vector_info(info: Mapping[str, Any], other: Mapping[str, Any], rows: np.ndarray) -> dict[str, Any]:
    """``info`` with the sub-environments ``rows`` (a boolean mask) reporting what ``other`` reports for
    them instead, and nothing else: a key ``other`` does not give them is masked off there."""
    out: dict[str, Any] = {}
    keys = dict.fromkeys(key for key in (*info, *other) if not key.startswith("_"))
    for key in keys:
        mine, theirs = info.get(key), other.get(key)
        have = _mask(info, key, rows.size)
        given = _mask(other, key, rows.size)
        mask = np.where(rows, given, have)
        if not mask.any():
            continue
        if isinstance(mine, Mapping) or isinstance(theirs, Mapping):
            out[key] = merge_vector_info(mine if isinstance(mine, Mapping) else {},
                                         theirs if isinstance(theirs, Mapping) else {}, rows)
        else:
            out[key] = _rows_from(mine, theirs, rows & given)
        out[f"_{key}"] = mask
    return out


def _mask(info: Mapping[str, Any], key: str, n: int) -> np.ndarray:
    if key not in info:
        return np.zeros(n, dtype=bool)
    mask = info.get(f"_{key}")
    return np.ones(n, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)


def _rows_from(mine: Any, theirs: Any, taken: np.ndarray) -> np.ndarray:
    """``mine``'s array with the rows ``taken`` from ``theirs`` (object dtype where the two do not share one)."""
    if mine is None:
        return np.array(theirs, copy=True)
    values = np.array(mine, copy=True)
    if theirs is None or not taken.any():
        return values
    other = np.asarray(theirs)
    if values.dtype != other.dtype and not np.can_cast(other.dtype, values.dtype, casting="same_kind"):
        values = values.astype(object)
    values[taken] = other[taken]
    return values
