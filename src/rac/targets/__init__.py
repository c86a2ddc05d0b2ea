"""Code generators: each turns the IR into text for one target: a Python module
(:mod:`rac.targets.python`) or a UPPAAL model and query file (:mod:`rac.targets.uppaal`).

May import: core, ir, model, runtime.
"""
