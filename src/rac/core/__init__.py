"""Shared by every stage: source text and spans (:mod:`~rac.core.source`), diagnostics and their one
renderer (:mod:`~rac.core.diagnostics`), the int32 limits (:mod:`~rac.core.numbers`), the
expression printer base with its operator tables (:mod:`~rac.core.printing`) and the atomic file
write (:mod:`~rac.core.files`).

Nothing here knows the `.ra` language; every other package may use it.

May import: nothing of rac.
"""
