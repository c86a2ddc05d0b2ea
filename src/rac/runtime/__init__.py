"""Running a checked automaton in Python: the float and integer rules the targets share
(:mod:`rac.runtime.semantics`: reward mirrors, int32 arithmetic, literals), the scalar interpreter
behind ``rac.load`` and its vectorised twin for batches of episodes.

May import: core, ir.
"""
