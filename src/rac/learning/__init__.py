"""Learning under a shield: episodes of the model, tabular Q-learning, gymnasium environments.

May import: rac.compiler, core, lang, ir, check, model, runtime, engine, output.
"""
