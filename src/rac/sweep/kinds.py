"""What a sweep task can run (``rac sweep --task``; :mod:`rac.sweep.task` runs them), and the option that sets its
memory.

A module of its own, not the task module, so that the ``rac`` command's parser
(:mod:`rac.cli.arguments`) lists the tasks without loading the task code.
"""

from __future__ import annotations

__all__ = ["MEMORY_OPTION", "TASKS"]

TASKS = ("check", "verify", "preanalyse", "experiment")
#: The option that sets a task's memory (its limit, and the budget of its command): what a task's budget refusals
#: name, where ``rac verify`` says ``--max-memory``.
MEMORY_OPTION = "--task-memory"
