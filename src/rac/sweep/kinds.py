"""What a sweep task can run (``rac sweep --task``; :mod:`rac.sweep.task` runs them).

A module of its own, not the task module, so that the ``rac`` command's parser
(:mod:`rac.cli.arguments`) lists the tasks without loading the task code.
"""

from __future__ import annotations

__all__ = ["TASKS"]

TASKS = ("check", "verify", "preanalyse", "experiment")
