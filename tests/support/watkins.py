"""The oracle of the tabular learner's update (tests/learning/test_untried.py, test_tabular.py): Watkins'
update one episode at a time, in episode order, written from the definition and not from
:mod:`rac.learning.tabular`."""

from __future__ import annotations

import numpy as np

from rac.learning.tabular import Transition


def in_order_update(values: np.ndarray, step: Transition, alpha: float, gamma: float, untried: float | None) -> None:
    """Update ``values`` in place with ``step``'s active episodes, one at a time: an ending episode does
    not bootstrap, the maximum runs over the next state's allowed actions, and an entry still at
    ``untried`` takes its target as it is."""
    for i in step.active:
        target = step.reward[i]
        if not step.ends[i]:
            target += gamma * values[step.next_rows[i]][step.next_masks[i]].max()
        old = values[step.rows[i], step.actions[i]]
        values[step.rows[i], step.actions[i]] = target if old == untried else old + alpha * (target - old)
