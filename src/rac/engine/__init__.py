"""rac's own verification engine: explore the model's state space (alone or with the automaton),
evaluate IR expressions on states, decide queries with Storm, shields, simulation and statistics.

May import: core, ir, model, runtime.
"""
